"""Posing the human demonstrator for a subtask: contact targets and inverse kinematics.

The demonstrator faces the object's -x (approach) side, as the G1 does in every scenario.
Hands go on the object's graspable faces: the ``left``/``right`` patches when the object has
them (box, basket), else the patch facing the person (the trolley's handle). Feet stand on the
object's top when the subtask puts feet on an object low enough to step on; otherwise they
stand on the floor in front of it. A damped least-squares IK on the MuJoCo model then puts
palms and soles on their targets, palms facing the surfaces and soles flat.

Body-frame offsets below are for ``human_description``: in the upright zero posture every link
frame is the world frame turned +90 deg about x, so a world offset (a, b, c) is the local
(a, c, -b). The zero posture is the anatomical one: arms down, palms forward.
"""

from __future__ import annotations

import dataclasses

import mujoco
import numpy as np
from scipy.optimize import lsq_linear

from locoman.errors import SceneError
from locoman.scene import human
from locoman.scene.objects import ContactPatch

PALM = np.array([0.037, -0.077, 0.0])  # [m] palm centre in the hand frame
SOLE = np.array([0.072, -0.077, 0.0])  # [m] sole centre in the foot frame
TOE = np.array([0.207, -0.077, 0.0])  # [m] toe tip in the foot frame
HEAD = np.array([0.0, 0.1, 0.0])  # [m] centre of the head in the head frame
LOCAL_UP = np.array([0.0, 1.0, 0.0])  # world z of every link in the zero posture
LOCAL_FORWARD = np.array([1.0, 0.0, 0.0])  # world x (facing) in the zero posture
ORIGIN = np.zeros(3)

# Keypoints: name -> (body, offset in the body frame [m]). Hands, feet and pelvis are the
# ones contact transfer and retargeting use; the rest complete the skeleton.
KEYPOINTS: dict[str, tuple[str, np.ndarray]] = {
    "pelvis": ("middle_pelvis", ORIGIN),
    "neck": ("middle_head", ORIGIN),
    "head": ("middle_head", HEAD),
    "left_shoulder": ("left_upperarm", ORIGIN),
    "right_shoulder": ("right_upperarm", ORIGIN),
    "left_elbow": ("left_lowerarm", ORIGIN),
    "right_elbow": ("right_lowerarm", ORIGIN),
    "left_wrist": ("left_hand", ORIGIN),
    "right_wrist": ("right_hand", ORIGIN),
    "left_hand": ("left_hand", PALM),
    "right_hand": ("right_hand", PALM),
    "left_hip": ("left_upperleg", ORIGIN),
    "right_hip": ("right_upperleg", ORIGIN),
    "left_knee": ("left_lowerleg", ORIGIN),
    "right_knee": ("right_lowerleg", ORIGIN),
    "left_ankle": ("left_foot", ORIGIN),
    "right_ankle": ("right_foot", ORIGIN),
    "left_foot": ("left_foot", SOLE),
    "right_foot": ("right_foot", SOLE),
    "left_toe": ("left_foot", TOE),
    "right_toe": ("right_foot", TOE),
}
SKELETON = (
    ("pelvis", "neck"),
    ("neck", "head"),
    ("neck", "left_shoulder"),
    ("neck", "right_shoulder"),
    ("left_shoulder", "left_elbow"),
    ("left_elbow", "left_wrist"),
    ("left_wrist", "left_hand"),
    ("right_shoulder", "right_elbow"),
    ("right_elbow", "right_wrist"),
    ("right_wrist", "right_hand"),
    ("pelvis", "left_hip"),
    ("pelvis", "right_hip"),
    ("left_hip", "left_knee"),
    ("left_knee", "left_ankle"),
    ("left_ankle", "left_toe"),
    ("right_hip", "right_knee"),
    ("right_knee", "right_ankle"),
    ("right_ankle", "right_toe"),
)
END_EFFECTORS = ("left_hand", "right_hand", "left_foot", "right_foot")
STANCE_HALF_WIDTH = 0.11  # [m] lateral offset of each sole from the stance centre
HANDLE_HALF_SPAN = 0.2  # [m] hands on a bar sit this far either side of its middle
# A person holds an object's side faces a tenth above their middle, except a low object
# (face centre below about knee height): that one is held near its top, the way people lift
# a box off the floor without a deep crouch.
GRIP_V = 0.1  # [-] height on the face, in [-1, 1] of its half height
LOW_GRIP_V = 0.6  # [-]: the palm's edge at the top edge of a 0.3 m box
LOW_FACE_BELOW_M = 0.45  # [m] face centre above the floor


