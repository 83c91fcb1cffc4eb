"""Symbolic kinematics of a floating-base robot for CasADi, built from its Pinocchio model.

The ``pin`` wheel has no ``pinocchio.casadi``, so the chain is walked here: each joint's
placement in its parent and its axis give the link poses; link velocities are propagated
down the chain. The configuration and velocity are those of paper A's trajectory
optimisation (35-D for the G1), with q+ = q- + v dt (eq. (1b)):

    q = (p, rpy, q_j),   v = dq/dt = (p_dot, rpy_dot, q_j_dot),

p the base position [m] in the world, rpy its roll-pitch-yaw (R = Rz(y) Ry(p) Rx(r)) [rad],
q_j the revolute joints [rad]. The base's angular velocity in the world is E(rpy) rpy_dot
(:func:`euler_rates_to_world`). ``tests/test_to_kinematics.py`` checks frame poses and the
CoM against Pinocchio to 1e-9 and the centroidal momentum h = A_G(q) v to 1e-8.
"""

from __future__ import annotations

import dataclasses

import casadi as ca
import numpy as np
import pinocchio as pin

_AXES = {"JointModelRX": (1.0, 0.0, 0.0), "JointModelRY": (0.0, 1.0, 0.0)}
_AXES["JointModelRZ"] = (0.0, 0.0, 1.0)


def rot_x(a: ca.SX) -> ca.SX:
    c, s = ca.cos(a), ca.sin(a)
    return ca.vertcat(ca.horzcat(1, 0, 0), ca.horzcat(0, c, -s), ca.horzcat(0, s, c))


def rot_y(a: ca.SX) -> ca.SX:
    c, s = ca.cos(a), ca.sin(a)
    return ca.vertcat(ca.horzcat(c, 0, s), ca.horzcat(0, 1, 0), ca.horzcat(-s, 0, c))


def rot_z(a: ca.SX) -> ca.SX:
    c, s = ca.cos(a), ca.sin(a)
    return ca.vertcat(ca.horzcat(c, -s, 0), ca.horzcat(s, c, 0), ca.horzcat(0, 0, 1))


def rpy_matrix(rpy: ca.SX) -> ca.SX:
    """R = Rz(yaw) Ry(pitch) Rx(roll)."""
    return rot_z(rpy[2]) @ rot_y(rpy[1]) @ rot_x(rpy[0])


def euler_rates_to_world(rpy: ca.SX) -> ca.SX:
    """E (3, 3) with omega_world = E(rpy) rpy_dot for R = Rz(y) Ry(p) Rx(r): the yaw rate
    turns about world z, the pitch rate about the once-yawed y, the roll rate about the
    body x."""
    p, y = rpy[1], rpy[2]
    return ca.horzcat(
        ca.vertcat(ca.cos(y) * ca.cos(p), ca.sin(y) * ca.cos(p), -ca.sin(p)),
        ca.vertcat(-ca.sin(y), ca.cos(y), 0),
        ca.vertcat(0, 0, 1),
    )


def _axis_rotation(axis: np.ndarray, angle: ca.SX) -> ca.SX:
    """Rotation by ``angle`` about a unit ``axis`` (Rodrigues)."""
    k = ca.DM(axis)
    skew = ca.skew(k)
    return ca.DM.eye(3) + ca.sin(angle) * skew + (1 - ca.cos(angle)) * (skew @ skew)


@dataclasses.dataclass(frozen=True)
class _Joint:
    parent: int
    rotation: np.ndarray  # placement in the parent joint's frame
    translation: np.ndarray
    axis: np.ndarray
    mass: float
    com: np.ndarray  # body CoM in the joint frame [m]
    inertia: np.ndarray  # about the body CoM, joint frame axes [kg m^2]


