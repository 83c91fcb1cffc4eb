"""Unitree G1 (29 DoF, floating base) as a Pinocchio model and a MuJoCo model.

Both models are built from the same ``example-robot-data`` URDF, so link frames, masses and
inertias agree exactly (checked by ``tests/test_g1_models.py``).

Collision geometry (MuJoCo, used to measure penetration):
    * feet: one box per foot spanning the URDF's four sole contact spheres, 2 cm thick;
    * limbs, pelvis, torso, head and hands: a capsule (a sphere when the mesh is round)
      enclosing every vertex of the link's mesh, along its principal axis (:func:`fit_capsule`);
    * shoulders: the URDF's cylinders;
    * tiny links covered by their neighbours (ankle pitch, waist yaw/roll, logo) have none.
Visual geometry is the URDF meshes, in geom group 1 with collisions disabled.

Configuration conventions:
    * Pinocchio ``q`` (36): base position [m], base quaternion (x, y, z, w), 29 joints [rad].
    * MuJoCo ``qpos``: base position [m], base quaternion (w, x, y, z), joints in MuJoCo order.
    * Keyframe ``q35`` (paper A): base position [m], roll-pitch-yaw [rad], 29 joints [rad].
"""

from __future__ import annotations

import dataclasses
import functools
import re
from collections.abc import Mapping

import mujoco
import numpy as np
import pinocchio as pin

from locoman.errors import ModelError
from locoman.scene import assets, rotations

#: Joint names in Pinocchio (URDF depth-first) order, which is also the keyframe order.
G1_JOINT_NAMES: tuple[str, ...] = (
    "left_hip_pitch_joint",
    "left_hip_roll_joint",
    "left_hip_yaw_joint",
    "left_knee_joint",
    "left_ankle_pitch_joint",
    "left_ankle_roll_joint",
    "right_hip_pitch_joint",
    "right_hip_roll_joint",
    "right_hip_yaw_joint",
    "right_knee_joint",
    "right_ankle_pitch_joint",
    "right_ankle_roll_joint",
    "waist_yaw_joint",
    "waist_roll_joint",
    "waist_pitch_joint",
    "left_shoulder_pitch_joint",
    "left_shoulder_roll_joint",
    "left_shoulder_yaw_joint",
    "left_elbow_joint",
    "left_wrist_roll_joint",
    "left_wrist_pitch_joint",
    "left_wrist_yaw_joint",
    "right_shoulder_pitch_joint",
    "right_shoulder_roll_joint",
    "right_shoulder_yaw_joint",
    "right_elbow_joint",
    "right_wrist_roll_joint",
    "right_wrist_pitch_joint",
    "right_wrist_yaw_joint",
)

FOOT_LINKS = ("left_ankle_roll_link", "right_ankle_roll_link")
HAND_LINKS = ("left_rubber_hand", "right_rubber_hand")
# An arm's links, shoulder to palm, without the side's prefix (``left_``, ``right_``).
ARM_CHAIN = (
    "shoulder_pitch_link",
    "shoulder_roll_link",
    "shoulder_yaw_link",
    "elbow_link",
    "wrist_roll_link",
    "wrist_pitch_link",
    "wrist_yaw_link",
    "rubber_hand",
)
BASE_LINK = "pelvis"

#: A relaxed standing posture [rad]: knees slightly bent, arms along the body.
STANDING_JOINTS: Mapping[str, float] = {
    "left_hip_pitch_joint": -0.2,
    "left_knee_joint": 0.42,
    "left_ankle_pitch_joint": -0.22,
    "right_hip_pitch_joint": -0.2,
    "right_knee_joint": 0.42,
    "right_ankle_pitch_joint": -0.22,
    "left_shoulder_pitch_joint": 0.2,
    "left_shoulder_roll_joint": 0.25,
    "left_elbow_joint": 0.9,
    "right_shoulder_pitch_joint": 0.2,
    "right_shoulder_roll_joint": -0.25,
    "right_elbow_joint": 0.9,
}

FOOT_BOX_THICKNESS = 0.02  # [m]
_NO_COLLISION_LINKS = frozenset(
    {
        "left_ankle_pitch_link",
        "right_ankle_pitch_link",
        "waist_yaw_link",
        "waist_roll_link",
        "logo_link",
        "pelvis_contour_link",
    }
)
#: Collision-geom group, so renderers and penetration queries can tell them from visuals.
COLLISION_GROUP = 3
VISUAL_GROUP = 1


