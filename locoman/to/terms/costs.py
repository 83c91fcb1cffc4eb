"""Stagewise costs of paper A, Table I, and the keyframe costs (9) and (10).

Every cost is a weighted squared norm, w ||.||^2. The weights are the paper's; each is a
field, so an ablation is a parameter change.

The costs of paper A as term kinds, written with :mod:`locoman.to.terms.costs`: L_st and L_wk
of Table I by the node's contact mode, L_reg, the slacks' L_slack, the keyframe costs (9)
and (10), and ours, an object's goal and uprightness. Weights and references are inputs
``p``, so one compiled kind serves every weight, node and scenario; a switched-off cost is a
zero weight.
"""

from __future__ import annotations

import dataclasses
import functools

import casadi as ca

from locoman.config.to import CostWeights
from locoman.scene.g1 import G1_JOINT_NAMES, STANDING_JOINTS
from locoman.to.problem.layout import NQ
from locoman.to.terms.dynamics import rigid_body_momentum
from locoman.to.terms.kinematics import euler_rates_to_world
from locoman.to.terms.term import Rows, TermKind, term_kind

LEGS = tuple(
    k for k, n in enumerate(G1_JOINT_NAMES) if any(p in n for p in ("hip", "knee", "ankle"))
)

ARMS = tuple(
    k
    for k, n in enumerate(G1_JOINT_NAMES)
    if any(p in n for p in ("waist", "shoulder", "elbow", "wrist"))
)

# The arms' nominal angles: the G1's standing posture (elbows bent, hands off the hips).
# Table I regularises q_arm without naming a reference; at zero the G1's elbow capsules
# sit in its pelvis. The paper's legs and arms leave out the G1's three waist joints; they
# count as arm joints here: unregularised, the waist twisted by up to 2.5 rad while the
# robot walked and swung the hands through the hips.
ARM_NOMINAL = [STANDING_JOINTS.get(G1_JOINT_NAMES[k], 0.0) for k in ARMS]


def _joint(name: str) -> int:
    return 6 + G1_JOINT_NAMES.index(name)


def _hip(side: str, axis: str) -> int:
    return _joint(f"{side}_hip_{axis}_joint")


def stance_cost(
    w: CostWeights,
    q: ca.SX,
    com: ca.SX,
    r_lf: ca.SX,
    r_rf: ca.SX,
    R_lf: ca.SX,
    R_rf: ca.SX,
    yaw_ref: ca.SX | float = 0.0,
) -> ca.SX:
    """L_st of Table I: both feet down. ``com`` is c_all, the CoM of the robot and what it
    carries [m]."""
    legs = ca.vertcat(
        q[_joint("left_hip_pitch_joint")] - q[_joint("right_hip_pitch_joint")],
        q[_joint("left_hip_roll_joint")],
        q[_joint("right_hip_roll_joint")],
        q[_joint("left_hip_yaw_joint")] + q[_joint("right_hip_yaw_joint")],
        q[_joint("left_knee_joint")] - q[_joint("right_knee_joint")],
    )
    return (
        w.com_over_feet * ca.sumsqr(com[0:2] - 0.5 * (r_lf[0:2] + r_rf[0:2]))
        + w.leg_symmetry * ca.sumsqr(legs)
        + w.foot_yaw_symmetry * ca.sumsqr(R_lf[:, 0] - R_rf[:, 0])
        + w.base_pose_stance * (q[4] ** 2 + (q[5] - yaw_ref) ** 2)
    )


def walking_cost(
    w: CostWeights, q: ca.SX, swing_height: ca.SX | None, yaw_ref: ca.SX | float = 0.0
) -> ca.SX:
    """L_wk of Table I: one foot in the air, ``swing_height`` [m] above its surface (the
    one it left, or, stepping up, the top it lands on; None: no swing foot)."""
    roll = ca.vertcat(q[_hip("left", "roll")], q[_hip("right", "roll")])
    cost = w.leg_roll * ca.sumsqr(roll) + w.base_pose_walking * (q[4] ** 2 + (q[5] - yaw_ref) ** 2)
    if swing_height is not None:
        cost += w.foot_clearance * (swing_height - w.clearance_m) ** 2
    return cost


