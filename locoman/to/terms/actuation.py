"""The arm joints' static torques while a hand holds an object: a bound beyond paper A.

Paper A's TO has no joint torques: its plans carry objects with wrist torques of 1.7 to 3
times the G1's 5 N m (``benchmarks/results/execute_step.json``), which no controller can
produce (``docs/execution.md``). While a palm holds an object, the torque each arm joint
needs to hold the arm and the hand's wrench still is

    tau_j = -a_j . ( sum_b (c_b - o_j) x m_b g  +  (p - o_j) x f + m )

over the links b from joint j to the hand, with a_j and o_j joint j's axis and origin, c_b
and m_b each link's centre of mass and mass, and (f, m) the object's wrench on the hand at
its contact point p (the TO's ``hand_wrench``); all in the palm's contact frame, where they
depend only on the arm's seven joint angles and the palm's rotation R. The arm's own
accelerations are left out (the bound is static). :func:`arm_torque_kind` bounds
|tau_j| <= limit_j.
"""

from __future__ import annotations

import functools

import casadi as ca
import numpy as np
import pinocchio as pin

from locoman.retarget.robot import contact_frames
from locoman.scene import g1
from locoman.to.terms.kinematics import axis_rotation, joint_axis
from locoman.to.terms.term import Rows, TermKind, term_kind

_GRAVITY = np.array([0.0, 0.0, -9.81])  # [m/s^2]

#: Each side's arm joints, shoulder to wrist, as they sit in G1_JOINT_NAMES.
ARM_JOINTS = tuple(
    tuple(
        f"{side}_{name}_joint"
        for name in (
            "shoulder_pitch",
            "shoulder_roll",
            "shoulder_yaw",
            "elbow",
            "wrist_roll",
            "wrist_pitch",
            "wrist_yaw",
        )
    )
    for side in ("left", "right")
)


def arm_columns(side: int) -> np.ndarray:
    """(7,) where hand ``side``'s arm joints sit in the TO's configuration q (35,)."""
    return np.array([6 + g1.G1_JOINT_NAMES.index(name) for name in ARM_JOINTS[side]])


def arm_limits(side: int) -> np.ndarray:
    """(7,) the URDF's effort limits [N m] of hand ``side``'s arm joints."""
    model = g1.g1_pinocchio_model()
    return np.array(
        [model.effortLimit[model.joints[model.getJointId(n)].idx_v] for n in ARM_JOINTS[side]]
    )


def arm_torques(
    model: pin.Model, side: int, q_arm: ca.SX, R: ca.SX, wrench: ca.SX, point: np.ndarray
) -> ca.SX:
    """(7,) the static torque [N m] each arm joint (shoulder to wrist) applies, as
    Pinocchio's RNEA at rest gives it: hand ``side`` (0 left, 1 right), its joint angles
    ``q_arm`` (7,) [rad], its palm's contact frame ``R`` (3, 3, world axes), the object's
    wrench on the hand ``wrench`` (6,: force [N], moment [N m] about the contact point,
    world axes) at ``point`` (3,) in the palm's frame [m]."""
    frames = contact_frames()
    palm_name = ("left_palm", "right_palm")[side]
    hand = model.frames[model.getFrameId(g1.HAND_LINKS[side])]
    # The palm's frame in the wrist yaw joint's: the hand link's placement, then the palm.
    palm_rotation = hand.placement.rotation @ frames.palm_axes[palm_name]
    palm_origin = hand.placement.act(frames.palm[palm_name])
    # Joint frames in the palm's: start from the wrist yaw joint's, walk to the shoulder.
    rotation = ca.DM(palm_rotation.T)
    origin = ca.DM(-palm_rotation.T @ palm_origin)
    gravity = R.T @ ca.DM(_GRAVITY)
    force = R.T @ wrench[0:3]
    moment = R.T @ wrench[3:6]
    ids = [model.getJointId(name) for name in ARM_JOINTS[side]]
    masses, centres = [], []
    torques = [None] * len(ids)
    for n in range(len(ids) - 1, -1, -1):
        j = ids[n]
        inertia = model.inertias[j]
        masses.append(inertia.mass)
        centres.append(origin + rotation @ ca.DM(inertia.lever))
        local_axis = joint_axis(model, j)
        axis = rotation @ ca.DM(local_axis)
        total = ca.cross(point - origin, force) + moment
        for mass, centre in zip(masses, centres, strict=True):
            total += ca.cross(centre - origin, mass * gravity)
        torques[n] = -ca.dot(axis, total)  # what the motor holds against
        # The parent joint's frame: this one's, undone by its rotation and its placement.
        placement = model.jointPlacements[j]
        undo = axis_rotation(local_axis, -q_arm[n])
        rotation_parent = rotation @ undo @ ca.DM(placement.rotation.T)
        origin = origin - rotation_parent @ ca.DM(placement.translation)
        rotation = rotation_parent
    return ca.vertcat(*torques)


@functools.cache
def arm_torque_kind(side: int) -> TermKind:
    """|tau_j| <= limit_j for hand ``side``'s arm joints (:func:`arm_torques`) at a node
    where it holds an object: x = its wrench (world), its palm's frame R (column-major), its
    arm's seven joint angles; p = the seven limits [N m]."""
    model = g1.g1_pinocchio_model()
    point = ca.DM([0.0, 0.0, contact_frames().palm_radius])  # the face, in the palm's frame

    def body(x, p) -> Rows:
        R = ca.reshape(x["R"], 3, 3)
        tau = arm_torques(model, side, x["q_arm"], R, x["wrench"], point)
        return Rows(inequalities=[ca.vertcat(p["limit"] - tau, p["limit"] + tau)])

    name = f"arm_torque_{('left', 'right')[side]}"
    return term_kind(name, {"wrench": 6, "R": 9, "q_arm": 7}, {"limit": 7}, body)