class SymbolicKinematics:
    """Frame poses, CoM and centroidal momentum of a Pinocchio model with a free-flyer root
    (joint 1) and revolute joints, as CasADi SX expressions of q and v (35-D for the G1).

    Attributes:
        nq: Configuration size (6 + revolute joints).
        q, v: The SX symbols of the configuration and its rate.
        mass: Total mass [kg].
    """

    def __init__(self, model: pin.Model) -> None:
        if model.joints[1].shortname() != "JointModelFreeFlyer":
            raise ValueError("the model's root joint must be a free flyer")
        self.model = model
        self.nq = model.nv
        self.q = ca.SX.sym("q", self.nq)
        self.v = ca.SX.sym("v", self.nq)
        self.mass = float(sum(inertia.mass for inertia in model.inertias))
        self._joints = [self._joint(j) for j in range(model.njoints)]
        self._poses, self._velocities = self._walk()

    def _joint(self, j: int) -> _Joint:
        model = self.model
        placement = model.jointPlacements[j]
        inertia = model.inertias[j]
        joint = model.joints[j]
        axis = np.zeros(3)
        if j >= 2:
            name = joint.shortname()
            axis = np.asarray(_AXES[name]) if name in _AXES else np.asarray(joint.extract().axis)
        return _Joint(
            parent=int(model.parents[j]),
            rotation=placement.rotation.copy(),
            translation=placement.translation.copy(),
            axis=axis,
            mass=float(inertia.mass),
            com=inertia.lever.copy(),
            inertia=inertia.inertia.copy(),
        )

    def _walk(self) -> tuple[list[tuple[ca.SX, ca.SX]], list[tuple[ca.SX, ca.SX]]]:
        """World pose (R, p) and velocity (omega, v of the joint origin) of every joint."""
        q, v = self.q, self.v
        base_R = rpy_matrix(q[3:6])
        poses: list[tuple[ca.SX, ca.SX]] = [(ca.SX.eye(3), ca.SX.zeros(3))] * 2
        velocities: list[tuple[ca.SX, ca.SX]] = [(ca.SX.zeros(3), ca.SX.zeros(3))] * 2
        # The free flyer's placement in the universe is the identity (Pinocchio's default).
        poses[1] = (base_R, q[0:3])
        velocities[1] = (euler_rates_to_world(q[3:6]) @ v[3:6], v[0:3])
        for j in range(2, self.model.njoints):
            joint = self._joints[j]
            R_parent, p_parent = poses[joint.parent]
            w_parent, v_parent = velocities[joint.parent]
            index = self.model.joints[j].idx_v  # the free flyer's 6 come first, as in q35
            R = R_parent @ ca.DM(joint.rotation) @ _axis_rotation(joint.axis, q[index])
            p = p_parent + R_parent @ ca.DM(joint.translation)
            w = w_parent + R @ ca.DM(joint.axis) * v[index]
            lin = v_parent + ca.cross(w_parent, p - p_parent)
            poses.append((R, p))
            velocities.append((w, lin))
        return poses, velocities

    def frame_pose(self, name: str) -> tuple[ca.SX, ca.SX]:
        """World rotation (3, 3) and position (3,) [m] of a Pinocchio frame."""
        if not self.model.existFrame(name):
            raise KeyError(f"the model has no frame {name!r}")
        frame = self.model.frames[self.model.getFrameId(name)]
        R_joint, p_joint = self._poses[frame.parentJoint]
        placement = frame.placement
        return (
            R_joint @ ca.DM(placement.rotation),
            p_joint + R_joint @ ca.DM(placement.translation),
        )

    def frame_velocity(self, name: str) -> tuple[ca.SX, ca.SX]:
        """World angular velocity [rad/s] and linear velocity [m/s] of a Pinocchio frame's
        origin."""
        if not self.model.existFrame(name):
            raise KeyError(f"the model has no frame {name!r}")
        frame = self.model.frames[self.model.getFrameId(name)]
        _, p_joint = self._poses[frame.parentJoint]
        w, v_joint = self._velocities[frame.parentJoint]
        _, p = self.frame_pose(name)
        return w, v_joint + ca.cross(w, p - p_joint)

    def com(self) -> ca.SX:
        """Centre of mass (3,) [m]."""
        total = ca.SX.zeros(3)
        for j in range(1, self.model.njoints):
            joint = self._joints[j]
            R, p = self._poses[j]
            total += joint.mass * (p + R @ ca.DM(joint.com))
        return total / self.mass

    def centroidal_momentum(self) -> ca.SX:
        """h = A_G(q) v (6,): linear momentum [kg m/s], then angular momentum about the CoM
        [kg m^2/s], in world axes."""
        com = self.com()
        linear = ca.SX.zeros(3)
        angular = ca.SX.zeros(3)
        for j in range(1, self.model.njoints):
            joint = self._joints[j]
            R, p = self._poses[j]
            w, v_origin = self._velocities[j]
            c = p + R @ ca.DM(joint.com)
            v_com = v_origin + ca.cross(w, c - p)
            linear += joint.mass * v_com
            inertia_world = R @ ca.DM(joint.inertia) @ R.T
            angular += inertia_world @ w + joint.mass * ca.cross(c - com, v_com)
        return ca.vertcat(linear, angular)


def pin_configuration(q35: np.ndarray) -> np.ndarray:
    """Pinocchio q (base xyzw quaternion) of a TO configuration (position, rpy, joints)."""
    quat = pin.Quaternion(rpy_matrix(ca.DM(q35[3:6])).full())
    return np.concatenate([q35[:3], [quat.x, quat.y, quat.z, quat.w], q35[6:]])


def pin_velocity(q35: np.ndarray, v35: np.ndarray) -> np.ndarray:
    """Pinocchio v (base linear and angular velocity in the base frame) of a TO velocity."""
    R = rpy_matrix(ca.DM(q35[3:6])).full()
    omega = euler_rates_to_world(ca.DM(q35[3:6])).full() @ v35[3:6]
    return np.concatenate([R.T @ v35[:3], R.T @ omega, v35[6:]])