def regularization_cost(
    w: CostWeights,
    q: ca.SX,
    v: ca.SX,
    wrench: ca.SX,
    base_omega: ca.SX,
    dt: ca.SX,
    ground: ca.SX | float = 0.0,
) -> ca.SX:
    """L_reg of Table I; the base height is taken over ``ground`` [m], the surface the
    feet stand on."""
    legs = [6 + k for k in LEGS]
    arms = [6 + k for k in ARMS]
    return (
        w.force * ca.sumsqr(wrench)
        + w.base_linear_velocity * ca.sumsqr(v[0:3])
        + w.base_angular_velocity * ca.sumsqr(base_omega)
        + w.leg_velocity * ca.sumsqr(v[legs])
        + w.arm_velocity * ca.sumsqr(v[arms])
        + w.arm_angle * ca.sumsqr(q[arms] - ca.DM(ARM_NOMINAL))
        + w.base_height * (q[2] - ground - w.base_height_m) ** 2
        + w.timestep * (dt - w.timestep_s) ** 2
    )


def keyframe_base_cost(w: CostWeights, q: ca.SX, q_keyframe: ca.SX) -> ca.SX:
    """(9): the base height and orientation of a keyframe."""
    height, orientation = w.keyframe_base
    return height * (q[2] - q_keyframe[2]) ** 2 + orientation * ca.sumsqr(q[3:6] - q_keyframe[3:6])


def object_goal_cost(w: CostWeights, q_object: ca.SX, goal: ca.SX) -> ca.SX:
    """The object at its target: position xy [m] and yaw [rad] (goal = (x, y, yaw))."""
    return w.object_goal * (ca.sumsqr(q_object[0:2] - goal[0:2]) + (q_object[5] - goal[2]) ** 2)


def keyframe_foot_cost(w: CostWeights, r_lf: ca.SX, r_rf: ca.SX, r_des: ca.SX) -> ca.SX:
    """(10): the feet's midpoint at the keyframe's."""
    return w.keyframe_foot * ca.sumsqr(0.5 * (r_lf[0:2] + r_rf[0:2]) - r_des[0:2])


STANCE_WEIGHTS = ("com_over_feet", "leg_symmetry", "foot_yaw_symmetry", "base_pose_stance")

WALKING_WEIGHTS = ("leg_roll", "base_pose_walking", "foot_clearance", "clearance_m")

REGULARIZATION_WEIGHTS = (
    "force",
    "base_linear_velocity",
    "base_angular_velocity",
    "leg_velocity",
    "arm_velocity",
    "arm_angle",
    "base_height",
    "base_height_m",
    "timestep",
    "timestep_s",
)


def weights_of(p, names: tuple[str, ...]) -> CostWeights:
    """A :class:`CostWeights` whose fields ``names`` are the ``p`` slots of the same names
    (the others keep numbers the cost does not read)."""
    return dataclasses.replace(CostWeights(), **{name: p[name] for name in names})


def weight_values(weights: CostWeights, names: tuple[str, ...]) -> dict[str, float]:
    """The ``p`` slots ``names`` of a kind, from ``weights``."""
    return {name: getattr(weights, name) for name in names}


@functools.cache
def stance_kind(carrying: bool) -> TermKind:
    """L_st: both feet down. c_all is the robot's CoM, or, ``carrying`` an object (its q,
    its mass and CoM in its frame), that of both."""
    x_slots = {"q": NQ, "com": 3, "r_l": 3, "r_r": 3, "R_l": 9, "R_r": 9}
    p_slots = {name: 1 for name in STANCE_WEIGHTS} | {"yaw_ref": 1}
    if carrying:
        x_slots |= {"q_o": 6}
        p_slots |= {"robot_mass": 1, "object_mass": 1, "object_com": 3}

    def body(x, p) -> Rows:
        c_all = x["com"]
        if carrying:
            m, m_o = p["robot_mass"], p["object_mass"]
            _, c_o = rigid_body_momentum(
                x["q_o"], ca.SX.zeros(6), m_o, ca.SX.eye(3), p["object_com"]
            )
            c_all = (m * x["com"] + m_o * c_o) / (m + m_o)
        R_l, R_r = ca.reshape(x["R_l"], 3, 3), ca.reshape(x["R_r"], 3, 3)
        w = weights_of(p, STANCE_WEIGHTS)
        cost = stance_cost(w, x["q"], c_all, x["r_l"], x["r_r"], R_l, R_r, p["yaw_ref"])
        return Rows(cost=cost)

    return term_kind("stance_carrying" if carrying else "stance", x_slots, p_slots, body)


