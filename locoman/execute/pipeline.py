"""Stage ``execute`` for one scenario: the G1 carries out the TO's trajectory in MuJoCo.

Layout under ``data/<scenario>/execute/``::

    metrics.json          success, failed_checks, time the robot stayed up, each object's
                          goal error, foot slip, tracking RMSE, peak torque fraction
                          (locoman.execute.metrics); timing.json: the QP's time per step
    executed.mcap         link and object poses every 10 ms (foxglove.FrameTransforms, /tf)
                          and /tracking: planned and executed base and hand positions
    motion.mp4            executed (left) beside planned (right), real time, 30 frames/s,
                          to AFTER_STOP_S past a stop (the whole plan: evaluate's MP4)
    plots/filmstrip.png   executed (top row) above planned (bottom row) at the same times
"""

from __future__ import annotations

import logging
from collections.abc import Iterator
from pathlib import Path

import cv2
import mujoco
import numpy as np

from locoman.artifacts import read_npz, write_metrics, write_png
from locoman.artifacts.mcap_io import write_mcap
from locoman.artifacts.pictures import fit_tile
from locoman.artifacts.video import write_mp4
from locoman.config.execute import ExecuteCfg
from locoman.execute.balance import execution_reference
from locoman.execute.metrics import execution_metrics, frame_positions
from locoman.execute.model import PALMS
from locoman.execute.reference import Reference
from locoman.execute.simulate import Execution, execute, execution_mjmodel, palm_torsion
from locoman.scene import g1
from locoman.scene.io import load_scene_spec, load_state
from locoman.scene.rotations import quat_xyzw_to_rpy, wxyz_to_xyzw
from locoman.sim import camera
from locoman.sim.evaluate import scene_qpos
from locoman.sim.foxglove import scene_entities
from locoman.sim.media import media_quality
from locoman.sim.pipeline import TILE, VIDEO_FPS, VIDEO_SIZE, view_bearing, view_option
from locoman.to.io import TRAJECTORY, TRAJECTORY_FILE

log = logging.getLogger(__name__)

MCAP_FILE = "executed.mcap"
VIDEO_FILE = "motion.mp4"
MCAP_PERIOD_S = 0.01  # [s]
# The video runs this long past the step an execution stopped at [s]: a frozen fall beside
# the rest of the plan would be most of a failed run's rendering (S1: 10 s of video).
AFTER_STOP_S = 1.0


def _planned_qpos(model: mujoco.MjModel, ref: Reference, names: list[str], i: int) -> np.ndarray:
    return scene_qpos(model, g1.pin_to_q35(ref.q[i]), names, ref.object_q[i])


def _frame(
    renderer: mujoco.Renderer,
    model: mujoco.MjModel,
    data: mujoco.MjData,
    qpos: np.ndarray,
    bearing: float,
    label: str,
) -> np.ndarray:
    data.qpos[:] = qpos
    mujoco.mj_forward(model, data)
    # The camera follows the base (the scene's first joint, the G1's free joint).
    base = np.r_[qpos[:3], quat_xyzw_to_rpy(wxyz_to_xyzw(qpos[3:7]))]
    renderer.update_scene(data, camera=camera.follow(base, bearing), scene_option=view_option())
    image = renderer.render().copy()
    cv2.putText(
        image, label, (6, 18), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (255, 255, 255), 1, cv2.LINE_AA
    )
    return image


def _pairs(
    model: mujoco.MjModel,
    executed: Execution,
    ref: Reference,
    names: list[str],
    samples: np.ndarray,
    size: tuple[int, int],
    bearing: float,
) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """(executed, planned) renders at the reference's samples ``samples``; after a fall the
    executed side keeps its last state."""
    width, height = size
    data = mujoco.MjData(model)
    with mujoco.Renderer(model, height=height, width=width) as renderer:
        for i in samples:
            j = min(int(i), len(executed.time) - 1)
            t = ref.time[i]
            done = "" if j == i else " (stopped)"
            label = f"executed t={t:.2f}s{done}"
            planned = _planned_qpos(model, ref, names, i)
            yield (
                _frame(renderer, model, data, executed.qpos[j], bearing, label),
                _frame(renderer, model, data, planned, bearing, "planned"),
            )


def filmstrip(
    model: mujoco.MjModel,
    executed: Execution,
    ref: Reference,
    names: list[str],
    frames: int,
    bearing: float,
) -> np.ndarray:
    """Executed (top row) above planned (bottom row) at ``frames`` evenly spaced times."""
    samples = np.linspace(0, len(ref) - 1, frames).round().astype(int)
    pairs = list(_pairs(model, executed, ref, names, samples, (TILE, TILE), bearing))
    top = np.hstack([fit_tile(a, TILE)[0] for a, _ in pairs])
    bottom = np.hstack([fit_tile(b, TILE)[0] for _, b in pairs])
    return np.vstack([top, bottom])


