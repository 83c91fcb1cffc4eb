"""Figures and files of a replay: the paper's RMSE metrics, the task outcome, MCAP, plots."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from locoman.artifacts import ArtifactSchema, Field, write_figure, write_npz
from locoman.artifacts.io import write_text_atomic
from locoman.artifacts.mcap_io import write_mcap
from locoman.artifacts.video import write_mp4
from locoman.hqp.figures import ReplaySeries, replay_figure
from locoman.hqp.limits import JointLimits
from locoman.hqp.replay import ReplayLog, ReplayTask
from locoman.scene.frames import body_frames
from locoman.scene.mobile_manipulator import ARM_BASE_BODY
from locoman.sim.foxglove import scene_entities
from locoman.sim.media import media_quality

#: Rate of the MCAP and the plot tables [Hz]; the npz keeps every control step.
EXPORT_RATE_HZ = 100.0  # MCAP and figures
CSV_EVERY = 5  # the dvc plots CSVs at 20 Hz: Vega inlines every row of every curve
#: The bottle counts as upright when its axis is within this angle of vertical [rad].
UPRIGHT_TOL_RAD = 0.2
#: ... and as lifted when it rose this far above its start [m].
LIFT_MIN_M = 0.01
#: The paper's figure of each case.
FIGURES = {"replica": "Fig. 5", "generalisation": "Fig. 6"}

REPLAY = ArtifactSchema(
    "hqp.replay",
    2,
    "hqp_replay",
    (
        Field("time_s", "float64", ("T",), "s"),
        Field("ee_pos_desired", "float64", ("T", 3), "m", "x_d"),
        Field("ee_pos", "float64", ("T", 3), "m", "x_a, measured"),
        Field("ee_vel_desired", "float64", ("T", 3), "m/s", "xd_dot"),
        Field("ee_vel", "float64", ("T", 3), "m/s", "xa_dot, measured"),
        Field("base_learned", "float64", ("T", 3), "mixed", "q_b,d: x [m], y [m], yaw [rad]"),
        Field("base_optimal", "float64", ("T", 3), "mixed", "q_b*, integrated HQP solution"),
        Field("base_actual", "float64", ("T", 3), "mixed", "q_b,a, measured"),
        Field("q_star", "float64", ("T", 10), "mixed", "q*: base (m, m, rad), arm [rad]"),
        Field("qdot_star", "float64", ("T", 10), "mixed", "qdot*, HQP solution"),
        Field("q", "float64", ("T", 10), "mixed", "measured joints"),
        Field("torque", "float64", ("T", 7), "N m", "arm torque applied, eq. (10)"),
        Field("gripper_closed", "float64", ("T",), "-", "1 while the gripper is closed"),
        Field("obj_pos", "float64", ("T", 3), "m", "carried object's base"),
        Field("level1_residual", "float64", ("T",), "mixed", "||J qdot* - b_1||"),
    ),
)


def _rmse(a: np.ndarray, b: np.ndarray) -> list[float]:
    return np.sqrt(np.mean((a - b) ** 2, axis=0)).tolist()


def bound_violation(log: ReplayLog, limits: JointLimits, dt: float) -> dict[str, float]:
    """Largest violation of (7), (8) and (9) by the commanded q*, qdot* (0 when respected)."""
    qa = log.q_star[:, 3:]
    pos = np.maximum(limits.arm_min - qa, qa - limits.arm_max).max(initial=0.0)
    vel = (np.abs(log.qdot_star) - limits.velocity_max).max(initial=0.0)
    prev = np.vstack([np.zeros((1, 10)), log.qdot_star[:-1]])
    acc = (np.abs(log.qdot_star - prev) / dt - limits.acceleration_max).max(initial=0.0)
    return {
        "position_rad": max(float(pos), 0.0),
        "velocity": max(float(vel), 0.0),
        "acceleration": max(float(acc), 0.0),
    }


def replay_metrics(
    log: ReplayLog, task: ReplayTask, limits: JointLimits, dt: float, tolerance_m: float
) -> dict[str, Any]:
    """The paper's RMSEs (Sec. IV-C), the task outcome and the controller's cost."""
    _w, x, y, _ = log.obj_quat_wxyz[-1]
    tilt = float(np.arccos(np.clip(1.0 - 2.0 * (x * x + y * y), -1.0, 1.0)))
    final_error = float(np.linalg.norm(log.obj_pos[-1] - task.target))
    lifted = float(log.obj_pos[:, 2].max() - log.obj_pos[0, 2])
    failed = [
        name
        for name, ok in (
            ("bottle_final_error", final_error <= tolerance_m),
            ("bottle_upright", tilt <= UPRIGHT_TOL_RAD),
            ("bottle_lifted", lifted >= LIFT_MIN_M),
        )
        if not ok
    ]
    return {
        "rmse_ee_pos_m": _rmse(log.ee_pos, log.ee_pos_desired),
        "rmse_ee_vel_mps": _rmse(log.ee_vel, log.ee_vel_desired),
        "rmse_base_learned_vs_optimal": _rmse(log.base_learned, log.base_optimal),
        "rmse_base_optimal_vs_actual": _rmse(log.base_optimal, log.base_actual),
        "ee_pos_error_max_m": float(np.linalg.norm(log.ee_pos - log.ee_pos_desired, axis=1).max()),
        "bottle_final_error_m": final_error,
        "bottle_tilt_rad": tilt,
        "bottle_lift_m": lifted,
        "success": not failed,
        "failed_checks": failed,
        "bound_violation_max": bound_violation(log, limits, dt),
        "level1_residual_max": float(log.level1_residual.max()),
        "hqp_step_median_s": float(np.median(log.hqp_step_s)),
        "hqp_step_p99_s": float(np.percentile(log.hqp_step_s, 99)),
        "realtime_factor": float((log.time_s[-1] - log.time_s[0] + dt) / log.wall_s),
    }


def _csv(path: Path, header: str, rows: np.ndarray) -> None:
    body = "\n".join(",".join(f"{v:.6g}" for v in r) for r in rows)
    write_text_atomic(path, header + "\n" + body + "\n")


def _in_frame(pos: np.ndarray, frame_pos: np.ndarray, frame_wxyz: np.ndarray) -> np.ndarray:
    """World points (T, 3) expressed in moving frames (T, 3) + (T, 4) (w, x, y, z) [m]."""
    rot = np.empty((len(pos), 9))
    for k, q in enumerate(frame_wxyz):
        mujoco.mju_quat2Mat(rot[k], q)
    return np.einsum("tji,tj->ti", rot.reshape(-1, 3, 3), pos - frame_pos)


VIDEO_FPS = 30.0  # [1/s]
VIDEO_SIZE = (640, 480)  # width, height [px]


def video_step(dt: float, fps: float) -> int:
    """Log steps per video frame: the nearest whole number to 1 / (``fps`` ``dt``)."""
    return max(1, round(1.0 / (fps * dt)))


def replay_frames(
    model: mujoco.MjModel, qpos: np.ndarray, dt: float, fps: float, size: tuple[int, int]
) -> Iterator[np.ndarray]:
    """Frames (height, width, 3) of the replay's ``qpos`` (T, nq), one every 1 / ``fps``
    seconds of the ``dt``-step log, from a camera that follows the arm's base."""
    data = mujoco.MjData(model)
    width, height = size
    arm_base = model.body(ARM_BASE_BODY).id
    cam = mujoco.MjvCamera()
    cam.distance, cam.elevation, cam.azimuth = 2.5, -25.0, 135.0
    with mujoco.Renderer(media_quality(model), height=height, width=width) as renderer:
        for q in qpos[:: video_step(dt, fps)]:
            data.qpos[:] = q
            mujoco.mj_forward(model, data)
            cam.lookat[:] = data.xpos[arm_base] + np.array([0.0, 0.0, 0.3])
            renderer.update_scene(data, camera=cam)
            yield renderer.render().copy()