@dataclasses.dataclass(frozen=True)
class ContactTarget:
    """Where an end effector touches, in the object frame.

    Attributes:
        effector: ``left_hand``, ``right_hand``, ``left_foot`` or ``right_foot``.
        patch: Contact patch name, or ``floor`` for a foot beside the object.
        point: Contact point [m] (object frame).
        normal: Outward normal of the touched surface (object frame).
        patch_uv: Coordinates in the patch, each in [-1, 1] of its half extents (0 for floor).
    """

    effector: str
    patch: str
    point: np.ndarray
    normal: np.ndarray
    patch_uv: tuple[float, float]


@dataclasses.dataclass(frozen=True)
class Pose:
    """A posed demonstrator.

    Attributes:
        qpos: MuJoCo qpos (43,): pelvis position [m], quaternion (w, x, y, z), 36 joints [rad].
        residual_m: Largest distance between an end effector and its target [m].
        iterations: IK iterations run.
    """

    qpos: np.ndarray
    residual_m: float
    iterations: int


def patch_axes(patch: ContactPatch) -> tuple[np.ndarray, np.ndarray]:
    """In-plane unit axes (u, v) of a patch, matching ``objects.patch_corners``."""
    n = np.asarray(patch.normal, float)
    helper = np.array([0.0, 0.0, 1.0]) if abs(n[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    u = np.cross(helper, n)
    u /= np.linalg.norm(u)
    return u, np.cross(n, u)


def patch_point(patch: ContactPatch, uv: tuple[float, float]) -> np.ndarray:
    """The point at normalised coordinates ``uv`` (each in [-1, 1]) of a patch [m]."""
    u, v = patch_axes(patch)
    a, b = patch.half_extents
    return np.asarray(patch.centre) + uv[0] * a * u + uv[1] * b * v


def _uv_of(patch: ContactPatch, point: np.ndarray) -> tuple[float, float]:
    u, v = patch_axes(patch)
    d = np.asarray(point) - np.asarray(patch.centre)
    a, b = patch.half_extents
    return float(d @ u / a), float(d @ v / b)


def contact_targets(
    kind: str,
    patches: tuple[ContactPatch, ...],
    effectors: list[str],
    size: tuple[float, ...],
    step_height_max: float,
    base_height: float,
) -> list[ContactTarget]:
    """Contact targets in the object frame for the subtask's end effectors.

    Args:
        kind: Object kind (for messages).
        patches: The object's contact patches.
        effectors: End effectors the plan puts in contact.
        size: Object extents [m] (length first).
        step_height_max: Feet stand on the top patch up to this height [m].
        base_height: Height of the object's bottom above the floor [m] (a low object is
            held near its top).

    Raises:
        SceneError: When the object offers no surface for a requested end effector.
    """
    by_name = {p.name: p for p in patches}
    targets: list[ContactTarget] = []
    hands = [e for e in effectors if e.endswith("_hand")]
    feet = [e for e in effectors if e.endswith("_foot")]
    if hands:
        if "left" in by_name and "right" in by_name:
            # Grip the side faces slightly towards the person and above their middle.
            sides = {"left_hand": by_name["left"], "right_hand": by_name["right"]}
            uvs = {name: _side_uv(p, base_height) for name, p in sides.items()}
        else:
            facing = [p for p in patches if p.normal[0] < -0.9]
            if not facing:
                raise SceneError(
                    f"object kind {kind!r} has no left/right faces and no face towards the "
                    "person; add contact patches for the hands"
                )
            bar = facing[0]
            span = min(HANDLE_HALF_SPAN / bar.half_extents[0], 0.8)
            u, _ = patch_axes(bar)
            sign = 1.0 if u[1] > 0 else -1.0  # +u towards the person's left (+y)
            sides = {"left_hand": bar, "right_hand": bar}
            uvs = {"left_hand": (sign * span, 0.0), "right_hand": (-sign * span, 0.0)}
        for name in hands:
            p = sides[name]
            targets.append(
                ContactTarget(
                    name, p.name, patch_point(p, uvs[name]), np.asarray(p.normal), uvs[name]
                )
            )
    if feet:
        top = by_name.get("top")
        if top is not None and top.centre[2] <= step_height_max:
            for name in feet:
                side = 1.0 if name.startswith("left") else -1.0
                point = np.asarray(top.centre) + np.array([0.0, side * STANCE_HALF_WIDTH, 0.0])
                targets.append(
                    ContactTarget(name, "top", point, np.asarray(top.normal), _uv_of(top, point))
                )
        else:
            x = -0.5 * size[0] - 0.3  # stand in front of the object's approach face
            for name in feet:
                side = 1.0 if name.startswith("left") else -1.0
                point = np.array([x, side * STANCE_HALF_WIDTH, 0.0])
                targets.append(ContactTarget(name, "floor", point, np.array([0, 0, 1.0]), (0, 0)))
    return targets


def stepped_aside(
    target: ContactTarget, lateral: float, patches: tuple[ContactPatch, ...]
) -> ContactTarget:
    """``target`` moved ``lateral`` metres along the object's +y, as a foot moves when the
    person steps aside; a patch contact keeps its patch, with the coordinates of the moved
    point."""
    point = target.point + np.array([0.0, lateral, 0.0])
    if target.patch == "floor":
        return dataclasses.replace(target, point=point)
    patch = {p.name: p for p in patches}[target.patch]
    return dataclasses.replace(target, point=point, patch_uv=_uv_of(patch, point))


def _side_uv(patch: ContactPatch, base_height: float) -> tuple[float, float]:
    u, _ = patch_axes(patch)
    low = base_height + patch.centre[2] < LOW_FACE_BELOW_M
    # Towards the person (-x) by a quarter of the face; above its middle (see GRIP_V).
    return (-0.25 if u[0] > 0 else 0.25), LOW_GRIP_V if low else GRIP_V


def map_to_object(
    target: ContactTarget, object_patches: dict[str, ContactPatch], variant_size, object_size
) -> np.ndarray:
    """The point on the scene's object that corresponds to a contact on the variant [m].

    A patch contact keeps its patch and its normalised patch coordinates; a floor contact
    keeps its distance in front of the approach face and its lateral offset.
    """
    if target.patch == "floor":
        dx = 0.5 * (float(object_size[0]) - float(variant_size[0]))
        return target.point - np.array([dx, 0.0, 0.0])
    return patch_point(object_patches[target.patch], target.patch_uv)


def _body_axis_jac(
    model: mujoco.MjModel, data: mujoco.MjData, body: int, local_axis: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """World axis a = R local_axis and d a / d v (3, nv): a_dot = w x a."""
    rot = data.xmat[body].reshape(3, 3)
    a = rot @ local_axis
    jacr = np.zeros((3, model.nv))
    mujoco.mj_jacBody(model, data, None, jacr, body)
    skew = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return a, -skew @ jacr


def point_jacobian(
    model: mujoco.MjModel, data: mujoco.MjData, body: int, offset: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """World position p [m] of ``offset`` [m] in ``body``'s frame and d p / d v (3, nv)."""
    rot = data.xmat[body].reshape(3, 3)
    p = data.xpos[body] + rot @ offset
    jacp = np.zeros((3, model.nv))
    mujoco.mj_jac(model, data, jacp, None, p, body)
    return p, jacp


# Seed postures for the IK [rad]: a crouch (hips and knees flexed, back bent, arms forward)
# reaches low targets that a start from upright never finds.
CROUCH = {
    "left_hip_Z": 1.3,
    "right_hip_Z": 1.3,
    "left_knee_Z": 1.9,
    "right_knee_Z": 1.9,
    "left_ankle_Z": -0.5,
    "right_ankle_Z": -0.5,
    "middle_lumbar_Z": 0.4,
    "left_shoulder_Z": 0.8,
    "right_shoulder_Z": 0.8,
}
REACH = {"left_shoulder_Z": 0.8, "right_shoulder_Z": 0.8, "left_elbow_Z": 0.3, "right_elbow_Z": 0.3}


def initial_qpos(
    model: mujoco.MjModel,
    stance_xy: np.ndarray,
    yaw: float,
    pelvis_height: float,
    joints: dict[str, float] | None = None,
) -> np.ndarray:
    """A seed posture: ``joints`` [rad] (others zero), the pelvis at ``pelvis_height`` [m]
    above ``stance_xy`` [m], facing ``yaw`` [rad]."""
    q = np.zeros(model.nq)
    q[:2] = stance_xy
    q[2] = pelvis_height
    yaw_q = np.array([np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)])
    mujoco.mju_mulQuat(q[3:7], yaw_q, human.UPRIGHT_QUAT_WXYZ)
    for name, value in (joints or {}).items():
        q[model.jnt_qposadr[model.joint(name).id]] = value
    return q


def pose_demonstrator(
    model: mujoco.MjModel,
    targets_world: dict[str, tuple[np.ndarray, np.ndarray]],
    stance_xy: np.ndarray,
    yaw: float,
    iterations: int = 150,
    damping: float = 1e-3,
    posture_weight: float = 1e-3,
    tol: float = 1e-4,
) -> Pose:
    """Inverse kinematics of the demonstrator: the best of an upright and a crouched start.

    Each start runs :func:`_solve_ik`; the pose with the smaller contact miss wins (the
    upright one on a tie, as it looks more natural).

    Args:
        model: The demonstrator's MuJoCo model (names without prefix).
        targets_world: effector -> (target point [m], outward surface normal), world frame.
        stance_xy: Where the pelvis should stand over [m].
        yaw: Facing direction [rad].
    """
    standing = human.standing_pelvis_height()
    foot_z = max(
        (p[2] for name, (p, _) in targets_world.items() if name.endswith("_foot")), default=0.0
    )
    reach = REACH if any(name.endswith("_hand") for name in targets_world) else {}
    seeds = [
        initial_qpos(model, stance_xy, yaw, standing + foot_z, reach),
        initial_qpos(model, stance_xy, yaw, 0.6 * standing + foot_z, CROUCH),
    ]
    best: Pose | None = None
    for seed in seeds:
        pose = _solve_ik(
            model, seed, targets_world, stance_xy, yaw, iterations, damping, posture_weight, tol
        )
        if best is None or pose.residual_m < best.residual_m - 1e-3:
            best = pose
    assert best is not None
    return best


def _solve_ik(
    model: mujoco.MjModel,
    q0: np.ndarray,
    targets_world: dict[str, tuple[np.ndarray, np.ndarray]],
    stance_xy: np.ndarray,
    yaw: float,
    iterations: int,
    damping: float,
    posture_weight: float,
    tol: float,
) -> Pose:
    """Damped least squares with joint limits as bounds on every step.

    Tasks (weights): palm and sole points on their targets (1); palms facing their surfaces
    and soles flat and facing ``yaw`` (0.3); pelvis and chest upright and facing ``yaw``
    (0.1, 0.03); pelvis above the stance centre (0.2); a pull towards the seed posture
    (``posture_weight``).
    """
    data = mujoco.MjData(model)
    q = q0.copy()
    facing = np.array([np.cos(yaw), np.sin(yaw), 0.0])
    up = np.array([0.0, 0.0, 1.0])
    pelvis, thorax = model.body("middle_pelvis").id, model.body("middle_thorax").id
    hinges = [j for j in range(model.njnt) if model.jnt_limited[j]]
    dof = model.jnt_dofadr[hinges]
    adr = model.jnt_qposadr[hinges]
    lo_q, hi_q = model.jnt_range[hinges, 0], model.jnt_range[hinges, 1]
    residual, run = np.inf, 0
    for _ in range(iterations):
        run += 1
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        rows, errs, weights = [], [], []
        residual = 0.0
        for name, (target, normal) in targets_world.items():
            body_name, offset = KEYPOINTS[name]
            body = model.body(body_name).id
            p, jac = point_jacobian(model, data, body, offset)
            rows.append(jac)
            errs.append(target - p)
            weights.append(1.0)
            residual = max(residual, float(np.linalg.norm(target - p)))
            if name.endswith("_hand"):
                axes = ((LOCAL_FORWARD, -np.asarray(normal)),)
            else:
                axes = ((LOCAL_UP, up), (LOCAL_FORWARD, facing))
            for local, world in axes:
                a, jac_a = _body_axis_jac(model, data, body, local)
                rows.append(jac_a)
                errs.append(world - a)
                weights.append(0.3)
        for body, w in ((pelvis, 0.1), (thorax, 0.03)):
            for local, world in ((LOCAL_UP, up), (LOCAL_FORWARD, facing)):
                a, jac_a = _body_axis_jac(model, data, body, local)
                rows.append(jac_a)
                errs.append(world - a)
                weights.append(w)
        p, jac = point_jacobian(model, data, pelvis, ORIGIN)
        rows.append(jac[:2])
        errs.append(stance_xy - p[:2])
        weights.append(0.2)
        if residual < tol:
            break
        sqrt_w = np.concatenate([np.full(len(e), w) for e, w in zip(errs, weights, strict=True)])
        to_seed = np.zeros(model.nv)
        mujoco.mj_differentiatePos(model, to_seed, 1.0, q, q0)
        to_seed[:6] = 0.0
        reg = np.sqrt(damping + posture_weight)
        A = np.vstack([sqrt_w[:, None] * np.vstack(rows), reg * np.eye(model.nv)])
        b = np.concatenate([sqrt_w * np.concatenate(errs), posture_weight / reg * to_seed])
        lo, hi = np.full(model.nv, -np.inf), np.full(model.nv, np.inf)
        lo[dof], hi[dof] = lo_q - q[adr], hi_q - q[adr]
        dq = lsq_linear(A, b, bounds=(np.minimum(lo, 0.0), np.maximum(hi, 0.0))).x
        mujoco.mj_integratePos(model, q, dq, 1.0)
        q[adr] = np.clip(q[adr], lo_q, hi_q)
    return Pose(qpos=q, residual_m=residual, iterations=run)


def keypoints_world(model: mujoco.MjModel, qpos: np.ndarray) -> np.ndarray:
    """World positions (K, 3) [m] of :data:`KEYPOINTS` at ``qpos``."""
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_kinematics(model, data)
    out = np.empty((len(KEYPOINTS), 3))
    for k, (body_name, offset) in enumerate(KEYPOINTS.values()):
        b = model.body(body_name).id
        out[k] = data.xpos[b] + data.xmat[b].reshape(3, 3) @ offset
    return out


def check_pose(pose: Pose, tolerance_m: float, where: str) -> None:
    """Raise when the IK left an end effector further than ``tolerance_m`` from its target."""
    if pose.residual_m > tolerance_m:
        raise SceneError(
            f"{where}: the demonstrator cannot reach its contacts (largest miss "
            f"{pose.residual_m:.3f} m > {tolerance_m} m); the object may be too far, too high "
            "or too low for a person standing beside it"
        )
