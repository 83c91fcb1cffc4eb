"""Stage ``solve`` for one scenario: the TO from the scene, the contacts and the keyframes."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from locoman.artifacts import read_npz, write_metrics, write_npz
from locoman.artifacts.mcap_io import write_frame_transforms
from locoman.config.to import SolveCfg
from locoman.contact.io import CONTACT_FIELDS, CONTACTS
from locoman.contact.io import subtask_file as contact_file
from locoman.errors import ArtifactError
from locoman.retarget.io import KEYFRAME, keyframe_file
from locoman.retarget.robot import contact_frames
from locoman.scene import g1
from locoman.scene.io import load_objects, load_plan, load_scene_model, load_state
from locoman.scene.rotations import matrix_to_rpy, quat_wxyz_to_matrix, rpy_to_matrix
from locoman.sim.foxglove import scene_entities
from locoman.to.collision import obstacles_from_objects
from locoman.to.compile import cache_dir
from locoman.to.io import MCAP_FILE, TRAJECTORY, TRAJECTORY_FILE
from locoman.to.layout import HANDS, ObjectModel
from locoman.to.trajopt import (
    Keyframe,
    TOInputs,
    Trajectory,
    TrajectoryOptimizer,
    object_pose,
)


def start_configuration(scene_dir: Path) -> np.ndarray:
    """The G1's q35 in the scene's initial state."""
    model = load_scene_model(scene_dir)
    qpos = load_state(scene_dir)["qpos"]
    adr = model.joint("floating_base_joint").qposadr[0]
    rpy = matrix_to_rpy(quat_wxyz_to_matrix(qpos[adr + 3 : adr + 7]))
    return np.r_[qpos[adr : adr + 3], rpy, qpos[g1.mujoco_joint_qpos_indices(model)]]


def manipulated_object(plan: dict[str, Any]) -> str:
    """The one object the hands touch (the TO models one)."""
    names = {s["object"] for s in plan["subtasks"] if any("hand" in c for c in s["contacts"])}
    if len(names) != 1:
        raise ArtifactError(
            f"the TO models one manipulated object; the plan's hands touch {sorted(names)}"
        )
    return names.pop()


def contact_frame(normal: np.ndarray) -> np.ndarray:
    """A rotation (3, 3) whose z column is ``normal`` and whose x is horizontal."""
    n = np.asarray(normal, dtype=float) / np.linalg.norm(normal)
    x = np.cross([0.0, 0.0, 1.0], n)
    x = x / np.linalg.norm(x) if np.linalg.norm(x) > 1e-6 else np.array([1.0, 0.0, 0.0])
    return np.column_stack([x, np.cross(n, x), n])


def load_inputs(
    scene_dir: Path, contacts_dir: Path, retarget_dir: Path, contacts: str = "registration"
) -> TOInputs:
    """The TO's view of a scenario. The hands hold the object from the first subtask that
    touches it to the end, at that subtask's contacts of the method ``contacts`` (a key of
    :data:`CONTACT_FIELDS`)."""
    points_field, normals_field = CONTACT_FIELDS[contacts]
    plan = load_plan(scene_dir)
    name = manipulated_object(plan)
    spec = load_objects(scene_dir)[name]
    obj = ObjectModel.from_spec(name, spec)
    start = np.r_[spec["pos_m"], 0.0, 0.0, spec["yaw_rad"]]
    keyframes = []
    for sub in plan["subtasks"]:
        kf = read_npz(keyframe_file(retarget_dir, sub["index"]), KEYFRAME)
        goal = None
        if sub["target"] is not None:
            goal = np.r_[sub["target"]["pos_m"][:2], sub["target"]["yaw_rad"]]
        keyframes.append(
            Keyframe(sub["predicate"], kf["q35"], object_pose(kf["T_world_object"]), goal)
        )
    first = next(s for s in plan["subtasks"] if s["object"] == name)
    contacts = read_npz(contact_file(contacts_dir, first["index"]), CONTACTS)
    effectors = [str(e) for e in contacts["effectors"]]
    R = contacts["T_world_object"][:3, :3]
    missing = [h for h in HANDS if h not in effectors]
    if missing:
        raise ArtifactError(f"contacts of subtask {first['index']} lack {missing}")
    rows = [effectors.index(h) for h in HANDS]
    points = contacts[points_field][rows]
    frames = np.array([contact_frame(R.T @ contacts[normals_field][r]) for r in rows])
    obstacles = obstacles_from_objects(load_objects(scene_dir))
    return TOInputs(
        start_configuration(scene_dir), start, obj, keyframes, points, frames, obstacles
    )


def _poses(traj: Trajectory, object_name: str) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Link and object poses over the nodes: positions (N, 3), quaternions (N, 4) wxyz."""
    out: dict[str, tuple[list, list]] = {}
    for q, q_obj in zip(traj.q, traj.object_q, strict=True):
        for name, (pos, quat) in g1.link_poses(g1.q35_to_pin(q)).items():
            entry = out.setdefault(name, ([], []))
            entry[0].append(pos)
            entry[1].append(quat)
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, rpy_to_matrix(q_obj[3:6]).ravel())
        entry = out.setdefault(object_name, ([], []))
        entry[0].append(q_obj[:3])
        entry[1].append(quat)
    return {k: (np.array(p), np.array(r)) for k, (p, r) in out.items()}


