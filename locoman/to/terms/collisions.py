"""Collision avoidance of paper A, Sec. IV-D: the scaled penetration (11) and its penalty (12).

The paper scales a point's distance d from the centroid of the penetrated body, an
ellipsoid, and asks p = d^2 - 1 >= 0 (11). The G1's links are chains of spheres (their
MuJoCo collision capsules, as placo uses them), and two spheres are kept apart by (11) in the
box pairs' units below, p = (|c_a - c_b| - r_a - r_b - margin) / L: d^2 - 1's gradient
vanishes when the centres meet, so a deep pair was hardly pushed out.

Boxes (a table, the carried box) are poorly covered by ellipsoids: enclosing the table puts
its own load inside, inscribing it misses the corners, and a superquadric norm errs by a
fraction of each half size, centimetres on a table's height. For a box we scale a smooth
clearance instead, c(x) ~ max_i (|x_i| - a_i), the box's signed distance on its faces
(log-sum-exp with a few millimetres of smoothing): a sphere of radius r is outside when
c >= r + margin, and p = (c - r - margin) / L takes the place of (11)'s d^2 - 1, with one
length L for every pair, so that a centimetre costs the same everywhere.

Which pairs are checked, and how, is configuration (:class:`CollisionCfg`): the paper adds
a minimal set per scenario, since every pair makes the problem less convex, and treats each
kind either with the penalty (12) or as the hard constraint (11), p >= 0 (S2's knees).

The collision terms of paper A, Sec. IV-D, as term kinds: one per pair geometry and
treatment, each evaluated over a list of pairs that is data (:mod:`locoman.to.terms.collisions`
holds the geometry).

Geometries (what is kept out of what):

- ``sphere_sphere``: two robot spheres (lifted centres), p = (|a - b| - r_a - r_b - margin) / L;
- ``sphere_object_box``: a robot sphere and a box fixed in a moving object's frame;
- ``sphere_fixed_box``: a robot sphere and a fixed box (an obstacle);
- ``object_point_fixed_box``: a point fixed in a moving object (a carried box's corner) and
  a fixed box;
- ``fixed_point_object_box``: a fixed point (on an obstacle's edge) and a box fixed in a
  moving object;
- ``object_point_object_box``: a point fixed in one moving object (a carried box's corner)
  and a box fixed in another (a trolley's chassis).

Treatments (:data:`locoman.config.to.TREATMENTS`): ``penalty`` (12), a residual
sqrt(w) min(p, 0) smoothed; ``constraint`` (11), p >= 0; ``homotopy`` (13a),
alpha p~ + (1 - alpha) p >= 0 from the box's smooth stand-in p~, with (13b)'s
sqrt(w_hom) alpha once per node (:func:`homotopy_weight_kind`).
"""

from __future__ import annotations

import functools
from types import SimpleNamespace

import casadi as ca
import numpy as np

from locoman.to.terms.kinematics import rot_z, rpy_matrix
from locoman.to.terms.term import Rows, TermKind, term_kind


def column(x) -> ca.SX | ca.DM:
    """A CasADi column of numbers (DM) or of an expression (unchanged)."""
    return x if isinstance(x, ca.SX | ca.MX) else ca.DM(np.asarray(x, dtype=float).ravel())


def box_clearance(
    point: ca.SX, centre: ca.SX, R: ca.SX, half_extents: ca.SX, smoothing: ca.SX
) -> ca.SX:
    """Smooth signed clearance [m] of ``point`` from a box (centre, axes R, half extents):
    tau ln sum_i exp((|x_i| - a_i) / tau), x = R^T (point - centre), |.| smoothed over 1 mm.
    Negative inside; on the faces the signed distance, up to tau ln 3."""
    local = R.T @ (point - centre)
    excess = ca.sqrt(local**2 + 1e-6) - column(half_extents)
    return smoothing * ca.logsumexp(excess / smoothing)


def sphere_box_penetration(
    centre_sphere: ca.SX,
    radius: float,
    box_centre: ca.SX,
    R: ca.SX,
    half: ca.SX,
    cfg,
    margin: ca.SX | float | None = None,
) -> ca.SX:
    """(11) for a sphere (radius 0: a point) and a box: p = (c - r - margin) / L, c the
    clearance of its centre; ``margin`` [m] in place of ``cfg.margin_m``."""
    clearance = box_clearance(centre_sphere, box_centre, R, half, cfg.smoothing_m)
    margin = cfg.margin_m if margin is None else margin
    return (clearance - radius - margin) / cfg.length_m


