"""The TO's inputs (:class:`locoman.to.problem.inputs.TOInputs`) read from a scenario's artifacts:
the scene (objects, plan, initial state), the contacts per subtask and the G1 keyframes."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from locoman.artifacts import read_npz
from locoman.contact.io import CONTACT_FIELDS, CONTACTS
from locoman.contact.io import subtask_file as contact_file
from locoman.contact.surface import closest_on_primitive
from locoman.errors import ArtifactError
from locoman.retarget.io import KEYFRAME, keyframe_file
from locoman.retarget.robot import contact_frames
from locoman.scene import g1
from locoman.scene.io import load_objects, load_plan, load_scene_model, load_state
from locoman.scene.objects import Primitive
from locoman.scene.plan_state import AS_BUILT, REST_TOL_M, top_face, world_pose
from locoman.scene.rotations import matrix_to_rpy, quat_wxyz_to_matrix
from locoman.to.problem.inputs import Keyframe, TOInputs, object_pose
from locoman.to.problem.layout import FEET, HANDS
from locoman.to.problem.objects import ObjectModel, obstacles_from_objects
from locoman.to.terms.supports import Chassis, OnObject, Support, Surface


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


def palm_reach() -> float:
    """How far a G1 palm reaches from its contact point along its capsule [m]: its half
    length and its radius."""
    frames = contact_frames()
    return float(frames.palm_half_length + frames.palm_radius)


def palms_on_the_bar(
    points: np.ndarray, frames: np.ndarray, spec: dict, reach: float
) -> tuple[np.ndarray, np.ndarray]:
    """The hands' contacts gripping a handle bar (a trolley's), ``points`` (2, 3) [m] and
    ``frames`` (2, 3, 3) in the object's frame, moved along the bar until each palm,
    ``reach`` [m] either side of its contact, clears the posts that hold the bar's ends: a
    moved contact lands on the bar's surface again, its frame that surface's. Other
    objects' contacts, and those already clear, stay as they are.

    The hands grip where the person's did, near the ends of a bar as wide as a person's
    shoulders: a G1 palm there overlapped the post (58 mm, a failed scheduled-contact check),
    which no term keeps it out of, its grip being fixed to the bar.
    """
    prims = {p["name"]: p for p in spec["primitives"]}
    if "handle" not in prims or not {"post_left", "post_right"} <= prims.keys():
        return points, frames
    bar = prims["handle"]
    handle = Primitive(bar["shape"], tuple(bar["size"]), tuple(bar["pos"]), "handle")
    inner = min(abs(prims[p]["pos"][1]) - prims[p]["size"][1] for p in ("post_left", "post_right"))
    bound = max(inner - reach, 0.0)
    points, frames = np.array(points, dtype=float), np.array(frames, dtype=float)
    for i in np.flatnonzero(np.abs(points[:, 1]) > bound):
        moved = points[i].copy()
        moved[1] = np.clip(moved[1], -bound, bound)
        q, n = closest_on_primitive(moved[None], handle)
        points[i], frames[i] = q[0], contact_frame(n[0])
    return points, frames


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
        if j is None and sub["predicate"] not in ("walk", "step"):
            raise ArtifactError(
                f"subtask {sub['index']} ({sub['predicate']}) acts on {sub['object']!r}, which "
                "is fixed in the scene: only a walk or a step may name a fixed object"
            )
        goal, support, height, step_height = None, None, 0.0, 0.0
        if sub["target"] is not None:
            goal = np.r_[sub["target"]["pos_m"][:2], sub["target"]["yaw_rad"]]
        if sub["predicate"] == "place":
            support, height = support_at(specs, poses, names, sub["object"])
        if sub["predicate"] == "step":  # onto a movable object where the plan left it
            at = poses.get(sub["object"], world_pose(specs, AS_BUILT, sub["object"]))
            step_height = step_top(specs, {sub["object"]: at}, sub["object"])
        hands = any("hand" in c for c in sub["contacts"])
        if j is not None and sub["object"] not in touched and hands:
            touched.add(sub["object"])
            hand = _hand_contacts(contacts_dir, sub["index"], fields)
            points[j], frames[j] = palms_on_the_bar(*hand, specs[sub["object"]], palm_reach())
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