@functools.cache
def walking_kind() -> TermKind:
    """L_wk: one foot in the air, its sole centre ``r_swing`` over ``surface_z`` [m]."""

    def body(x, p) -> Rows:
        height = x["r_swing"][2] - p["surface_z"]
        w = weights_of(p, WALKING_WEIGHTS)
        return Rows(cost=walking_cost(w, x["q"], height, p["yaw_ref"]))

    p_slots = {name: 1 for name in WALKING_WEIGHTS} | {"yaw_ref": 1, "surface_z": 1}
    return term_kind("walking", {"q": NQ, "r_swing": 3}, p_slots, body)


@functools.cache
def regularization_kind() -> TermKind:
    """L_reg of the robot: its contact wrenches, velocities, arm angles, base height over
    ``ground`` [m] (the surface its feet stand on) and time step."""

    def body(x, p) -> Rows:
        q, v = x["q"], x["v"]
        wrenches = ca.vertcat(x["foot_wrench"], x["hand_wrench"])
        omega = euler_rates_to_world(q[3:6]) @ v[3:6]
        w = weights_of(p, REGULARIZATION_WEIGHTS)
        return Rows(cost=regularization_cost(w, q, v, wrenches, omega, x["dt"], p["ground"]))

    x_slots = {"q": NQ, "v": NQ, "foot_wrench": 12, "hand_wrench": 12, "dt": 1}
    p_slots = {name: 1 for name in REGULARIZATION_WEIGHTS} | {"ground": 1}
    return term_kind("regularization", x_slots, p_slots, body)


@functools.cache
def squared_kind(size: int) -> TermKind:
    """weight ||x||^2: an object's support wrench in L_reg, a slack in L_slack."""

    def body(x, p) -> Rows:
        return Rows(cost=p["weight"] * ca.sumsqr(x["x"]))

    return term_kind(f"squared_{size}", {"x": size}, {"weight": 1}, body)


@functools.cache
def keyframe_base_kind() -> TermKind:
    """(9): the base height and orientation (q[2:6]) towards a keyframe's; the weights are
    zero where it is off."""

    def body(x, p) -> Rows:
        w = dataclasses.replace(CostWeights(), keyframe_base=[p["w_height"], p["w_orientation"]])
        q = ca.vertcat(0.0, 0.0, x["base"])
        q_kf = ca.vertcat(0.0, 0.0, p["reference"])
        return Rows(cost=keyframe_base_cost(w, q, q_kf))

    p_slots = {"w_height": 1, "w_orientation": 1, "reference": 4}
    return term_kind("keyframe_base", {"base": 4}, p_slots, body)


@functools.cache
def keyframe_foot_kind() -> TermKind:
    """(10): the feet's midpoint towards a keyframe's (xy); weight zero where it is off."""

    def body(x, p) -> Rows:
        w = dataclasses.replace(CostWeights(), keyframe_foot=p["weight"])
        return Rows(cost=keyframe_foot_cost(w, x["r_l"], x["r_r"], p["target"]))

    return term_kind("keyframe_foot", {"r_l": 3, "r_r": 3}, {"weight": 1, "target": 2}, body)


@functools.cache
def object_pose_kind() -> TermKind:
    """Ours: an object's position (xy) and yaw at its goal (weight zero but where a subtask
    ends), and its roll and pitch level while it moves."""

    def body(x, p) -> Rows:
        q = x["q"]
        w = dataclasses.replace(CostWeights(), object_goal=p["w_goal"])
        cost = object_goal_cost(w, q, p["goal"]) + p["w_upright"] * ca.sumsqr(q[3:5])
        return Rows(cost=cost)

    return term_kind("object_pose", {"q": 6}, {"w_goal": 1, "goal": 3, "w_upright": 1}, body)