@functools.cache
def g1_pinocchio_model() -> pin.Model:
    """Pinocchio model of the G1 with a free-flyer root joint (nq = 36, nv = 35)."""
    model = pin.buildModelFromXML(assets.urdf_text(assets.G1_URDF), pin.JointModelFreeFlyer())
    names = tuple(model.names[2:])
    if names != G1_JOINT_NAMES:
        raise ModelError(f"G1 URDF joint order changed: {names}; update G1_JOINT_NAMES")
    return model


def g1_mjspec() -> mujoco.MjSpec:
    """MuJoCo spec of the G1: free joint on the pelvis, fitted collision primitives.

    Mesh file names are relative to :func:`locoman.scene.assets.robots_dir`, which is set as
    the spec's ``meshdir``; a caller that saves the MJCF elsewhere rewrites ``meshdir``.
    """
    spec = _urdf_spec()
    pelvis = spec.body(BASE_LINK)
    pelvis.add_freejoint(name="floating_base_joint")
    for body in spec.bodies:
        if body.name == "world":
            continue
        _make_collision_geoms(spec, body)
    _exclude_neighbour_collisions(spec)
    return spec


def _urdf_spec() -> mujoco.MjSpec:
    """The URDF as MuJoCo reads it: every link kept, visual meshes kept."""
    urdf = assets.urdf_text(assets.G1_URDF, mesh_root="")
    mj_ext = (
        '<mujoco><compiler fusestatic="false" discardvisual="false" strippath="false" '
        'balanceinertia="false"/></mujoco>'
    )
    urdf = re.sub(r"(<robot[^>]*>)", lambda m: m.group(1) + mj_ext, urdf, count=1)
    spec = mujoco.MjSpec.from_string(urdf)
    spec.meshdir = str(assets.robots_dir())
    spec.modelname = "g1"
    return spec


def _make_collision_geoms(spec: mujoco.MjSpec, body: mujoco.MjsBody) -> None:
    geoms = list(body.geoms)
    visual = [g for g in geoms if g.contype == 0 and g.conaffinity == 0]
    collision = [g for g in geoms if not (g.contype == 0 and g.conaffinity == 0)]
    for g in visual:
        g.group = VISUAL_GROUP
        g.rgba = [0.72, 0.74, 0.78, 1.0]
    if body.name in FOOT_LINKS:
        spheres = [g for g in collision if g.type == mujoco.mjtGeom.mjGEOM_SPHERE]
        centres = np.array([g.pos for g in spheres])
        radius = spheres[0].size[0]
        lo, hi = centres.min(axis=0) - radius, centres.max(axis=0) + radius
        sole = centres[:, 2].min() - radius
        for g in spheres:
            spec.delete(g)
        foot = body.add_geom()
        foot.name = body.name.replace("_ankle_roll_link", "_foot")
        foot.type = mujoco.mjtGeom.mjGEOM_BOX
        foot.size = [(hi[0] - lo[0]) / 2, (hi[1] - lo[1]) / 2, FOOT_BOX_THICKNESS / 2]
        foot.pos = [(hi[0] + lo[0]) / 2, (hi[1] + lo[1]) / 2, sole + FOOT_BOX_THICKNESS / 2]
        _as_collision(foot)
        return
    cylinders = [g for g in collision if g.type == mujoco.mjtGeom.mjGEOM_CYLINDER]
    for g in collision:
        if g not in cylinders or body.name in _NO_COLLISION_LINKS:
            spec.delete(g)
    if body.name in _NO_COLLISION_LINKS or not visual:
        return
    if cylinders:
        for geom in cylinders:
            _as_collision(geom)
        return
    fit = capsule_fits()[body.name]
    fitted = body.add_geom()
    if fit.half_length > 0.0:
        fitted.type = mujoco.mjtGeom.mjGEOM_CAPSULE
        fitted.size = [fit.radius, fit.half_length, 0.0]
    else:
        fitted.type = mujoco.mjtGeom.mjGEOM_SPHERE
        fitted.size = [fit.radius, 0.0, 0.0]
    fitted.pos, fitted.quat = fit.pos, fit.quat_wxyz
    _as_collision(fitted)


