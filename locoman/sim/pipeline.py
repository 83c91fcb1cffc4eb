"""Stage ``evaluate`` for one scenario: replay the TO's trajectory in MuJoCo and check it.

Layout under ``data/<scenario>/evaluate/``::

    metrics.json              penetration, residuals, friction, slip, goal, rest, success
                              and failed_checks (which of them failed)
    plots/penetration.csv     penetration per node (paper A, Fig. 5: penetration_m) and per
                              class (locoman.sim.penetration), for dvc plots
    plots/filmstrip.png       the motion, a few nodes side by side
    motion.mp4                the motion in real time, 30 frames per second
"""

from __future__ import annotations

import csv
import dataclasses
import io
from collections.abc import Iterator
from pathlib import Path

import cv2
import mujoco
import numpy as np

from locoman.artifacts import (
    read_npz,
    write_metrics,
    write_png,
    write_text_atomic,
)
from locoman.artifacts.pictures import fit_tile
from locoman.artifacts.video import write_mp4
from locoman.config.to import EvaluateCfg
from locoman.retarget.robot import contact_frames
from locoman.scene import g1
from locoman.scene.io import load_objects, load_scene_model
from locoman.scene.rotations import rpy_to_matrix
from locoman.sim import camera
from locoman.sim.audit import unscheduled_penetrations
from locoman.sim.evaluate import (
    dynamics_residuals,
    friction_violation,
    nonholonomic_tangent,
    nonholonomic_violation,
    object_at_rest,
    scene_qpos,
    stance_slip,
    stance_turn,
    support_slip,
)
from locoman.sim.media import media_quality
from locoman.sim.penetration import CLASSES, HEADLINE, Penetrations, penetrations
from locoman.to.io import TRAJECTORY, TRAJECTORY_FILE
from locoman.to.problem.objects import ObjectModel

TILE = 320
VIDEO_FILE = "motion.mp4"
VIDEO_FPS = 30.0  # [1/s]
VIDEO_SIZE = (640, 480)  # width, height [px]


def view_option() -> mujoco.MjvOption:
    """The G1's visual meshes, not its collision primitives."""
    option = mujoco.MjvOption()
    option.geomgroup[:] = 1
    option.geomgroup[g1.COLLISION_GROUP] = 0
    return option


def _render(
    renderer: mujoco.Renderer,
    model: mujoco.MjModel,
    data: mujoco.MjData,
    q: np.ndarray,
    names: list[str],
    object_q: np.ndarray,
    label: str,
    bearing: float,
) -> np.ndarray:
    """The scene with the G1 at ``q`` (35,) and the objects ``names`` at ``object_q``
    (M, 6), seen from ``bearing`` [deg] off the robot's heading (:func:`camera.follow`),
    ``label`` written in its top left corner."""
    data.qpos[:] = scene_qpos(model, q, names, object_q)
    mujoco.mj_forward(model, data)
    renderer.update_scene(data, camera=camera.follow(q, bearing), scene_option=view_option())
    image = renderer.render().copy()
    # White on the image's top band (black was unreadable on the letterbox).
    cv2.putText(
        image, label, (6, 18), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (255, 255, 255), 1, cv2.LINE_AA
    )
    return image


def filmstrip_nodes(traj: dict[str, np.ndarray], frames: int) -> np.ndarray:
    """The ``frames`` evenly spaced nodes the filmstrip shows."""
    return np.linspace(0, len(traj["q"]) - 1, frames).round().astype(int)


def view_bearing(model: mujoco.MjModel, traj: dict[str, np.ndarray], frames: int) -> float:
    """The camera's bearing [deg] for this motion: the side from which the scene hides the
    least of the robot at the filmstrip's nodes (:func:`camera.best_bearing`)."""
    names = object_names(traj)
    nodes = filmstrip_nodes(traj, frames)
    states = [scene_qpos(model, traj["q"][k], names, traj["object_q"][k]) for k in nodes]
    return camera.best_bearing(model, view_option(), states, [traj["q"][k] for k in nodes])