def write_replay(
    out: Path, name: str, log: ReplayLog, task: ReplayTask, model: mujoco.MjModel, dt: float
) -> None:
    """``replay_<name>.npz`` (every step), ``replay_<name>.mcap``, ``replay_<name>.mp4`` (real
    time), ``plots/<name>_*.csv`` and the paper's figure ``fig_<name>.png``."""
    # The step times stay out: a wall clock would change the artifact on every run; their
    # median and p99 go to timing.json.
    write_npz(
        out / f"replay_{name}.npz",
        REPLAY,
        {f.name: getattr(log, f.name) for f in REPLAY.fields},
    )
    step = max(1, round(1.0 / (EXPORT_RATE_HZ * dt)))
    sl = slice(None, None, step)
    t = log.time_s[sl]
    frames = body_frames(model, log.qpos[sl])
    entities = scene_entities(model, log.qpos[0], moving=set(frames))
    fps = 1.0 / (dt * video_step(dt, VIDEO_FPS))  # the frames' true rate
    write_mp4(
        out / f"replay_{name}.mp4", replay_frames(model, log.qpos, dt, VIDEO_FPS, VIDEO_SIZE), fps
    )
    ee_arm = _in_frame(log.ee_pos[sl], *frames[ARM_BASE_BODY])
    write_mcap(
        out / f"replay_{name}.mcap",
        t,
        frames,
        {
            "/ee": {
                "desired": log.ee_pos_desired[sl],
                "actual": log.ee_pos[sl],
                "velocity_desired": log.ee_vel_desired[sl],
                "velocity_actual": log.ee_vel[sl],
            },
            "/base": {
                "learned": log.base_learned[sl],
                "optimal": log.base_optimal[sl],
                "actual": log.base_actual[sl],
            },
            "/joints": {
                "q_star": log.q_star[sl],
                "q": log.q[sl],
                "qdot_star": log.qdot_star[sl],
                "torque": log.torque[sl],
                "gripper_closed": log.gripper_closed[sl],
            },
        },
        entities=entities,
    )
    plots = out / "plots"
    _csv(
        plots / f"{name}_ee_pos.csv",
        "time_s,x_d,y_d,z_d,x_a,y_a,z_a",
        np.c_[t, log.ee_pos_desired[sl], log.ee_pos[sl]][::CSV_EVERY],
    )
    _csv(
        plots / f"{name}_ee_vel.csv",
        "time_s,vx_d,vy_d,vz_d,vx_a,vy_a,vz_a",
        np.c_[t, log.ee_vel_desired[sl], log.ee_vel[sl]][::CSV_EVERY],
    )
    _csv(
        plots / f"{name}_base.csv",
        "time_s,x_learned,y_learned,yaw_learned,x_optimal,y_optimal,yaw_optimal,"
        "x_actual,y_actual,yaw_actual",
        np.c_[t, log.base_learned[sl], log.base_optimal[sl], log.base_actual[sl]][::CSV_EVERY],
    )
    _csv(plots / f"{name}_ee_arm.csv", "time_s,x_r,y_r,z_r", np.c_[t, ee_arm][::CSV_EVERY])
    series = ReplaySeries(
        t,
        log.ee_pos_desired[sl],
        log.ee_pos[sl],
        ee_arm,
        log.base_learned[sl],
        log.base_optimal[sl],
        log.base_actual[sl],
        log.ee_vel_desired[sl],
        log.ee_vel[sl],
        task.grasp_time_s,
        task.grasp_velocity,
    )
    figure = FIGURES.get(name, f"case {name}")
    write_figure(out / f"fig_{name}.png", replay_figure(series, f"Paper B, {figure}: {name}"))
