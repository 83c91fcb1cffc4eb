"""A MOCA-like mobile manipulator: a Franka Panda on a planar 3-DoF base (paper B, Sec. IV-B).

Kinematics: world -> ``base_x`` (slide, world x) -> ``base_y`` (slide, world y) -> ``base_yaw``
(hinge, z) -> base frame Sigma_B -> the Panda's ``panda_link0`` (Sigma_R), mounted
:data:`ARM_OFFSET_X` = 0.3875 m ahead of Sigma_B (the paper's Sigma_R-Sigma_B offset) on a
column of height ``mount_height``.

Actuation mirrors MOCA: the base takes velocity commands (``velocity`` actuators on the three
base joints), the arm is torque-controlled (``motor`` actuators, ranges from the URDF efforts)
and the gripper is a position-controlled parallel jaw (``panda_finger_joint2`` mirrors
``panda_finger_joint1`` through an equality constraint, as the URDF's ``mimic`` says).

The Panda URDF's visual meshes are COLLADA, which MuJoCo cannot read; its collision meshes
(STL) are used for both drawing and contact. The fingers keep the URDF's collision boxes.
"""

from __future__ import annotations

import dataclasses
import re
import warnings

import mujoco
import numpy as np

from locoman.errors import SceneError
from locoman.scene import assets

# The Panda's names are unique in the scene, so it is attached without a prefix; the MJCF this
# writes reloads (tests/test_scene_models.py), so MuJoCo's warning about it is noise.
warnings.filterwarnings("ignore", message="Attaching a spec with an empty prefix")

ARM_OFFSET_X = 0.3875  # [m] panda_link0 ahead of the base frame (paper B, Sec. IV-B)
BASE_JOINTS = ("base_x", "base_y", "base_yaw")
ARM_JOINTS = tuple(f"panda_joint{i}" for i in range(1, 8))
FINGER_JOINTS = ("panda_finger_joint1", "panda_finger_joint2")
EE_SITE = "ee_site"
ARM_BASE_BODY = "panda_link0"  # Sigma_R, the arm base frame
#: A comfortable arm posture [rad] (Franka's "ready" pose).
ARM_READY = (0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785)
GRIPPER_OPEN = 0.04  # [m] finger joint opening (each finger)


@dataclasses.dataclass(frozen=True)
class MobileBaseGeometry:
    """Box-shaped base and arm column [m].

    Attributes:
        length: Base box extent along the base x axis.
        width: Base box extent along the base y axis.
        height: Top of the base box above the floor.
        clearance: Gap between the floor and the bottom of the box.
        mount_height: Height of ``panda_link0`` above the floor.
        base_velocity_gain: Gain of the base velocity actuators [N s/m] / [N m s/rad].
    """

    length: float = 0.72
    width: float = 0.61
    height: float = 0.40
    clearance: float = 0.03
    mount_height: float = 0.75
    base_velocity_gain: float = 2.0e4


