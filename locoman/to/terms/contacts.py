"""The robot's contacts (paper A, Sec. IV-A) as term kinds, written with
:mod:`locoman.to.contacts`:

- a foot's patch contact (2a)-(2c) at node k + 1, at touchdown with (2d), or going on, (2b)
  then over the step (:func:`foot_patch_kind`), and how deep a landing sole may sink
  (:func:`sole_depth_kind`);
- a hand's interactive contact (4), (5a), (5b) with the object it touches, at the first touch
  or going on (:func:`hand_contact_kind`);
- the friction cone and CoP (3) of a foot on its surface (:func:`foot_cone_kind`) and of a
  wrench on a face fixed to an object (:func:`object_face_cone_kind`: a hand's, or an
  object's support).
"""

from __future__ import annotations

import functools

import casadi as ca

from locoman.to.contacts import (
    friction_cone_cop,
    interactive_contact,
    no_rolling,
    patch_contact,
    sinking_bound,
)
from locoman.to.kinematics import euler_rates_to_world, rpy_matrix
from locoman.to.terms import Rows, TermKind, term_kind

# A contact at node k + 1 starts there (``touchdown``) or held at node k already (``held``).
ONSETS = ("touchdown", "held")


@functools.cache
def foot_patch_kind(onset: str) -> TermKind:
    """(2a)-(2c) of a sole (centre r, velocity r_dot, rotation R, slack s) on a surface at
    ``surface_z`` [m]; at touchdown (2d) on its angular velocity w, held: (2b) over the step
    from the sole's centre at node k, ``r_before``.

    As paper A's (2b), the sole's centre does not slide but the sole may turn about it: the
    stance feet pivot by up to 12 deg per node on ``tiny``, S1 and S2 (reported by the
    evaluation as ``stance_foot_turn_max_rad``). Holding the turn too, as an object's
    support does (:func:`locoman.to.supports.turn_about_normal`), took ``tiny`` from 110 to
    1446 iterations: its schedule turns the robot by pivoting, and would need turning steps
    instead (docs/deviations.md)."""
    x_slots = {"r": 3, "r_dot": 3, "R": 9, "slack": 1}
    x_slots |= {"w": 3} if onset == "touchdown" else {"r_before": 3}

    def body(x, p) -> Rows:
        R = ca.reshape(x["R"], 3, 3)
        before = None if onset == "touchdown" else x["r_before"]
        rows = [patch_contact(x["r"], x["r_dot"], R, p["surface_z"], p["k_z"], x["slack"], before)]
        if onset == "touchdown":
            rows.append(no_rolling(x["w"]))
        return Rows(equalities=rows)

    return term_kind(f"foot_patch_{onset}", x_slots, {"surface_z": 1, "k_z": 1}, body)


@functools.cache
def sole_depth_kind() -> TermKind:
    """A sole's centre r no deeper than ``depth_max`` [m] below its surface at ``surface_z``
    [m] (:func:`locoman.to.contacts.sinking_bound`), beside (2a) where it lands.

    Only at touchdown, where the sole still moves: held, r_dot_z is about 0 and (2a) bounds
    the depth by the slack already, and rows on every standing node cost S1 and S2 hundreds
    of iterations (``docs/trajectory-optimisation.md``)."""

    def body(x, p) -> Rows:
        return Rows(inequalities=[sinking_bound(x["r"], p["surface_z"], p["depth_max"])])

    return term_kind("sole_depth", {"r": 3}, {"surface_z": 1, "depth_max": 1}, body)


def object_face(q_object: ca.SX, point: ca.SX, face: ca.SX) -> tuple[ca.SX, ca.SX]:
    """A point [m] and a contact frame fixed to an object (its frame's ``point``, ``face``
    (3x3, column-major)), in the world."""
    R = rpy_matrix(q_object[3:6])
    return q_object[0:3] + R @ point, R @ ca.reshape(face, 3, 3)


@functools.cache
def hand_contact_kind(onset: str) -> TermKind:
    """(4), (5a), (5b) of a palm (centre, contact frame, angular velocity: lifted) on the
    face at ``point`` of an object (q, v); the palm's centre sits ``palm_radius`` [m] off
    the face. Held, (5b) keeps only the rate about the normal: with (5a) at both nodes the
    other two follow, and imposing them makes the constraint Jacobian singular."""

    def body(x, p) -> Rows:
        r_j, R_j = object_face(x["q_o"], p["point"], p["face"])
        r_j = r_j + p["palm_radius"] * R_j[:, 2]
        w_o = euler_rates_to_world(x["q_o"][3:6]) @ x["v_o"][3:6]
        R_palm = ca.reshape(x["R"], 3, 3)
        rows = interactive_contact(x["r"], r_j, x["slack"], R_palm, R_j, x["w"], w_o)
        if onset == "held":
            rows = ca.vertcat(rows[0:5], ca.dot(R_j[:, 2], x["w"] - w_o))
        return Rows(equalities=[rows])

    x_slots = {"r": 3, "R": 9, "w": 3, "slack": 3, "q_o": 6, "v_o": 6}
    p_slots = {"point": 3, "face": 9, "palm_radius": 1}
    return term_kind(f"hand_contact_{onset}", x_slots, p_slots, body)


@functools.cache
def foot_cone_kind() -> TermKind:
    """(3) of a foot's wrench (force, moment at the sole centre) in its sole frame R."""

    def body(x, p) -> Rows:
        w, R = x["wrench"], ca.reshape(x["R"], 3, 3)
        half = p["half"]
        return Rows(inequalities=[friction_cone_cop(w[0:3], w[3:6], R, p["mu"], half[0], half[1])])

    return term_kind("foot_cone", {"wrench": 6, "R": 9}, {"mu": 1, "half": 2}, body)


@functools.cache
def object_face_cone_kind() -> TermKind:
    """(3) of a wrench on a face fixed to an object (frame ``face`` in the object's, whose
    rpy are variables): a hand's on the object it pushes, or a support's on the object's
    bottom (``face`` the identity)."""

    def body(x, p) -> Rows:
        w = x["wrench"]
        R = rpy_matrix(x["rpy"]) @ ca.reshape(p["face"], 3, 3)
        half = p["half"]
        return Rows(inequalities=[friction_cone_cop(w[0:3], w[3:6], R, p["mu"], half[0], half[1])])

    return term_kind(
        "object_face_cone", {"wrench": 6, "rpy": 3}, {"mu": 1, "half": 2, "face": 9}, body
    )