@dataclasses.dataclass(frozen=True)
class CapsuleFit:
    """A capsule enclosing a link mesh, in the link frame.

    Attributes:
        pos: Capsule centre [m].
        quat_wxyz: Orientation; the capsule axis is the local z axis.
        radius: [m].
        half_length: Half length of the cylindrical part [m]; 0 means a sphere.
    """

    pos: np.ndarray
    quat_wxyz: np.ndarray
    radius: float
    half_length: float


def fit_capsule(vertices: np.ndarray) -> CapsuleFit:
    """Capsule enclosing ``vertices`` (n, 3) [m].

    The axis is the principal direction of the vertex cloud; the radius is the largest
    distance of a vertex from the axis, and the cylinder is just long enough for the end caps
    to contain every vertex.
    """
    centre = 0.5 * (vertices.min(axis=0) + vertices.max(axis=0))
    local = vertices - centre
    _, _, vt = np.linalg.svd(local - local.mean(axis=0), full_matrices=False)
    axis = vt[0]
    t = local @ axis
    offset = 0.5 * (t.max() + t.min())
    t = t - offset
    centre = centre + offset * axis
    radial = np.linalg.norm(local - np.outer(local @ axis, axis), axis=1)
    radius = float(radial.max())
    # Each vertex is inside the end cap once the cylinder reaches |t| - sqrt(R^2 - r^2).
    cap_reach = np.abs(t) - np.sqrt(np.maximum(radius**2 - radial**2, 0.0))
    half_length = float(max(0.0, cap_reach.max()))
    quat = np.zeros(4)
    mujoco.mju_quatZ2Vec(quat, axis)
    return CapsuleFit(centre, quat, radius, half_length)


@functools.cache
def capsule_fits() -> dict[str, CapsuleFit]:
    """Enclosing capsule of each link's visual mesh, in the link frame."""
    spec = _urdf_spec()
    model = spec.compile()
    fits = {}
    for gid in range(model.ngeom):
        if model.geom_type[gid] != mujoco.mjtGeom.mjGEOM_MESH or model.geom_contype[gid]:
            continue
        body = model.body(model.geom_bodyid[gid]).name
        if body in fits:
            continue
        mesh = model.geom_dataid[gid]
        start, count = model.mesh_vertadr[mesh], model.mesh_vertnum[mesh]
        verts = model.mesh_vert[start : start + count]
        rot = np.zeros(9)
        mujoco.mju_quat2Mat(rot, model.geom_quat[gid])
        in_body = verts @ rot.reshape(3, 3).T + model.geom_pos[gid]
        fits[body] = fit_capsule(in_body)
    return fits


def _exclude_neighbour_collisions(spec: mujoco.MjSpec) -> None:
    """Exclude contacts between a link and its two nearest ancestors that have collision geoms.

    Their capsules overlap by construction around the joint between them (e.g. pelvis and hip
    roll, wrist roll and wrist yaw); any other pair counts as a self-collision.
    """

    def has_collision(body: mujoco.MjsBody) -> bool:
        return any(g.contype or g.conaffinity for g in body.geoms)

    for body in spec.bodies:
        if body.name == "world" or not has_collision(body):
            continue
        ancestors: list[str] = []
        parent = body.parent
        while parent.name != "world" and len(ancestors) < 2:
            if has_collision(parent):
                ancestors.append(parent.name)
            parent = parent.parent
        for name in ancestors:
            spec.add_exclude(bodyname1=name, bodyname2=body.name)


def _as_collision(geom: mujoco.MjsGeom) -> None:
    geom.contype, geom.conaffinity = 1, 1
    geom.group = COLLISION_GROUP
    geom.rgba = [0.9, 0.4, 0.2, 0.4]
    geom.friction = [1.0, 0.005, 0.0001]


def standing_q35(joints: Mapping[str, float] | None = None) -> np.ndarray:
    """Keyframe-layout configuration of the standing posture, base at the origin.

    The base height is chosen so that both foot soles rest at z = 0.

    Args:
        joints: Joint angles [rad] to use instead of :data:`STANDING_JOINTS`.
    """
    angles = STANDING_JOINTS if joints is None else joints
    q35 = np.zeros(6 + len(G1_JOINT_NAMES))
    for name, value in angles.items():
        q35[6 + G1_JOINT_NAMES.index(name)] = value
    q35[2] = -min(sole_heights(q35))
    return q35


@functools.cache
def g1_mjmodel() -> mujoco.MjModel:
    """Compiled stand-alone MuJoCo model of the G1 (do not modify: it is shared)."""
    return g1_mjspec().compile()