def mobile_manipulator_mjspec(geometry: MobileBaseGeometry | None = None) -> mujoco.MjSpec:
    """MuJoCo spec of the mobile manipulator, base frame at the world origin."""
    geo = geometry or MobileBaseGeometry()
    spec = mujoco.MjSpec()
    spec.modelname = "mobile_manipulator"
    spec.meshdir = str(assets.robots_dir())
    # One body, three joints: MuJoCo applies them in order, so both slides stay along world
    # axes and the hinge turns the base about its own origin.
    base = spec.worldbody.add_body(name="mm_base")
    base.add_joint(name="base_x", type=mujoco.mjtJoint.mjJNT_SLIDE, axis=[1, 0, 0])
    base.add_joint(name="base_y", type=mujoco.mjtJoint.mjJNT_SLIDE, axis=[0, 1, 0])
    base.add_joint(name="base_yaw", type=mujoco.mjtJoint.mjJNT_HINGE, axis=[0, 0, 1])
    box_half_h = (geo.height - geo.clearance) / 2
    base.add_geom(
        name="mm_base_box",
        type=mujoco.mjtGeom.mjGEOM_BOX,
        size=[geo.length / 2, geo.width / 2, box_half_h],
        pos=[0, 0, geo.clearance + box_half_h],
        rgba=[0.25, 0.25, 0.28, 1],
        mass=80.0,
    )
    column_h = geo.mount_height - geo.height
    base.add_geom(
        name="mm_column",
        type=mujoco.mjtGeom.mjGEOM_BOX,
        size=[0.09, 0.09, column_h / 2],
        pos=[ARM_OFFSET_X, 0, geo.height + column_h / 2],
        rgba=[0.6, 0.6, 0.62, 1],
        mass=5.0,
    )
    frame = base.add_frame(pos=[ARM_OFFSET_X, 0, geo.mount_height])
    spec.attach(_panda_spec(), frame=frame, prefix="")
    hand = spec.body("panda_hand")
    hand.add_site(name=EE_SITE, pos=[0, 0, 0.1034], size=[0.01, 0, 0])
    spec.add_equality(
        type=mujoco.mjtEq.mjEQ_JOINT,
        name1=FINGER_JOINTS[1],
        name2=FINGER_JOINTS[0],
        data=np.r_[0.0, 1.0, np.zeros(10)],
    )
    for name in BASE_JOINTS:
        act = spec.add_actuator(name=name + "_vel", target=name)
        act.trntype = mujoco.mjtTrn.mjTRN_JOINT
        act.set_to_velocity(kv=geo.base_velocity_gain)
    efforts = (87.0, 87.0, 87.0, 87.0, 12.0, 12.0, 12.0)
    for name, effort in zip(ARM_JOINTS, efforts, strict=True):
        act = spec.add_actuator(name=name + "_torque", target=name)
        act.trntype = mujoco.mjtTrn.mjTRN_JOINT
        act.set_to_motor()
        act.ctrllimited = True
        act.ctrlrange = [-effort, effort]
    grip = spec.add_actuator(name="gripper", target=FINGER_JOINTS[0])
    grip.trntype = mujoco.mjtTrn.mjTRN_JOINT
    grip.set_to_position(kp=2000.0, kv=50.0)
    grip.ctrllimited, grip.ctrlrange = True, [0.0, GRIPPER_OPEN]
    grip.forcelimited, grip.forcerange = True, [-70.0, 70.0]
    return spec


def _panda_spec() -> mujoco.MjSpec:
    urdf = assets.urdf_text(assets.PANDA_URDF, mesh_root="")
    ext = '<mujoco><compiler fusestatic="false" discardvisual="true" strippath="false"/></mujoco>'
    urdf = re.sub(r"(<robot[^>]*>)", lambda m: m.group(1) + ext, urdf, count=1)
    spec = mujoco.MjSpec.from_string(urdf)
    spec.meshdir = str(assets.robots_dir())
    for geom in spec.geoms:
        geom.group = 2
        geom.rgba = [0.92, 0.92, 0.92, 1.0]
        geom.friction = [1.5, 0.005, 0.0001]
        if "finger" in geom.parent.name:
            geom.rgba = [0.2, 0.2, 0.2, 1.0]
            geom.condim = 4
    for joint in spec.joints:
        joint.damping = [0.5 if joint.type == mujoco.mjtJoint.mjJNT_HINGE else 10.0, 0.0, 0.0]
    return spec


