"""Centroidal dynamics, discretised by semi-implicit Euler (paper A, eq. (1)).

    h+ = h- + [m g + sum_i f_i ; sum_i (r_i - c) x f_i + tau_i] dt          (1a)
    q+ = q- + v+ dt                                                           (1b)

h = (linear momentum [kg m/s], angular momentum about the CoM [kg m^2/s]) in world axes,
f_i, tau_i the force [N] and moment [N m] at contact point r_i [m], c the CoM [m]. Objects
obey the same equations as rigid bodies (:func:`rigid_body_momentum`). Every function takes
and returns CasADi expressions, so the same code builds the NLP and evaluates a solution.

The dynamics (1) of every body, semi-implicit Euler over a step k -> k + 1:

    h+ - h- - [m g + sum_i f_i ; sum_i (r_i - c) x f_i + tau_i] dt = 0      (1a)
    q+ - q- - v+ dt = 0                                                     (1b)

A body's step (:func:`robot_step_kind`, :func:`object_step_kind`) owns its rows with gravity
in them; every contact that acts on the body at node k adds its wrench's share to the first
six (:func:`wrench_kind`), the robot's and the object's with opposite signs, so Newton's
third law (6) holds by construction. Where the wrench acts and about which CoM is read from
the variables the kinds name: a lifted point (a sole centre, the robot's CoM), or a point
fixed in an object's frame (a hand's contact on it, its CoM, its origin).
"""

from __future__ import annotations

import functools

import casadi as ca

from locoman.to.problem.layout import NQ
from locoman.to.terms.kinematics import euler_rates_to_world, rpy_matrix
from locoman.to.terms.term import Rows, TermKind, term_kind

STANDARD_GRAVITY = 9.81  # g [m/s^2]
GRAVITY = (0.0, 0.0, -STANDARD_GRAVITY)  # the gravity vector, world z up [m/s^2]


def rigid_body_momentum(
    q: ca.SX, v: ca.SX, mass: float, inertia: ca.DM, com_local: ca.DM
) -> tuple[ca.SX, ca.SX]:
    """Centroidal momentum (6,) and CoM (3,) [m] of a rigid body with configuration
    q = (p, rpy) and rate v = (p_dot, rpy_dot); ``inertia`` (3, 3) [kg m^2] about the CoM
    in body axes, ``com_local`` (3,) [m] the CoM in the body frame."""
    R = rpy_matrix(q[3:6])
    omega = euler_rates_to_world(q[3:6]) @ v[3:6]
    com = q[0:3] + R @ com_local
    v_com = v[0:3] + ca.cross(omega, R @ com_local)
    return ca.vertcat(mass * v_com, R @ inertia @ R.T @ omega), com


@functools.cache
def robot_step_kind() -> TermKind:
    """(1a) with gravity only, and (1b), of the robot's centroid (h lifted)."""

    def body(x, p) -> Rows:
        gravity = ca.vertcat(p["mass"] * ca.DM(GRAVITY), ca.DM.zeros(3))
        momentum = x["h1"] - x["h"] - gravity * x["dt"]
        return Rows(equalities=[momentum, x["q1"] - x["q"] - x["v1"] * x["dt"]])

    slots = {"h": 6, "h1": 6, "q": NQ, "q1": NQ, "v1": NQ, "dt": 1}
    return term_kind("robot_step", slots, {"mass": 1}, body)


@functools.cache
def object_step_kind() -> TermKind:
    """(1a) with gravity only, and (1b), of a rigid object (q = (p, rpy), v = dq/dt)."""

    def body(x, p) -> Rows:
        inertia = ca.reshape(p["inertia"], 3, 3)
        h, _ = rigid_body_momentum(x["q"], x["v"], p["mass"], inertia, p["com"])
        h1, _ = rigid_body_momentum(x["q1"], x["v1"], p["mass"], inertia, p["com"])
        gravity = ca.vertcat(p["mass"] * ca.DM(GRAVITY), ca.DM.zeros(3))
        momentum = h1 - h - gravity * x["dt"]
        return Rows(equalities=[momentum, x["q1"] - x["q"] - x["v1"] * x["dt"]])

    slots = {"q": 6, "v": 6, "q1": 6, "v1": 6, "dt": 1}
    return term_kind("object_step", slots, {"mass": 1, "inertia": 9, "com": 3}, body)


# Where a wrench acts and about which CoM a body turns: a lifted point (3 variables), or a
# point fixed in an object's frame (the object's q = (p, rpy) and the point's place in it).
POINT_SOURCES = ("point", "object")


def _source(x, p, name: str, source: str) -> ca.SX:
    if source == "point":
        return x[name]
    q = x[f"{name}_q"]
    return q[0:3] + rpy_matrix(q[3:6]) @ p[f"{name}_local"]


def _slots(name: str, source: str) -> tuple[dict[str, int], dict[str, int]]:
    return ({name: 3}, {}) if source == "point" else ({f"{name}_q": 6}, {f"{name}_local": 3})


def _wrench_share(x, p, r: ca.SX, c: ca.SX) -> Rows:
    f, tau = x["wrench"][0:3], x["wrench"][3:6]
    share = ca.vertcat(f, ca.cross(r - c, f) + tau)
    return Rows(equalities=[-p["sign"] * share * x["dt"]])


@functools.cache
def wrench_kind(at: str, about: str) -> TermKind:
    """A contact's share of a body's (1a): -sign [f; (r - c) x f + tau] dt, the wrench
    (f, tau) acting at r on the body whose CoM is c; ``at`` and ``about`` are each a
    :data:`POINT_SOURCES`."""
    x_slots, p_slots = {"wrench": 6, "dt": 1}, {"sign": 1}
    for name, source in (("r", at), ("c", about)):
        xs, ps = _slots(name, source)
        x_slots |= xs
        p_slots |= ps

    def body(x, p) -> Rows:
        return _wrench_share(x, p, _source(x, p, "r", at), _source(x, p, "c", about))

    return term_kind(f"wrench_{at}_about_{about}", x_slots, p_slots, body)


@functools.cache
def same_object_wrench_kind() -> TermKind:
    """:func:`wrench_kind` of a wrench at a point of an object about the same object's CoM
    (a hand's on the object it touches; its support's at its origin)."""

    def body(x, p) -> Rows:
        q = x["q"]
        R = rpy_matrix(q[3:6])
        return _wrench_share(x, p, q[0:3] + R @ p["r_local"], q[0:3] + R @ p["c_local"])

    x_slots = {"wrench": 6, "dt": 1, "q": 6}
    p_slots = {"sign": 1, "r_local": 3, "c_local": 3}
    return term_kind("wrench_same_object", x_slots, p_slots, body)
