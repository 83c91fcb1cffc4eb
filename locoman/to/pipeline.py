"""Stage ``solve`` for one scenario: the TO from the scene, the contacts and the keyframes."""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
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
from locoman.scene.plan_state import AS_BUILT, REST_TOL_M, top_face, world_pose
from locoman.scene.rotations import matrix_to_rpy, quat_wxyz_to_matrix, rpy_to_matrix
from locoman.sim.audit import ClosePair
from locoman.sim.foxglove import scene_entities
from locoman.to.collision import obstacles_from_objects
from locoman.to.compile import cache_dir
from locoman.to.inputs import Keyframe, TOInputs, object_pose
from locoman.to.io import MCAP_FILE, TRAJECTORY, TRAJECTORY_FILE
from locoman.to.layout import FEET, HANDS, ObjectModel
from locoman.to.optimizer import Trajectory, TrajectoryOptimizer
from locoman.to.pair_search import Round, Scene, search
from locoman.to.schedule import Schedule
from locoman.to.supports import Chassis, OnObject, Support, Surface


def start_configuration(scene_dir: Path) -> np.ndarray:
    """The G1's q35 in the scene's initial state."""
    model = load_scene_model(scene_dir)
    qpos = load_state(scene_dir)["qpos"]
    adr = model.joint("floating_base_joint").qposadr[0]
    rpy = matrix_to_rpy(quat_wxyz_to_matrix(qpos[adr + 3 : adr + 7]))
    return np.r_[qpos[adr : adr + 3], rpy, qpos[g1.mujoco_joint_qpos_indices(model)]]


def object_order(plan: dict[str, Any], objects: dict[str, dict]) -> list[str]:
    """The TO's objects: the scene's movable ones, in the order the plan first names them,
    then the rest by name."""
    movable = sorted(name for name, spec in objects.items() if spec["movable"])
    named = [s["object"] for s in plan["subtasks"] if s["object"] in movable]
    return list(dict.fromkeys(named + movable))


def support_at(
    objects: dict[str, dict], poses: dict[str, np.ndarray], names: list[str], name: str
) -> tuple[Support, float]:
    """What object ``name`` at ``poses[name]`` (4, 4) rests on, and that surface's height:
    a wheeled object on its chassis; else the top face of another object that holds its
    bottom centre (a movable one of ``names`` at ``poses``: :class:`OnObject`, the height in
    that object's frame; a fixed one: :class:`Surface` at its world height); else the floor.

    Raises:
        ArtifactError: If the object's bottom is neither on the floor nor on a top face.
    """
    if objects[name]["kind"] == "trolley":
        return Chassis(), 0.0
    bottom = poses[name][:3, 3]
    for other, spec in sorted(objects.items()):
        face = top_face(spec) if other != name else None
        if face is None:
            continue
        centre, half = face
        pose = poses.get(other, world_pose(objects, AS_BUILT, other))
        local = np.linalg.solve(pose, np.r_[bottom, 1.0])[:3] - centre
        if abs(local[2]) <= REST_TOL_M and np.all(np.abs(local[:2]) <= half):
            if other in poses:
                return OnObject(names.index(other)), float(centre[2])
            return Surface(), float(pose[2, 3] + centre[2])
    if abs(bottom[2]) <= REST_TOL_M:
        return Surface(), 0.0
    raise ArtifactError(
        f"{name} at {np.round(bottom, 3).tolist()} rests on nothing: neither on the floor "
        "nor on an object's top face"
    )


def step_top(objects: dict[str, dict], poses: dict[str, np.ndarray], name: str) -> float:
    """[m] world height of the top face of object ``name`` at ``poses[name]``.

    Raises:
        ArtifactError: If the object has no top face to stand on.
    """
    face = top_face(objects[name])
    if face is None:
        raise ArtifactError(f"a 'step' onto {name!r}, which has no top face to stand on")
    return float((poses[name] @ np.r_[face[0], 1.0])[2])


def contact_frame(normal: np.ndarray) -> np.ndarray:
    """A rotation (3, 3) whose z column is ``normal`` and whose x is horizontal."""
    n = np.asarray(normal, dtype=float) / np.linalg.norm(normal)
    x = np.cross([0.0, 0.0, 1.0], n)
    x = x / np.linalg.norm(x) if np.linalg.norm(x) > 1e-6 else np.array([1.0, 0.0, 0.0])
    return np.column_stack([x, np.cross(n, x), n])


def _hand_contacts(
    contacts_dir: Path, subtask: int, fields: tuple[str, str]
) -> tuple[np.ndarray, np.ndarray]:
    """(2, 3) left and right hand contacts in the object's frame [m] and (2, 3, 3) their
    contact frames, from one subtask's contacts."""
    points_field, normals_field = fields
    contacts = read_npz(contact_file(contacts_dir, subtask), CONTACTS)
    effectors = [str(e) for e in contacts["effectors"]]
    missing = [h for h in HANDS if h not in effectors]
    if missing:
        raise ArtifactError(f"contacts of subtask {subtask} lack {missing}")
    R = contacts["T_world_object"][:3, :3]
    rows = [effectors.index(h) for h in HANDS]
    frames = np.array([contact_frame(R.T @ contacts[normals_field][r]) for r in rows])
    return contacts[points_field][rows], frames