def start_qpos(
    model: mujoco.MjModel,
    base_pose: np.ndarray,
    ee_target: np.ndarray,
    ee_rotation: np.ndarray | None = None,
    iterations: int = 300,
    damping: float = 1e-3,
    qpos: np.ndarray | None = None,
) -> np.ndarray:
    """Initial ``qpos``: base at ``base_pose``, arm solved so the end effector is at ``ee_target``.

    Damped least-squares IK on the seven arm joints, started from :data:`ARM_READY`, with
    joint limits enforced by clipping; the gripper starts open. Position only, or the full
    pose when ``ee_rotation`` is given (the orientation error then counts 1 m per rad).

    Args:
        model: A compiled model containing this robot.
        base_pose: Base frame (x [m], y [m], yaw [rad]).
        ee_target: End-effector position (world) [m].
        ee_rotation: Optional (3, 3) end-effector orientation (world).
        iterations: IK iterations.
        damping: Levenberg-Marquardt damping [m^2].
        qpos: State to start from (other bodies keep their values); default ``qpos0``.

    Raises:
        SceneError: If the target stays more than 5 mm (or 0.01 rad) away (out of reach).
    """
    data = mujoco.MjData(model)
    if qpos is not None:
        data.qpos[:] = qpos
    qadr = np.array([model.joint(n).qposadr[0] for n in BASE_JOINTS + ARM_JOINTS])
    dadr = np.array([model.joint(n).dofadr[0] for n in ARM_JOINTS])
    data.qpos[qadr[:3]] = base_pose
    data.qpos[qadr[3:]] = ARM_READY
    for name in FINGER_JOINTS:
        data.qpos[model.joint(name).qposadr[0]] = GRIPPER_OPEN
    lo = np.array([model.joint(n).range[0] for n in ARM_JOINTS])
    hi = np.array([model.joint(n).range[1] for n in ARM_JOINTS])
    site = model.site(EE_SITE).id
    jac = np.zeros((6, model.nv))

    def error() -> np.ndarray:
        err = ee_target - data.site_xpos[site]
        if ee_rotation is None:
            return err
        return np.r_[err, rotation_error(ee_rotation, data.site_xmat[site].reshape(3, 3))]

    for _ in range(iterations):
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)  # the Jacobian needs cdof and subtree_com
        err = error()
        if np.linalg.norm(err) < 1e-7:
            break
        mujoco.mj_jacSite(model, data, jac[:3], jac[3:], site)
        j = jac[: len(err), dadr]
        step = j.T @ np.linalg.solve(j @ j.T + damping * np.eye(len(err)), err)
        data.qpos[qadr[3:]] = np.clip(data.qpos[qadr[3:]] + step, lo, hi)
    mujoco.mj_kinematics(model, data)
    miss = error()
    if np.linalg.norm(miss[:3]) > 5e-3 or np.linalg.norm(miss[3:]) > 1e-2:
        raise SceneError(
            f"start end-effector pose {ee_target.tolist()} is out of the arm's reach from base "
            f"pose {base_pose.tolist()} (position miss {np.linalg.norm(miss[:3]):.3f} m, "
            f"orientation miss {np.linalg.norm(miss[3:]):.3f} rad); move arm_start or start"
        )
    return data.qpos.copy()


def rotation_error(
    r_desired: np.ndarray,
    r_actual: np.ndarray,
    out: np.ndarray | None = None,
    work: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
) -> np.ndarray:
    """Axis-angle vector [rad] of R_d R_a^T (world frame): the rotation taking R_a to R_d;
    written into ``out`` (3,) when given. ``work``, a (3, 3) array, a (9,) view of it and a
    (4,) array, holds the intermediate R_d R_a^T and its quaternion, for callers in a
    control loop."""
    if work is None:
        rel = np.empty((3, 3))
        work = (rel, rel.reshape(9), np.empty(4))
    rel, rel_flat, q = work
    # numpy's product (np.dot: the bits of @ at 60% of its cost), not mju_mulMatMatT: the
    # replay is chaotic at the grasp, and MuJoCo's summation order moves its RMSEs by 5e-6 m.
    np.dot(r_desired, r_actual.T, rel)
    mujoco.mju_mat2Quat(q, rel_flat)
    err = np.empty(3) if out is None else out
    mujoco.mju_quat2Vel(err, q, 1.0)
    return err