@functools.cache
def foot_sole_corners() -> dict[str, np.ndarray]:
    """The four bottom corners (4, 3) of each foot box in its ankle-roll link frame [m]."""
    model = g1_mjmodel()
    corners = {}
    for link in FOOT_LINKS:
        geom = model.geom(link.replace("_ankle_roll_link", "_foot"))
        half = geom.size
        local = [[sx * half[0], sy * half[1], -half[2]] for sx in (-1, 1) for sy in (-1, 1)]
        corners[link] = np.array(local) + geom.pos
    return corners


def sole_heights(q35: np.ndarray) -> list[float]:
    """Height [m] of the lowest sole corner of each foot at keyframe configuration ``q35``."""
    model = g1_pinocchio_model()
    data = model.createData()
    pin.framesForwardKinematics(model, data, q35_to_pin(q35))
    heights = []
    for link, corners in foot_sole_corners().items():
        oMf = data.oMf[model.getFrameId(link)]
        heights.append(float((corners @ oMf.rotation.T + oMf.translation)[:, 2].min()))
    return heights


def q35_to_pin(q35: np.ndarray) -> np.ndarray:
    """Keyframe configuration (position, roll-pitch-yaw, joints) -> Pinocchio ``q`` (xyzw)."""
    q35 = np.asarray(q35, dtype=float)
    quat_xyzw = rotations.rpy_to_quat_xyzw(q35[3:6])
    return np.concatenate([q35[:3], quat_xyzw, q35[6:]])


def pin_to_q35(q: np.ndarray) -> np.ndarray:
    """Pinocchio ``q`` (xyzw quaternion) -> keyframe configuration (roll-pitch-yaw)."""
    q = np.asarray(q, dtype=float)
    return np.concatenate([q[:3], rotations.quat_xyzw_to_rpy(q[3:7]), q[7:]])


def link_poses(q: np.ndarray) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """World pose of every link (body frame) at Pinocchio configuration ``q``: position
    (3,) [m] and quaternion (4,) (w, x, y, z)."""
    model = g1_pinocchio_model()
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    out = {}
    for f, frame in enumerate(model.frames):
        if frame.type != pin.FrameType.BODY:
            continue
        pose = data.oMf[f]
        quat = pin.Quaternion(pose.rotation)
        out[frame.name] = (pose.translation.copy(), np.array([quat.w, quat.x, quat.y, quat.z]))
    return out


def mujoco_joint_qpos_indices(model: mujoco.MjModel) -> np.ndarray:
    """``qpos`` address of each joint of :data:`G1_JOINT_NAMES` in a compiled MuJoCo model."""
    try:
        return np.array([model.joint(name).qposadr[0] for name in G1_JOINT_NAMES], dtype=int)
    except KeyError as exc:
        raise ModelError(f"MuJoCo model has no G1 joint {exc}; was it built by g1_mjspec?") from exc


def pin_to_mujoco_qpos(q: np.ndarray, model: mujoco.MjModel, qpos: np.ndarray) -> np.ndarray:
    """Write Pinocchio configuration ``q`` into a copy of MuJoCo ``qpos`` (quaternion wxyz)."""
    out = np.array(qpos, dtype=float)
    adr = model.joint("floating_base_joint").qposadr[0]
    out[adr : adr + 3] = q[:3]
    out[adr + 3 : adr + 7] = rotations.xyzw_to_wxyz(q[3:7])
    out[mujoco_joint_qpos_indices(model)] = q[7:]
    return out


def capsule_spheres(model: mujoco.MjModel, geom: int) -> list[tuple[np.ndarray, float]]:
    """A collision capsule (or sphere) of ``model`` as spheres along its axis, at most a
    radius apart: (centre in the body frame [m], radius [m]) each.

    Between two spheres the chain is at most 13 % of a radius thinner than the capsule.
    """
    size = model.geom_size[geom]
    rot = np.zeros(9)
    mujoco.mju_quat2Mat(rot, model.geom_quat[geom])
    axis = rot.reshape(3, 3)[:, 2]
    half = size[1] if model.geom_type[geom] == mujoco.mjtGeom.mjGEOM_CAPSULE else 0.0
    count = int(np.ceil(2.0 * half / size[0])) + 1
    pos = model.geom_pos[geom]
    return [(pos + t * half * axis, float(size[0])) for t in np.linspace(-1.0, 1.0, count)]
