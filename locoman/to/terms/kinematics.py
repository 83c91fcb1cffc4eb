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

The robot's kinematics, lifted: the quantities every other term reads, as functions of q, v.

The expensive part of the TO, the G1's forward kinematics and its derivatives, appears once
per node, in these terms only:

- :func:`kinematics_kind`: centroidal momentum, CoM, the soles' and palms' frames and the
  trunk's body points (:data:`locoman.to.problem.layout.KINEMATICS`);
- :func:`link_spheres_kind`: the centres of one link's collision spheres (its capsules, as
  placo and MuJoCo see them), one kind per link;
- :func:`link_point_kind`: a point fixed to a link (the palms', the feet's and the trunk's
  collision spheres), one kind per link.

Each lifts its quantities (:attr:`locoman.to.terms.term.Term.lifts`): as virtual variables of
the NLP (:class:`locoman.to.nlp.ipopt.BlockNLP`), functions of q and v whose derivatives reach
them by the chain rule.
"""

from __future__ import annotations

import dataclasses

import casadi as ca
import numpy as np
import pinocchio as pin

from locoman.retarget.robot import ContactFrames
from locoman.scene import g1
from locoman.to.collisions.spheres import link_spheres
from locoman.to.problem.layout import BODY_POINTS, FEET, HANDS, KINEMATICS, N_KIN, NQ
from locoman.to.terms.term import Rows, TermKind, term_kind

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


def joint_axis(model: pin.Model, j: int) -> np.ndarray:
    """(3,) revolute joint ``j``'s unit axis in its own frame."""
    name = model.joints[j].shortname()
    return np.asarray(_AXES[name]) if name in _AXES else np.asarray(model.joints[j].extract().axis)


def axis_rotation(axis: np.ndarray, angle: ca.SX) -> ca.SX:
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
        axis = joint_axis(model, j) if j >= 2 else np.zeros(3)
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
            R = R_parent @ ca.DM(joint.rotation) @ axis_rotation(joint.axis, q[index])
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


def kinematics_function(kin: SymbolicKinematics, frames: ContactFrames) -> ca.Function:
    """K(q, v): the lifted kinematic quantities in :data:`KINEMATICS` order. A palm's
    contact frame is ``frames.palm_axes``: (5a) lays the palm's capsule flat on the face."""
    q, v = kin.q, kin.v
    parts = {"h": kin.centroidal_momentum(), "com": kin.com()}
    palms = [frames.palm[f"{side}_palm"] for side in ("left", "right")]
    palm_axes = [frames.palm_axes[f"{side}_palm"] for side in ("left", "right")]
    for foot, link in zip(FEET, g1.FOOT_LINKS, strict=True):
        R, p = kin.frame_pose(link)
        w, v_origin = kin.frame_velocity(link)
        offset = R @ ca.DM(frames.sole["left_sole"])
        parts |= {
            f"{foot}_r": p + offset,
            f"{foot}_r_dot": v_origin + ca.cross(w, offset),
            f"{foot}_R": ca.vec(R),
            f"{foot}_w": w,
        }
    for hand, link, palm, axes in zip(HANDS, g1.HAND_LINKS, palms, palm_axes, strict=True):
        R, p = kin.frame_pose(link)
        w, _ = kin.frame_velocity(link)
        parts |= {
            f"{hand}_r": p + R @ ca.DM(palm),
            f"{hand}_R": ca.vec(R @ ca.DM(axes)),
            f"{hand}_w": w,
        }
    points = []
    for link, offset, _ in BODY_POINTS:
        R, p = kin.frame_pose(link)
        points.append(p + R @ ca.DM(offset))
    parts["body_points"] = ca.vertcat(*points)
    return ca.Function("kinematics", [q, v], [ca.vertcat(*[parts[name] for name in KINEMATICS])])


def kinematics_kind(kin: SymbolicKinematics, frames: ContactFrames) -> TermKind:
    """kin - K(q, v) = 0 at a node."""
    K = kinematics_function(kin, frames)

    def body(x, p) -> Rows:
        return Rows(equalities=[x["kin"] - K(x["q"], x["v"])])

    return term_kind("kinematics", {"q": NQ, "v": NQ, "kin": N_KIN}, {}, body, lifts=True)


def link_spheres_kind(kin: SymbolicKinematics, link: str) -> TermKind:
    """c - c(q) = 0: the world centres [m] of ``link``'s collision spheres, lifted."""
    R, p = kin.frame_pose(link)
    spheres = link_spheres(link)
    centres = ca.Function(
        f"{link}_centres", [kin.q], [ca.vertcat(*[p + R @ ca.DM(s.centre) for s in spheres])]
    )

    def body(x, _) -> Rows:
        return Rows(equalities=[x["c"] - centres(x["q"])])

    return term_kind(f"spheres_{link}", {"q": NQ, "c": 3 * len(spheres)}, {}, body, lifts=True)


def link_point_kind(kin: SymbolicKinematics, link: str) -> TermKind:
    """c - (p(q) + R(q) o) = 0: a point at ``offset`` o [m] in ``link``'s frame, defined."""
    R, p = kin.frame_pose(link)
    pose = ca.Function(f"{link}_pose", [kin.q], [p, ca.vec(R)])

    def body(x, par) -> Rows:
        p_link, R_link = pose(x["q"])
        return Rows(equalities=[x["c"] - (p_link + ca.reshape(R_link, 3, 3) @ par["offset"])])

    return term_kind(f"point_{link}", {"q": NQ, "c": 3}, {"offset": 3}, body, lifts=True)


def _between(q: ca.SX, q_next: ca.SX, fraction: ca.SX) -> ca.SX:
    """The configuration a fraction t along a step, linear in q (as the evaluation's
    replay between two nodes has it)."""
    return q + fraction * (q_next - q)


def link_spheres_between_kind(kin: SymbolicKinematics, link: str) -> TermKind:
    """:func:`link_spheres_kind` at the configuration a fraction along a step (inputs q at
    both nodes, ``p`` slot ``fraction``): where a collision pair between two nodes puts the
    link's spheres."""
    R, p = kin.frame_pose(link)
    spheres = link_spheres(link)
    centres = ca.Function(
        f"{link}_centres", [kin.q], [ca.vertcat(*[p + R @ ca.DM(s.centre) for s in spheres])]
    )

    def body(x, par) -> Rows:
        q = _between(x["q"], x["q_next"], par["fraction"])
        return Rows(equalities=[x["c"] - centres(q)])

    slots = {"q": NQ, "q_next": NQ, "c": 3 * len(spheres)}
    return term_kind(f"spheres_between_{link}", slots, {"fraction": 1}, body, lifts=True)


def link_point_between_kind(kin: SymbolicKinematics, link: str) -> TermKind:
    """:func:`link_point_kind` at the configuration a fraction along a step."""
    R, p = kin.frame_pose(link)
    pose = ca.Function(f"{link}_pose", [kin.q], [p, ca.vec(R)])

    def body(x, par) -> Rows:
        p_link, R_link = pose(_between(x["q"], x["q_next"], par["fraction"]))
        return Rows(equalities=[x["c"] - (p_link + ca.reshape(R_link, 3, 3) @ par["offset"])])

    slots = {"q": NQ, "q_next": NQ, "c": 3}
    p_slots = {"offset": 3, "fraction": 1}
    return term_kind(f"point_between_{link}", slots, p_slots, body, lifts=True)
