"""What the executed motion achieved, measured on MuJoCo's state (no ground truth but the plan).

Checks (``failed_checks`` names those that fail; ``success`` is none failing):
    * ``completed``: every control step ran (no QP failure, no fall, no divergence);
    * ``stayed_up``: the pelvis above ``fallen_height_m`` and tilted less than
      ``fallen_tilt_rad`` from the plan's throughout;
    * ``object_goal``: each object with a goal ends within ``goal_tol_m`` (xy) and
      ``goal_yaw_tol_rad`` of it;
    * ``torque_limits``: no torque beyond its joint's limit;
    * ``unscheduled_penetration``: no contact the schedule does not allow deeper than
      ``penetration_tol_m`` (a stance sole on anything and a holding hand on its object are
      allowed).
"""

from __future__ import annotations

import mujoco
import numpy as np
import pinocchio as pin

from locoman.config.execute import ExecuteCfg
from locoman.execute.model import BASE, PALMS, SOLES, execution_model, torque_limits
from locoman.execute.reference import Reference
from locoman.execute.simulate import Execution
from locoman.scene import g1
from locoman.sim.camera import robot_geoms

#: Every how many control steps the penetration is measured (10 ms at 1 kHz).
PENETRATION_STRIDE = 10


def frame_positions(q: np.ndarray, frames: tuple[str, ...]) -> np.ndarray:
    """(T, F, 3) each frame's position [m] along the configurations ``q`` (T, 36)."""
    model = execution_model()
    data = model.createData()
    ids = [model.getFrameId(name) for name in frames]
    out = np.zeros((len(q), len(ids), 3))
    for i, qi in enumerate(q):
        pin.framesForwardKinematics(model, data, qi)
        for j, f in enumerate(ids):
            out[i, j] = data.oMf[f].translation
    return out


def rmse(a: np.ndarray, b: np.ndarray) -> float | None:
    """Root mean square of the distance |a - b| over the samples [m]; None without any."""
    if len(a) == 0:
        return None
    return float(np.sqrt(np.mean(np.sum((a - b) ** 2, axis=-1))))


def stance_slip(stance: np.ndarray, soles: np.ndarray) -> float:
    """Largest distance [m] a sole centre moves from where its stance began, over every
    stance (``stance`` (T, 2), ``soles`` (T, 2, 3))."""
    worst = 0.0
    for foot in range(2):
        anchor = None
        for i in range(len(stance)):
            if not stance[i, foot]:
                anchor = None
                continue
            if anchor is None:
                anchor = soles[i, foot]
            worst = max(worst, float(np.linalg.norm(soles[i, foot, :2] - anchor[:2])))
    return worst


def touchdown_heights(foot_contact: np.ndarray, soles: np.ndarray, planned: np.ndarray) -> list:
    """How high [m] above its planned footprint each sole was when the plan put it down: at
    each sample where ``foot_contact`` (T, 2) turns true, the executed sole centre's height
    (``soles`` (T, 2, 3)) minus the plan's (``planned``), in time order. The controller
    holds a stance sole still: one that lags its swing lands late, or never (the falls of
    S1 and S2 follow touchdowns 1.5-3 cm high)."""
    heights = []
    for i in np.flatnonzero((foot_contact[1:] & ~foot_contact[:-1]).any(axis=1)) + 1:
        for foot in np.flatnonzero(foot_contact[i] & ~foot_contact[i - 1]):
            heights.append(float(soles[i, foot, 2] - planned[i, foot, 2]))
    return heights


def unscheduled_penetration(
    model: mujoco.MjModel, executed: Execution, ref: Reference, objects: list[str]
) -> tuple[float, str]:
    """Deepest penetration [m] of a robot geom into anything the schedule does not let it
    touch, and the pair's geom names, every :data:`PENETRATION_STRIDE` steps."""
    robot = robot_geoms(model)
    feet = [model.geom(name.replace("_sole", "_foot")).id for name in SOLES]
    hand_bodies = [model.body(link).id for link in g1.HAND_LINKS]
    object_bodies = {model.body(name).id: j for j, name in enumerate(objects)}
    data = mujoco.MjData(model)
    deepest, pair = 0.0, ""
    for i in range(0, len(executed.time), PENETRATION_STRIDE):
        data.qpos[:] = executed.qpos[i]
        mujoco.mj_forward(model, data)
        for c in data.contact[: data.ncon]:
            g1_, g2_ = int(c.geom1), int(c.geom2)
            if not (robot[g1_] or robot[g2_]) or -c.dist <= deepest:
                continue
            own, other = (g1_, g2_) if robot[g1_] else (g2_, g1_)
            if own in feet and executed.stance[i, feet.index(own)]:
                continue
            body = model.geom_bodyid[own]
            held = object_bodies.get(model.geom_bodyid[other], -2)
            if body in hand_bodies and held == ref.hand_object[i, hand_bodies.index(body)]:
                continue
            deepest = float(-c.dist)
            pair = f"{model.geom(g1_).name or g1_} | {model.geom(g2_).name or g2_}"
    return deepest, pair