def filmstrip(
    model: mujoco.MjModel, traj: dict[str, np.ndarray], frames: int, bearing: float
) -> np.ndarray:
    """Renders of evenly spaced nodes, two rows, seen from ``bearing`` [deg]."""
    data = mujoco.MjData(model)
    time = np.r_[0.0, np.cumsum(traj["dt"][:-1])]
    names = object_names(traj)
    tiles = []
    with mujoco.Renderer(model, height=TILE, width=TILE) as renderer:
        for k in filmstrip_nodes(traj, frames):
            label = f"t={time[k]:.2f}s {traj['phase'][k]}"
            q, object_q = traj["q"][k], traj["object_q"][k]
            image = _render(renderer, model, data, q, names, object_q, label, bearing)
            tiles.append(fit_tile(image, TILE)[0])
    while len(tiles) % 2:
        tiles.append(np.full_like(tiles[0], 255))
    half = len(tiles) // 2
    return np.vstack([np.hstack(tiles[:half]), np.hstack(tiles[half:])]) if half else tiles[0]


def motion_frames(
    model: mujoco.MjModel,
    traj: dict[str, np.ndarray],
    fps: float,
    size: tuple[int, int],
    bearing: float,
) -> Iterator[np.ndarray]:
    """Frames (height, width, 3) of the motion in real time at ``fps`` [1/s]: robot and object
    interpolated linearly between the nodes, the camera following the robot from ``bearing``
    [deg] off its heading."""
    time = np.r_[0.0, np.cumsum(traj["dt"][:-1])]
    names = object_names(traj)
    width, height = size
    data = mujoco.MjData(model)
    with mujoco.Renderer(model, height=height, width=width) as renderer:
        for t in np.arange(0.0, time[-1] + 0.5 / fps, 1.0 / fps):
            q = np.array([np.interp(t, time, c) for c in traj["q"].T])
            objects = traj["object_q"].reshape(len(time), -1)  # (N, M * 6), M may be 0
            o = np.array([np.interp(t, time, c) for c in objects.T]).reshape(-1, 6)
            k = min(int(np.searchsorted(time, t, side="right")), len(time) - 1)
            label = f"t={t:.2f}s {traj['phase'][k]}"
            yield _render(renderer, model, data, q, names, o, label, bearing)


def pose_matrix(pose: np.ndarray) -> np.ndarray:
    """(4, 4) of a (p, rpy) pose."""
    out = np.eye(4)
    out[:3, :3], out[:3, 3] = rpy_to_matrix(pose[3:6]), pose[:3]
    return out


def goal_metrics(traj: dict[str, np.ndarray], names: list[str]) -> dict[str, float]:
    """Per object with a goal: ``<name>_goal_error_m``, the distance [m] of its xy from the
    goal's, and ``<name>_goal_yaw_error_rad``, at the node its subtask ends."""
    out = {}
    for j, name in enumerate(names):
        node, goal = int(traj["goal_node"][j]), traj["object_goal"][j]
        if node < 0:
            continue
        pose = traj["object_q"][node, j]
        out[f"{name}_goal_error_m"] = float(np.linalg.norm(pose[:2] - goal[:2]))
        yaw = float(abs(np.remainder(pose[5] - goal[2] + np.pi, 2 * np.pi) - np.pi))
        out[f"{name}_goal_yaw_error_rad"] = yaw
    return out


def held_lifts(traj: dict[str, np.ndarray], names: list[str]) -> dict[str, float]:
    """Per object both hands hold off any support at the end (it ends at rest in them; a
    ``place`` ends with the hands still on a supported object): how far [m] its frame's
    origin, its bottom, ends above where it was last supported."""
    out = {}
    for j, name in enumerate(names):
        if not np.all(traj["hand_object"][-1] == j) or traj["support_kind"][-1, j] != "none":
            continue
        supported = np.flatnonzero(traj["support_kind"][:, j] != "none")
        base = traj["object_q"][supported[-1] if supported.size else 0, j, 2]
        out[name] = float(traj["object_q"][-1, j, 2] - base)
    return out