def _feet_on_object(contacts_dir: Path, subtask: int, contacts: str) -> np.ndarray | None:
    """(2, 2) x, y [m] of the left and right foot contacts of one subtask, when ``contacts``
    is the naive baseline and contact transfer put the feet on the object (S1's step);
    None otherwise.

    The TO takes the feet from the keyframe, which retargeting placed at the transferred
    contacts; the baseline's feet are the semantic model's output instead (paper A, Sec. V-A:
    "the contact locations of the hands or feet, depending on the task"). A foot on the
    floor is not a semantic match of the object, so it keeps the keyframe's sole.
    """
    if contacts == "registration":
        return None
    points_field, _ = CONTACT_FIELDS[contacts]
    data = read_npz(contact_file(contacts_dir, subtask), CONTACTS)
    effectors = [str(e) for e in data["effectors"]]
    if any(f not in effectors for f in FEET):
        return None
    rows = [effectors.index(f) for f in FEET]
    if any(str(data["surfaces"][r]) != "object" for r in rows):
        return None
    T = data["T_world_object"]
    return (data[points_field][rows] @ T[:3, :3].T + T[:3, 3])[:, :2]


def load_inputs(
    scene_dir: Path, contacts_dir: Path, retarget_dir: Path, contacts: str = "registration"
) -> TOInputs:
    """The TO's view of a scenario: every movable object, where it starts and what it rests
    on; per subtask its keyframe (every object where the plan left it), goal and, for a
    ``place``, what it sets its object on. The hands hold an object at the contacts of the
    first subtask that touches it, of the method ``contacts`` (a key of
    :data:`CONTACT_FIELDS`); the naive baseline's feet on an object replace the keyframe's
    in (10)."""
    fields = CONTACT_FIELDS[contacts]
    plan = load_plan(scene_dir)
    specs = load_objects(scene_dir)
    names = object_order(plan, specs)
    if not names:
        raise ArtifactError("the scene has no movable object for the TO")
    models = tuple(ObjectModel.from_spec(name, specs[name]) for name in names)
    scene_poses = {name: world_pose(specs, AS_BUILT, name) for name in names}
    starts = np.array([object_pose(scene_poses[name]) for name in names])
    supports = [support_at(specs, scene_poses, names, name) for name in names]
    points = np.zeros((len(names), 2, 3))
    frames = np.tile(np.eye(3), (len(names), 2, 1, 1))
    touched: set[str] = set()
    keyframes = []
    for sub in plan["subtasks"]:
        kf = read_npz(keyframe_file(retarget_dir, sub["index"]), KEYFRAME)
        movable = [str(m) for m in kf["movable_objects"]]
        poses = dict(zip(movable, kf["T_world_movable"], strict=True))
        j = names.index(sub["object"]) if sub["object"] in names else None
        if j is None and sub["predicate"] != "walk":
            raise ArtifactError(
                f"subtask {sub['index']} ({sub['predicate']}) acts on {sub['object']!r}, which "
                "is fixed in the scene: only a walk may name a fixed object"
            )
        goal, support, height, step_height = None, None, 0.0, 0.0
        if sub["target"] is not None:
            goal = np.r_[sub["target"]["pos_m"][:2], sub["target"]["yaw_rad"]]
        if sub["predicate"] == "place":
            support, height = support_at(specs, poses, names, sub["object"])
        if sub["predicate"] == "step":
            step_height = step_top(specs, poses, sub["object"])
        hands = any("hand" in c for c in sub["contacts"])
        if j is not None and sub["object"] not in touched and hands:
            touched.add(sub["object"])
            points[j], frames[j] = _hand_contacts(contacts_dir, sub["index"], fields)
        feet = None
        if any("foot" in c for c in sub["contacts"]):
            feet = _feet_on_object(contacts_dir, sub["index"], contacts)
        object_poses = np.array([object_pose(poses[name]) for name in names])
        keyframes.append(
            Keyframe(
                sub["predicate"],
                kf["q35"],
                j,
                object_poses,
                goal,
                support,
                height,
                step_height,
                feet,
            )
        )
    obstacles = obstacles_from_objects(specs)
    return TOInputs(
        start_configuration(scene_dir),
        models,
        starts,
        tuple(s for s, _ in supports),
        np.array([h for _, h in supports]),
        keyframes,
        points,
        frames,
        obstacles,
    )


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
    print(
        f"[solve] {optimizer.schedule.nodes} nodes, {optimizer.nlp.n_x} variables, "
        f"{optimizer.nlp.n_g} constraints, {len(optimizer.transcription.pairs)} collision "
        f"pairs, built in {optimizer.build_time_s:.1f} s",
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
    traj = optimizer.solve()
    obstacles = {o.name: o for o in inputs.obstacles}
    seats = tuple(tuple(m.seat for m in mode.objects) for mode in optimizer.modes)
    scene = Scene(inputs.objects, traj.object_q, obstacles, contact_frames(), seats=seats)
    model = load_scene_model(scene_dir)
    traj, rounds, remaining, unfreed = search(optimizer, traj, model, scene, cfg.collision)
    if (remaining or unfreed) and traj.success:
        # The rounds ran out with pairs the solution needs still missing, or left a pair
        # they could not free: not a solution.
        status = "Collision_Pairs_Missing" if remaining else "Collision_Pairs_Unfreed"
        traj = dataclasses.replace(traj, success=False, status=status)
    write_solution(out_dir, traj, inputs, optimizer, cfg, scene_dir, rounds, remaining, unfreed)
    return traj


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
            "object_names": np.array(names),
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
            "object_friction": np.array([obj.friction for obj in inputs.objects]),
            "object_half_extents": np.array([obj.half_extents for obj in inputs.objects]),
            "rear_axle_x": np.array(
                [np.nan if obj.rear_axle_x is None else obj.rear_axle_x for obj in inputs.objects]
            ),
            "prehensile": np.array(prehensile),
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
