"""Stage `hqp_replay`: replay every KMP case on the mobile manipulator in MuJoCo at 1 kHz.

Usage: python stages/hqp_replay.py   (reads params.yaml, data/<demos.scenario>/scene/ and
kmp_fit/, writes data/<demos.scenario>/hqp_replay/)
"""

from __future__ import annotations

from locoman.kernels import pin_kernels

pin_kernels()  # first: NumPy, OpenBLAS and OpenCV choose their CPU kernels when they load

import sys
from pathlib import Path

import numpy as np

from locoman.artifacts import read_npz, write_metrics, write_text_atomic
from locoman.config import load_params
from locoman.errors import ConfigError
from locoman.hqp.figures import results_table
from locoman.hqp.replay import ReplayTask, joint_limits, replay
from locoman.hqp.report import replay_metrics, write_replay
from locoman.kmp.demos import task_points
from locoman.kmp.io import REFERENCE
from locoman.progress import progress
from locoman.scene.io import load_objects, load_plan, load_scene_model, load_state
from locoman.stage import DATA_DIR, StageOutputs, run_stage


def main(outputs: StageOutputs) -> Path:
    cfg = load_params()
    d, h = cfg.demos, cfg.hqp
    root = DATA_DIR / d.scenario
    scene = root / "scene"
    plan = load_plan(scene)
    obj, _ = task_points(load_objects(scene), plan, d.grasp_height)
    target = next(s["target"]["pos_m"] for s in plan["subtasks"] if s["target"] is not None)
    home = load_state(scene)["qpos"]
    out = outputs.folder(d.scenario, "hqp_replay")
    metrics = {}
    for name in progress(cfg.kmp.cases, "hqp_replay cases"):
        ref = read_npz(root / "kmp_fit" / f"reference_{name}.npz", REFERENCE)
        steps = np.diff(ref["time_s"])
        if not np.allclose(steps, h.dt, rtol=1e-6, atol=1e-12):
            raise ConfigError(
                f"reference {name!r} is sampled every {steps[0]:.6f} s but hqp.dt = {h.dt} s; "
                "set kmp.rate_hz = 1 / hqp.dt"
            )
        task = ReplayTask(
            time_s=ref["time_s"],
            ee_pos=ref["wrist_pos"],
            ee_vel=ref["wrist_vel"],
            base=ref["base"],
            grasp_velocity=np.asarray(d.grasp_velocity, dtype=float),
            grasp_time_s=d.grasp_time_s,
            release_time_s=d.place_time_s,
            obj=obj,
            target=np.asarray(target, dtype=float),
        )
        model = load_scene_model(scene)
        log = replay(model, home, task, h)
        write_replay(out, name, log, task, model, h.dt)
        metrics[name] = replay_metrics(
            log, task, joint_limits(model, h), h.dt, h.success_tolerance_m
        )
    write_metrics(out, metrics)
    write_text_atomic(out / "results.md", results_table(metrics))
    return out


if __name__ == "__main__":
    run_stage(main, sys.argv[1:])