def build_optimizer(inputs: TOInputs, cfg: SolveCfg) -> TrajectoryOptimizer:
    """The TO of ``inputs`` with the settings of ``cfg`` (compiled, or loaded from the
    cache, once per problem structure)."""
    optimizer = TrajectoryOptimizer(
        inputs,
        cfg.schedule,
        cfg.weights,
        cfg.contact,
        cfg.collision,
        cfg.solver,
        cache_dir(cfg.cache_dir),
    )
    print(
        f"[solve] {optimizer.schedule.nodes} nodes, {optimizer.nlp.n_x} variables, "
        f"{optimizer.nlp.n_g} constraints, built in {optimizer.nlp.build_time_s:.1f} s",
        flush=True,
    )
    return optimizer


def solve_scenario(
    scene_dir: Path, contacts_dir: Path, retarget_dir: Path, out_dir: Path, cfg: SolveCfg
) -> Trajectory:
    """Build and solve the TO; write the trajectory, its MCAP and the solver's metrics. A
    failed solve is written too, with its status."""
    inputs = load_inputs(scene_dir, contacts_dir, retarget_dir, cfg.contacts)
    optimizer = build_optimizer(inputs, cfg)
    traj = optimizer.solve((cfg.keyframe_base, cfg.keyframe_foot))
    write_solution(out_dir, traj, inputs, optimizer, cfg, scene_dir)
    return traj


def write_solution(
    out_dir: Path,
    traj: Trajectory,
    inputs: TOInputs,
    optimizer: TrajectoryOptimizer,
    cfg: SolveCfg,
    scene_dir: Path,
) -> None:
    """The stage's outputs: trajectory, MCAP (frames and the scene's geometry), metrics (and
    timing)."""
    n = optimizer.schedule.nodes
    goal = next((kf.goal for kf in reversed(inputs.keyframes) if kf.goal is not None), None)
    write_npz(
        out_dir / TRAJECTORY_FILE,
        TRAJECTORY,
        {
            "status": traj.status,
            "success": np.array(traj.success),
            "q": traj.q,
            "v": traj.v,
            "foot_wrench": traj.foot_wrench,
            "hand_wrench": traj.hand_wrench,
            "hand_points": traj.hand_points,
            "object_q": traj.object_q,
            "object_v": traj.object_v,
            "support_wrench": traj.support_wrench,
            "foot_slack": traj.foot_slack,
            "hand_slack": traj.hand_slack,
            "dt": traj.dt,
            "feet_contact": traj.feet_contact,
            "hands_contact": traj.hands_contact,
            "object_active": traj.object_active,
            "object_supported": traj.object_supported,
            "phase": traj.phase,
            "subtask": traj.subtask,
            "object_goal": goal if goal is not None else np.full(3, np.nan),
            "object_name": inputs.obj.name,
            "mu": np.array([cfg.contact.floor_friction, inputs.obj.friction, inputs.obj.friction]),
            "sole_half_extents": contact_frames().sole_half_extents,
            "palm_half_extents": np.array(cfg.contact.palm_half_extents_m),
            "object_half_extents": inputs.obj.half_extents,
            "hand_frames": inputs.hand_frames,
            "prehensile": np.array(cfg.contact.prehensile),
        },
    )
    poses = _poses(traj, inputs.obj.name)
    model = load_scene_model(scene_dir)
    entities = scene_entities(model, load_state(scene_dir)["qpos"], moving=set(poses))
    write_frame_transforms(out_dir / MCAP_FILE, traj.time, poses, entities=entities)
    write_metrics(
        out_dir,
        {
            "status": traj.status,
            "success": traj.success,
            "iterations": traj.iterations,
            "solve_time_s": traj.solve_time_s,
            "build_time_s": traj.build_time_s,
            "n_variables": traj.n_variables,
            "n_constraints": traj.n_constraints,
            "max_constraint_violation": traj.max_constraint_violation,
            "cost": traj.cost,
            "nodes": n,
            "duration_s": float(traj.time[-1]),
            "phases": [[p.name, p.subtask, p.nodes] for p in optimizer.schedule.phases],
        },
    )