def motion_frames(
    model: mujoco.MjModel, executed: Execution, ref: Reference, names: list[str], bearing: float
) -> Iterator[np.ndarray]:
    """Executed beside planned, in real time at :data:`VIDEO_FPS`, to the end of the
    reference or :data:`AFTER_STOP_S` past where the execution stopped."""
    dt = ref.time[1] - ref.time[0]
    end = (
        len(ref)
        if executed.completed
        else min(len(ref), len(executed.time) + round(AFTER_STOP_S / dt))
    )
    samples = np.arange(0, end, max(1, round(1.0 / (VIDEO_FPS * dt))))
    half = (VIDEO_SIZE[0] // 2, VIDEO_SIZE[1])
    for a, b in _pairs(model, executed, ref, names, samples, half, bearing):
        yield np.hstack([a, b])


def write_executed_mcap(
    path: Path,
    model: mujoco.MjModel,
    executed: Execution,
    ref: Reference,
    names: list[str],
    state: np.ndarray,
) -> None:
    """Link and object poses every :data:`MCAP_PERIOD_S`, the planned and executed base and
    palm positions on ``/tracking``, and the scene drawn at ``state`` (its initial qpos)."""
    dt = ref.time[1] - ref.time[0]
    rows = np.arange(0, len(executed.time), max(1, round(MCAP_PERIOD_S / dt)))
    frames: dict[str, tuple[list, list]] = {}
    for i in rows:
        for name, (pos, quat) in g1.link_poses(executed.q[i]).items():
            entry = frames.setdefault(name, ([], []))
            entry[0].append(pos)
            entry[1].append(quat)
        for j, name in enumerate(names):
            quat = np.zeros(4)
            mujoco.mju_mat2Quat(quat, executed.object_rotation[i, j].ravel())
            entry = frames.setdefault(name, ([], []))
            entry[0].append(executed.object_position[i, j])
            entry[1].append(quat)
    poses = {name: (np.array(p), np.array(q)) for name, (p, q) in frames.items()}
    palms = frame_positions(executed.q[rows], PALMS)
    signals = {
        "/tracking": {
            "base_planned": ref.q[rows, :3],
            "base_executed": executed.q[rows, :3],
            "left_palm_planned": ref.frames[PALMS[0]].position[rows],
            "left_palm_executed": palms[:, 0],
            "right_palm_planned": ref.frames[PALMS[1]].position[rows],
            "right_palm_executed": palms[:, 1],
        }
    }
    entities = scene_entities(model, state, moving=set(poses))
    write_mcap(path, executed.time[rows], poses, signals, entities=entities)


def execution_setup(
    scene_dir: Path, traj: dict[str, np.ndarray], cfg: ExecuteCfg
) -> tuple[Reference, mujoco.MjModel]:
    """The controller's reference (:func:`locoman.execute.balance.execution_reference`)
    and MuJoCo's model of the scene, the palms' torsional friction the TO's palm patch's
    on its most frictional object."""
    ref = execution_reference(traj, cfg)
    friction = float(np.max(traj["object_friction"], initial=0.0))
    torsion = palm_torsion(friction, traj["palm_half_extents"])
    return ref, execution_mjmodel(load_scene_spec(scene_dir), cfg, torsion)


def execute_scenario(scene_dir: Path, solve_dir: Path, out_dir: Path, cfg: ExecuteCfg) -> dict:
    """Execute, measure, and write the metrics, the MCAP and (``cfg.video``) the pictures;
    returns the metrics."""
    traj = read_npz(solve_dir / TRAJECTORY_FILE, TRAJECTORY)
    names = [str(name) for name in traj["object_names"]]
    ref, model = execution_setup(scene_dir, traj, cfg)
    executed = execute(model, ref, names, cfg, float(traj["floor_friction"]))
    metrics = execution_metrics(model, executed, ref, traj, cfg)
    write_executed_mcap(
        out_dir / MCAP_FILE, model, executed, ref, names, load_state(scene_dir)["qpos"]
    )
    if cfg.video:
        media_quality(model)
        bearing = view_bearing(model, traj, cfg.filmstrip_frames)
        strip = filmstrip(model, executed, ref, names, cfg.filmstrip_frames, bearing)
        write_png(out_dir / "plots" / "filmstrip.png", strip)
        write_mp4(
            out_dir / VIDEO_FILE, motion_frames(model, executed, ref, names, bearing), VIDEO_FPS
        )
    write_metrics(out_dir, metrics)
    log.info(
        "execute: %s, up %.2f of %.2f s, failed: %s",
        "success" if metrics["success"] else "failed",
        metrics["time_up_s"],
        metrics["duration_s"],
        ", ".join(metrics["failed_checks"]) or "none",
    )
    return metrics