def sphere_ellipsoid_penetration(
    centre_sphere: ca.SX, radius: float, box_centre: ca.SX, R: ca.SX, half: ca.SX, cfg
) -> ca.SX:
    """(11) for a sphere against the smooth stand-in of a box, the ellipsoid inscribed in
    it (semi-axes a_i, grown by r + margin): p~ = d^2 - 1, d the sphere centre's scaled
    distance from the box's centre. It touches the box's faces at their centres and cuts
    its corners: a guide, which the box replaces as alpha goes to zero. (The ellipsoid
    through the corners, sqrt(3) a_i, held S2's hips away from the box they carry, and
    the solve diverged from there.)"""
    x = R.T @ (centre_sphere - box_centre)
    return ca.sumsqr(x / (half + radius + cfg.margin_m)) - 1.0


def sphere_sphere_penetration(
    a: ca.SX, b: ca.SX, radius: ca.SX | float, length: ca.SX | float
) -> ca.SX:
    """(11) of two spheres whose radii (and margin) sum to ``radius`` [m], in the box pairs'
    units: p = (|a - b| - radius) / L, L = ``length`` [m] (|.| smoothed over 1 mm).

    The paper's d^2 - 1, d = |a - b| / radius, saturates at -1 as the centres meet, and its
    gradient 2 d grad d vanishes there, so (12) hardly pushed a deep pair out (a wrist
    left deep in the torso, a solve ten times longer); this p's gradient keeps its size at
    any depth (docs/performance.md)."""
    return (ca.sqrt(ca.sumsqr(a - b) + 1e-6) - radius) / length


def penetration_residual(p: ca.SX, softness: float) -> ca.SX:
    """The residual r of (12), whose square is the penalty: min(p, 0) smoothed over
    ``softness`` (-softness ln(1 + exp(-p / softness)), written so that it cannot overflow).

    The paper's p^2 for p < 0 is only once differentiable; with it IPOPT reached the
    optimum of ``tiny`` at 69 nodes by iteration 160 and then cycled between a penalty's
    active and inactive sides for 770 more. Smoothed, r and its Gauss-Newton curvature turn
    on before contact; for |p| >> softness r is min(p, 0), and at p = 0 it is -softness ln 2.
    """
    return ca.fmin(p, 0.0) - softness * ca.log1p(ca.exp(-ca.fabs(p) / softness))


# The numbers of a box clearance (:func:`sphere_box_penetration`): margin [m] (a touching
# pair's is the least), log-sum-exp smoothing [m], length L [m].
BOX_NUMBERS = {"margin": 1, "smoothing": 1, "length": 1}

PENALTY_NUMBERS = {"weight": 1, "softness": 1}

# geometry -> (x slots, p slots); ``c``: a robot sphere's lifted centre.
GEOMETRIES: dict[str, tuple[dict[str, int], dict[str, int]]] = {
    "sphere_sphere": ({"a": 3, "b": 3}, {"radius": 1, "length": 1}),
    "sphere_object_box": ({"c": 3, "q_o": 6}, {"radius": 1, "centre": 3, "half": 3}),
    "sphere_fixed_box": ({"c": 3}, {"radius": 1, "centre": 3, "yaw": 1, "half": 3}),
    "object_point_fixed_box": ({"q_o": 6}, {"point": 3, "centre": 3, "yaw": 1, "half": 3}),
    "fixed_point_object_box": ({"q_o": 6}, {"point": 3, "centre": 3, "half": 3}),
    "object_point_object_box": ({"q_a": 6, "q_o": 6}, {"point": 3, "centre": 3, "half": 3}),
}


def _object_frame(q: ca.SX) -> tuple[ca.SX, ca.SX]:
    return q[0:3], rpy_matrix(q[3:6])


def _sphere_and_box(geometry: str, x, p) -> tuple[ca.SX, ca.SX, ca.SX, ca.SX, ca.SX]:
    """Sphere centre [m], radius [m], box centre [m], rotation, half sizes [m]."""
    if geometry == "sphere_object_box":
        origin, R = _object_frame(x["q_o"])
        return x["c"], p["radius"], origin + R @ p["centre"], R, p["half"]
    if geometry == "sphere_fixed_box":
        return x["c"], p["radius"], p["centre"], rot_z(p["yaw"]), p["half"]
    if geometry == "object_point_fixed_box":
        origin, R = _object_frame(x["q_o"])
        return origin + R @ p["point"], 0.0, p["centre"], rot_z(p["yaw"]), p["half"]
    origin, R = _object_frame(x["q_o"])
    if geometry == "object_point_object_box":
        origin_a, R_a = _object_frame(x["q_a"])
        point = origin_a + R_a @ p["point"]
    else:
        point = p["point"]
    return point, 0.0, origin + R @ p["centre"], R, p["half"]