def object_names(traj: dict[str, np.ndarray]) -> list[str]:
    return [str(name) for name in traj["object_names"]]


# Trajectory fields in which NaN means "none" (no goal, no rear axle).
NAN_MEANS_NONE = ("object_goal", "rear_axle_x")


def all_finite(traj: dict[str, np.ndarray]) -> bool:
    """Every floating-point array of the trajectory is finite (a NaN in q replays as no
    penetration at all), but for :data:`NAN_MEANS_NONE`."""
    return all(
        bool(np.all(np.isfinite(v)))
        for name, v in traj.items()
        if name not in NAN_MEANS_NONE
        and isinstance(v, np.ndarray)
        and np.issubdtype(v.dtype, np.floating)
    )


def penetration_csv(time: np.ndarray, found: Penetrations) -> str:
    """Fig. 5's curve: per node its time [s], paper A's penetration [m] (``penetration_m``),
    each class's (``<class>_m``) and the sum over every contact (``contact_sum_m``)."""
    columns = [found.per_node(HEADLINE)] + [found.per_node((kind,)) for kind in CLASSES]
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(
        ["node", "time_s", "penetration_m", *(f"{kind}_m" for kind in CLASSES), "contact_sum_m"]
    )
    for k, t in enumerate(time):
        values = [c[k] for c in columns] + [found.contact_sum[k]]
        writer.writerow([k, f"{t:.6f}", *(f"{v:.9f}" for v in values)])
    return buffer.getvalue()