def execution_metrics(
    model: mujoco.MjModel,
    executed: Execution,
    ref: Reference,
    traj: dict[str, np.ndarray],
    cfg: ExecuteCfg,
) -> dict:
    """The metrics and checks of an execution against its reference (``metrics.json``)."""
    names = [str(name) for name in traj["object_names"]]
    n = len(executed.time)
    tracked = (BASE, *SOLES, *PALMS)
    actual = frame_positions(executed.q, tracked)
    planned = np.stack([ref.frames[name].position[:n] for name in tracked], axis=1)
    holding = ref.hand_object[:n] >= 0
    limits = torque_limits(execution_model())
    height = executed.q[:, 2] if n else np.zeros(0)
    metrics: dict = {
        "completed": executed.completed,
        "stopped": executed.stopped,
        "duration_s": float(ref.time[-1]),
        "time_up_s": float(executed.time[-1] + (ref.time[1] - ref.time[0])) if n else 0.0,
        "min_pelvis_height_m": float(height.min()) if n else None,
        "grasps_lost": [
            {"t_s": t, "hand": ("left", "right")[hand], "object": names[obj]}
            for t, hand, obj in executed.lost_grasps
        ],
        "tracking_rmse_m": {
            "base": rmse(actual[:, 0], planned[:, 0]),
            "feet": rmse(actual[:, 1:3], planned[:, 1:3]),
            "hands": rmse(actual[:, 3:5], planned[:, 3:5]),
            "hands_holding": rmse(actual[:, 3:5][holding], planned[:, 3:5][holding]),
        },
        "com_rmse_m": rmse(_coms(executed.q), ref.com[:n]),
        "foot_slip_max_m": stance_slip(executed.stance, actual[:, 1:3]),
        "touchdown_heights_m": touchdown_heights(
            ref.foot_contact[:n], actual[:, 1:3], planned[:, 1:3]
        ),
        "peak_torque_fraction": float(np.max(np.abs(executed.tau) / limits)) if n else 0.0,
        "steps_beyond_torque_limits": int(executed.limits_dropped.sum()),
        "qp_time_median_ms": float(np.median(executed.solve_time_s) * 1e3) if n else 0.0,
        "qp_time_p99_ms": float(np.percentile(executed.solve_time_s, 99) * 1e3) if n else 0.0,
    }
    goals = {}
    for j, name in enumerate(names):
        if int(traj["goal_node"][j]) < 0 or not n:
            continue
        goal = traj["object_goal"][j]
        position = executed.object_position[-1, j]
        rotation = executed.object_rotation[-1, j]
        yaw = float(np.arctan2(rotation[1, 0], rotation[0, 0]))
        goals[f"{name}_goal_error_m"] = float(np.linalg.norm(position[:2] - goal[:2]))
        goals[f"{name}_goal_yaw_error_rad"] = float(
            abs(np.remainder(yaw - goal[2] + np.pi, 2 * np.pi) - np.pi)
        )
    metrics |= goals
    depth, pair = unscheduled_penetration(model, executed, ref, names)
    metrics["unscheduled_penetration_max_m"] = depth
    metrics["unscheduled_penetration_pair"] = pair
    positions = [v for k, v in goals.items() if k.endswith("_goal_error_m")]
    yaws = [v for k, v in goals.items() if k.endswith("_goal_yaw_error_rad")]
    checks = {
        "completed": executed.completed,
        "stayed_up": executed.completed or not executed.stopped.startswith("fell"),
        "object_goal": all(e <= cfg.goal_tol_m for e in positions)
        and all(e <= cfg.goal_yaw_tol_rad for e in yaws),
        "torque_limits": metrics["peak_torque_fraction"] <= 1.0 + 1e-9,
        "unscheduled_penetration": depth <= cfg.penetration_tol_m,
    }
    metrics["failed_checks"] = [name for name, passed in checks.items() if not passed]
    metrics["success"] = not metrics["failed_checks"]
    return metrics


def _coms(q: np.ndarray) -> np.ndarray:
    model = execution_model()
    data = model.createData()
    return np.array([pin.centerOfMass(model, data, qi) for qi in q]).reshape(len(q), 3)
