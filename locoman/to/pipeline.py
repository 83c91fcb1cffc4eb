"""Stage ``solve`` for one scenario: the TO from the scene, the contacts and the keyframes."""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Sequence
from pathlib import Path

import mujoco
import numpy as np

from locoman.artifacts import write_metrics, write_npz
from locoman.artifacts.mcap_io import write_frame_transforms
from locoman.config.to import SolveCfg
from locoman.retarget.robot import contact_frames
from locoman.scene import g1
from locoman.scene.io import load_scene_model, load_state
from locoman.scene.rotations import rpy_to_matrix
from locoman.sim.audit import ClosePair
from locoman.sim.foxglove import scene_entities
from locoman.to.io import MCAP_FILE, TRAJECTORY, TRAJECTORY_FILE
from locoman.to.nlp.compile import cache_dir
from locoman.to.problem.inputs import TOInputs
from locoman.to.problem.loading import load_inputs
from locoman.to.problem.schedule import Schedule
from locoman.to.rounds.search import Round, search, solution_scene
from locoman.to.solve.optimizer import TrajectoryOptimizer
from locoman.to.solve.trajectory import Trajectory

log = logging.getLogger(__name__)


def _poses(traj: Trajectory, names: list[str]) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Link and object poses over the nodes: positions (N, 3), quaternions (N, 4) wxyz."""
    out: dict[str, tuple[list, list]] = {}
    for q, q_objects in zip(traj.q, traj.object_q, strict=True):
        for name, (pos, quat) in g1.link_poses(g1.q35_to_pin(q)).items():
            entry = out.setdefault(name, ([], []))
            entry[0].append(pos)
            entry[1].append(quat)
        for name, q_obj in zip(names, q_objects, strict=True):
            quat = np.zeros(4)
            mujoco.mju_mat2Quat(quat, rpy_to_matrix(q_obj[3:6]).ravel())
            entry = out.setdefault(name, ([], []))
            entry[0].append(q_obj[:3])
            entry[1].append(quat)
    return {k: (np.array(p), np.array(r)) for k, (p, r) in out.items()}


def object_goals(inputs: TOInputs, schedule: Schedule) -> tuple[np.ndarray, np.ndarray]:
    """(M, 3) each object's last goal (x, y [m], yaw [rad]; NaN: none) and (M,) the node it
    holds at, the last node of its subtask (-1: none)."""
    goals = np.full((len(inputs.objects), 3), np.nan)
    nodes = np.full(len(inputs.objects), -1, dtype=int)
    for i, kf in enumerate(inputs.keyframes):
        if kf.goal is not None:
            goals[kf.object] = kf.goal
            nodes[kf.object] = max(k for k in range(schedule.nodes) if schedule.subtask_of(k) == i)
    return goals, nodes


def build_optimizer(inputs: TOInputs, cfg: SolveCfg) -> TrajectoryOptimizer:
    """The TO of ``inputs`` with the settings of ``cfg`` (its terms compiled, or loaded from
    the cache, once per robot)."""
    optimizer = TrajectoryOptimizer(inputs, cfg, cache_dir(cfg.cache_dir))
    log.info(
        f"{optimizer.schedule.nodes} nodes, {optimizer.nlp.n_x} variables, "
        f"{optimizer.nlp.n_g} constraints, {len(optimizer.transcription.pairs)} collision "
        f"pairs, built in {optimizer.build_time_s:.1f} s"
    )
    return optimizer


def solve_scenario(
    scene_dir: Path, contacts_dir: Path, retarget_dir: Path, out_dir: Path, cfg: SolveCfg
) -> Trajectory:
    """Build and solve the TO; write the trajectory, its MCAP and the solver's metrics. A
    failed solve is written too, with its status."""
    inputs = load_inputs(scene_dir, contacts_dir, retarget_dir, cfg.contacts)
    optimizer = build_optimizer(inputs, cfg)
    traj = optimizer.solve()
    scene = solution_scene(optimizer, traj, cfg.collision)
    model = load_scene_model(scene_dir)
    found = search(optimizer, traj, model, scene, cfg.collision)
    write_solution(
        out_dir,
        found.trajectory,
        inputs,
        optimizer,
        cfg,
        scene_dir,
        found.rounds,
        found.missing,
        found.unfreed,
    )
    return found.trajectory


def write_solution(
    out_dir: Path,
    traj: Trajectory,
    inputs: TOInputs,
    optimizer: TrajectoryOptimizer,
    cfg: SolveCfg,
    scene_dir: Path,
    rounds: Sequence[Round] = (),
    remaining: Sequence[ClosePair] = (),
    unfreed: Sequence[ClosePair] = (),
) -> None:
    """The stage's outputs: trajectory, MCAP (frames and the scene's geometry), metrics (and
    timing)."""
    n = optimizer.schedule.nodes
    names = [obj.name for obj in inputs.objects]
    goals, goal_nodes = object_goals(inputs, optimizer.schedule)
    prehensile = [cfg.contact.prehensile or obj.prehensile for obj in inputs.objects]
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
            "object_names": np.array(names, dtype=str),
            "object_q": traj.object_q,
            "object_v": traj.object_v,
            "support_wrench": traj.support_wrench,
            "foot_slack": traj.foot_slack,
            "hand_slack": traj.hand_slack,
            "support_slack": traj.support_slack,
            "dt": traj.dt,
            "feet_contact": traj.feet_contact,
            "foot_object": traj.foot_object,
            "hand_object": traj.hand_object,
            "object_active": traj.object_active,
            "support_kind": traj.support_kind,
            "support_base": traj.support_base,
            "phase": traj.phase,
            "subtask": traj.subtask,
            "object_goal": goals,
            "goal_node": goal_nodes,
            "floor_friction": np.array(float(cfg.contact.floor_friction)),
            # Shapes and types written out: a scene may have no movable object (M = 0).
            "object_friction": np.array([obj.friction for obj in inputs.objects], dtype=float),
            "object_half_extents": np.array(
                [obj.half_extents for obj in inputs.objects], dtype=float
            ).reshape(-1, 2),
            "rear_axle_x": np.array(
                [np.nan if obj.rear_axle_x is None else obj.rear_axle_x for obj in inputs.objects],
                dtype=float,
            ),
            "prehensile": np.array(prehensile, dtype=bool),
            "sole_half_extents": contact_frames().sole_half_extents,
            "palm_half_extents": np.array(cfg.contact.palm_half_extents_m),
            "hand_points": traj.hand_points,
            "hand_frames": inputs.hand_frames,
        },
    )
    poses = _poses(traj, names)
    model = load_scene_model(scene_dir)
    entities = scene_entities(model, load_state(scene_dir)["qpos"], moving=set(poses))
    write_frame_transforms(out_dir / MCAP_FILE, traj.time, poses, entities=entities)
    write_metrics(
        out_dir,
        {
            "status": traj.status,
            "success": traj.success,
            "iterations": traj.iterations,
            "exact_hessian_iterations": traj.exact_iterations,
            "homotopy_alpha_max": traj.alpha_max,
            "solve_time_s": traj.solve_time_s,
            "build_time_s": traj.build_time_s,
            "n_variables": traj.n_variables,
            "n_constraints": traj.n_constraints,
            "max_constraint_violation": traj.max_constraint_violation,
            "cost": traj.cost,
            "nodes": n,
            "duration_s": float(traj.time[-1]),
            "phases": [[p.name, p.subtask, p.nodes] for p in optimizer.schedule.phases],
            "collision_pairs": traj.collision_pairs,
            "collision_rounds": [dataclasses.asdict(r) for r in rounds],
            "pairs_found": sum(r.pairs_added for r in rounds),
            "restarts": sum(r.restart for r in rounds),
            "pairs_missing": sorted({c.label for c in remaining}),
            "pairs_unfreed": sorted({c.label for c in unfreed}),
            "function_time_s": traj.function_time_s,
        },
    )