def evaluate_scenario(
    scene_dir: Path, solve_dir: Path, out_dir: Path, cfg: EvaluateCfg, media: bool = True
) -> dict:
    """Replay, check, and write the metrics and the penetration curve, and with ``media``
    the filmstrip and the MP4 (a grid's cells leave them out: rendering is most of the
    evaluation's time); returns the metrics."""
    traj = read_npz(solve_dir / TRAJECTORY_FILE, TRAJECTORY)
    model = load_scene_model(scene_dir)
    names = object_names(traj)
    specs = load_objects(scene_dir)
    objects = [ObjectModel.from_spec(name, specs[name]) for name in names]
    sole_centre = contact_frames().sole["left_sole"]
    found = penetrations(model, traj)
    per_node = found.per_node(HEADLINE)
    by_class = found.by_class()
    between, by_body = unscheduled_penetrations(model, traj, cfg.substeps)
    residuals = dynamics_residuals(traj, objects, sole_centre)
    friction = friction_violation(traj, sole_centre)
    slip = stance_slip(traj, sole_centre)
    avg = float(per_node.sum() / len(per_node))
    worst = int(np.argmax(per_node))
    worst_pair = found.deepest(HEADLINE, worst)
    metrics = {
        "solve_status": str(traj["status"]),
        "avg_penetration_m": avg,
        "max_penetration_m": float(per_node.max()),
        "max_penetration_node": worst,
        "max_penetration_pair": [] if worst_pair is None else list(worst_pair.geoms),
        "penetration_by_class": by_class,
        "contact_sum_penetration_avg_m": float(found.contact_sum.mean()),
        "contact_sum_penetration_max_m": float(found.contact_sum.max()),
        "max_unscheduled_penetration_between_nodes_m": between,
        "deepest_penetration": {
            body: dataclasses.asdict(p) | {"pair": list(p.pair)}
            for body, p in sorted(by_body.items())
        },
        "dynamics_residual_max": residuals.max,
        "dynamics_residuals": {
            "robot_momentum": residuals.robot_momentum,
            "robot_configuration": residuals.robot_configuration,
            **{f"{name}_momentum": h for name, (h, _) in residuals.objects.items()},
            **{f"{name}_configuration": c for name, (_, c) in residuals.objects.items()},
        },
        "friction_cone_violation_max": friction,
        "stance_foot_slip_max_m": slip,
        "stance_foot_turn_max_rad": stance_turn(traj, sole_centre),
        "duration_s": float(traj["dt"][:-1].sum()),
    }
    goal_errors = goal_metrics(traj, names)
    metrics |= goal_errors
    metrics["object_goal_error_m"] = max(
        (v for k, v in goal_errors.items() if k.endswith("_goal_error_m")), default=0.0
    )
    metrics["object_goal_yaw_error_rad"] = max(
        (v for k, v in goal_errors.items() if k.endswith("_goal_yaw_error_rad")), default=0.0
    )
    final = {name: pose_matrix(traj["object_q"][-1, j]) for j, name in enumerate(names)}
    lifts = held_lifts(traj, names)
    rest = {
        name: (
            (bool(np.abs(traj["object_v"][-1, j]).max() <= cfg.rest_speed_tol), "hands")
            if name in lifts
            else object_at_rest(
                specs,
                name,
                final,
                traj["object_q"][-1, j],
                traj["object_v"][-1, j],
                cfg.rest_height_tol_m,
                cfg.rest_speed_tol,
                cfg.rest_tilt_tol_rad,
            )
        )
        for j, name in enumerate(names)
    }
    metrics["supports_at_end"] = {name: support for name, (_, support) in rest.items()}
    # success means every one of these; NaN fails every comparison.
    checks = {
        "solver_converged": bool(traj["success"]),
        "finite": all_finite(traj),
        "dynamics_residual": residuals.max <= cfg.dynamics_tol,
        "friction_cone": friction <= cfg.friction_tol,
        "stance_foot_slip": slip <= cfg.slip_tol_m,
        "avg_penetration": avg <= cfg.penetration_tol_m,
        "max_penetration": max(float(per_node.max()), between) <= cfg.max_penetration_tol_m,
        # Per contact: two loaded soles 2.5 mm deep in MuJoCo's soft floor are two
        # contacts within the bound, not one 5 mm deep.
        "scheduled_contact_penetration": found.deepest_depth(("scheduled_contact",))
        <= cfg.scheduled_contact_tol_m,
        "object_penetration": by_class["object_environment"]["max_m"]
        <= cfg.object_penetration_tol_m,
        "object_goal": metrics["object_goal_error_m"] <= cfg.goal_tol_m,
        "objects_at_rest_on_support": all(at_rest for at_rest, _ in rest.values()),
    }
    if np.any(traj["support_kind"] == "chassis"):
        lateral = nonholonomic_violation(traj)
        metrics["nonholonomic_violation_max_mps"] = lateral
        metrics["nonholonomic_tangent_max_mps"] = nonholonomic_tangent(traj)
        checks["nonholonomic"] = lateral <= cfg.nonholonomic_tol_mps
    for name, lift in lifts.items():
        metrics[f"{name}_lift_m"] = lift
        checks[f"{name}_lift"] = lift >= cfg.lift_tol_m
    for pair, value in support_slip(traj, [obj.half_extents for obj in objects]).items():
        metrics[f"{pair}_slip_max_m"] = value
        checks[f"{pair}_slip"] = value <= cfg.rider_slip_tol_m
    metrics["failed_checks"] = [name for name, passed in checks.items() if not passed]
    metrics["success"] = not metrics["failed_checks"]
    time = np.r_[0.0, np.cumsum(traj["dt"][:-1])]
    write_text_atomic(out_dir / "plots" / "penetration.csv", penetration_csv(time, found))
    if media:
        media_quality(model)
        bearing = view_bearing(model, traj, cfg.filmstrip_frames)
        strip = filmstrip(model, traj, cfg.filmstrip_frames, bearing)
        write_png(out_dir / "plots" / "filmstrip.png", strip)
        video = motion_frames(model, traj, VIDEO_FPS, VIDEO_SIZE, bearing)
        write_mp4(out_dir / VIDEO_FILE, video, VIDEO_FPS)
    write_metrics(out_dir, metrics)
    return metrics
