"""A short closed-loop replay in MuJoCo: the HQP + impedance loop tracks and respects limits."""

from __future__ import annotations

import numpy as np

from locoman.config import load_params
from locoman.hqp.replay import ReplayTask, joint_limits, replay
from locoman.hqp.report import bound_violation
from locoman.scene.builder import build_scene


def test_short_replay_tracks_a_moving_target(repo):
    cfg = load_params(repo / "params.yaml")
    scene = build_scene("mm", cfg.scenarios["mm_pick_place"])
    model = scene.spec.compile()
    home = model.key("home").qpos.copy()
    t = np.arange(0, 1501) * cfg.hqp.dt
    start = np.array([0.417, 0.062, 1.107])
    vel = np.array([0.1, 0.0, -0.02])
    base0 = np.array([*cfg.scenarios["mm_pick_place"].start.xy, 0.046])
    task = ReplayTask(
        time_s=t,
        ee_pos=start + t[:, None] * vel,
        ee_vel=np.tile(vel, (len(t), 1)),
        base=base0 + t[:, None] * np.array([0.1, 0.0, 0.0]),
        grasp_velocity=np.array(cfg.demos.grasp_velocity),
        grasp_time_s=100.0,
        release_time_s=200.0,
        obj="bottle",
        target=np.zeros(3),
    )
    log = replay(model, home, task, cfg.hqp)
    err = np.linalg.norm(log.ee_pos - log.ee_pos_desired, axis=1)
    assert err.max() < 0.02 and err[-500:].mean() < 0.005
    violation = bound_violation(log, joint_limits(model, cfg.hqp), cfg.hqp.dt)
    assert max(violation.values()) < 1e-9
    assert log.base_actual[-1, 0] > base0[0] + 0.05
