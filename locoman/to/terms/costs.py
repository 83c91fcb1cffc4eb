"""The costs of paper A as term kinds, written with :mod:`locoman.to.costs`: L_st and L_wk
of Table I by the node's contact mode, L_reg, the slacks' L_slack, the keyframe costs (9)
and (10), and ours, an object's goal and uprightness. Weights and references are inputs
``p``, so one compiled kind serves every weight, node and scenario; a switched-off cost is a
zero weight.
"""

from __future__ import annotations

import dataclasses
import functools

import casadi as ca

from locoman.to.costs import (
    CostWeights,
    keyframe_base_cost,
    keyframe_foot_cost,
    object_goal_cost,
    regularization_cost,
    stance_cost,
    walking_cost,
)
from locoman.to.dynamics import rigid_body_momentum
from locoman.to.kinematics import euler_rates_to_world
from locoman.to.layout import NQ
from locoman.to.terms import Rows, TermKind, term_kind

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