def _penetration(geometry: str, x, p) -> ca.SX:
    """p of (11)."""
    if geometry == "sphere_sphere":
        return sphere_sphere_penetration(x["a"], x["b"], p["radius"], p["length"])
    centre, radius, box, R, half = _sphere_and_box(geometry, x, p)
    cfg = SimpleNamespace(margin_m=p["margin"], smoothing_m=p["smoothing"], length_m=p["length"])
    return sphere_box_penetration(centre, radius, box, R, half, cfg)


def _stand_in(geometry: str, x, p) -> ca.SX:
    """p~ of (13a): the box's smooth stand-in, grown by the collision margin (not a
    touching pair's least one)."""
    centre, radius, box, R, half = _sphere_and_box(geometry, x, p)
    cfg = SimpleNamespace(margin_m=p["stand_in_margin"])
    return sphere_ellipsoid_penetration(centre, radius, box, R, half, cfg)


# The inputs that are a robot sphere's centre: between two nodes the transcription hands
# them at the configuration there (virtual variables of their own); the objects' poses and
# alpha are linear along the step.
ROBOT_SLOTS = ("a", "b", "c")


class _Between:
    """The inputs a fraction t along a step: a robot sphere's centre as given, every other
    slot (1 - t) x_k + t x_{k+1} (an object's (p, rpy), alpha), as the evaluation's replay
    between two nodes has them."""

    def __init__(self, x, fraction: ca.SX) -> None:
        self._x, self._t = x, fraction

    def __getitem__(self, slot: str) -> ca.SX:
        if slot in ROBOT_SLOTS:
            return self._x[slot]
        return (1.0 - self._t) * self._x[slot] + self._t * self._x[f"{slot}_next"]


@functools.cache
def collision_kind(geometry: str, treatment: str, between: bool = False) -> TermKind:
    """The term of one pair ``geometry`` under ``treatment``; ``between``: at a fraction
    (``p`` slot ``fraction``) along a step, every input taken at both its nodes (a hand
    can pass through a thin post between two nodes where neither node shows it)."""
    x_slots, p_slots = (dict(s) for s in GEOMETRIES[geometry])
    if geometry != "sphere_sphere":
        p_slots |= BOX_NUMBERS
    if treatment == "penalty":
        p_slots |= PENALTY_NUMBERS
    if treatment == "homotopy":
        if geometry == "sphere_sphere":
            raise ValueError("spheres are their own smooth stand-in: no homotopy")
        x_slots |= {"alpha": 1}
        p_slots |= {"stand_in_margin": 1}
    if between:
        x_slots |= {f"{s}_next": size for s, size in x_slots.items() if s not in ROBOT_SLOTS}
        p_slots |= {"fraction": 1}

    def body(x, p) -> Rows:
        x = _Between(x, p["fraction"]) if between else x
        penetration = _penetration(geometry, x, p)
        if treatment == "penalty":
            residual = ca.sqrt(p["weight"]) * penetration_residual(penetration, p["softness"])
            return Rows(residuals=[residual])
        if treatment == "constraint":
            return Rows(inequalities=[penetration])
        alpha, stand_in = x["alpha"], _stand_in(geometry, x, p)
        return Rows(inequalities=[alpha * stand_in + (1.0 - alpha) * penetration])

    # Sphere pairs' penalties stay Gauss-Newton with the exact Hessian too (the robot's own
    # links, active at many nodes at once: their curvature made IPOPT regularise).
    exact = geometry != "sphere_sphere"
    name = f"{geometry}_{treatment}" + ("_between" if between else "")
    return term_kind(
        name, x_slots, p_slots, body, exact_residuals=exact, one_sided=treatment == "penalty"
    )


@functools.cache
def homotopy_weight_kind() -> TermKind:
    """(13b): sqrt(w_hom) alpha, the residual whose square drives alpha to zero."""

    def body(x, p) -> Rows:
        return Rows(residuals=[ca.sqrt(p["weight"]) * x["alpha"]])

    return term_kind("homotopy_weight", {"alpha": 1}, {"weight": 1}, body)
