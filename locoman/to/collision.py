"""Collision avoidance of paper A, Sec. IV-D: the scaled penetration (11) and its penalty (12).

The paper scales a point's distance d from the centroid of the penetrated body, an
ellipsoid, and asks p = d^2 - 1 >= 0 (11). That is what the G1's links get: each is a chain
of spheres (its MuJoCo collision capsules, as placo uses them), and two spheres are kept
apart by (11) with d = |c_a - c_b| / (r_a + r_b + margin).

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
"""

from __future__ import annotations

import dataclasses
import functools

import casadi as ca
import mujoco
import numpy as np

from locoman.scene import g1
from locoman.scene.rotations import rpy_to_matrix
from locoman.to.kinematics import rot_z

# The links whose spheres the default self-collision pairs use; the pairs measured most in
# MuJoCo replays of tiny: the arms against the torso and the hips, the knees against each
# other (paper A, S2: "between the knees when walking").
_ARM_LINKS = ("shoulder_yaw_link", "elbow_link", "wrist_yaw_link", "rubber_hand")
_TRUNK_LINKS = ("torso_link", "pelvis", "{side}_hip_roll_link", "{side}_hip_yaw_link")


# How a collision kind enters the TO: not at all, as the penalty (12) on p, or as the hard
# constraint (11) p >= 0.
TREATMENTS = ("off", "penalty", "constraint")


def _default_self_pairs() -> list[list[str]]:
    pairs = []
    for side in ("left", "right"):
        for arm in _ARM_LINKS:
            for trunk in _TRUNK_LINKS:
                if arm == "shoulder_yaw_link" and trunk != "torso_link":
                    continue
                pairs.append([f"{side}_{arm}", trunk.format(side=side)])
    pairs.append(["left_knee_link", "right_knee_link"])
    return pairs


@dataclasses.dataclass
class CollisionCfg:
    """The collision terms of the TO (paper A, Sec. IV-D). Each kind has a treatment of
    :data:`TREATMENTS`: ``off``, ``penalty`` (12) or ``constraint`` (11); a change of
    treatment changes the problem's structure (one compile).

    Attributes:
        self_pairs: Link pairs of the G1 kept apart between their spheres.
        self_collision: Treatment of ``self_pairs``.
        object_body: Between the robot's body points, and each palm while it does not touch
            the object, and the object (its box; a trolley's chassis and handle frame).
        hands_environment: Between the palms and every fixed object's bounding box.
        feet_environment: Between the feet (a heel and a toe sphere each) and every fixed
            object's bounding box. Off by default: it keeps S2's swing foot out of the table
            leg it crosses while the robot carries the box round the table's corner, but
            with it S2's exact-Hessian phase crawled (cost 2358 at 1000 iterations, not
            converged).
        object_environment: Between the corners of the object, while no support holds it,
            and every fixed object's bounding box, and between the obstacles' vertical edges
            and the object. (As the constraint (11) the four bottom corners of a level box
            are dependent, and IPOPT stalled: keep it a penalty.)
        margin_m: Clearance added to every pair [m].
        smoothing_m: Log-sum-exp temperature of the box clearance [m]; it may overstate
            the clearance by up to ln(3) times this, so keep it below ``margin_m``.
        length_m: L, the length that scales a box's penetration [m].
        softness: Width, in p, over which (12)'s min(p, 0) is smoothed [-]
            (:func:`penetration_residual`); 0.01 is about a millimetre on a box.
    """

    self_pairs: list[list[str]] = dataclasses.field(default_factory=_default_self_pairs)
    self_collision: str = "penalty"
    object_body: str = "penalty"
    hands_environment: str = "penalty"
    feet_environment: str = "off"
    object_environment: str = "penalty"
    margin_m: float = 0.01
    smoothing_m: float = 0.004
    length_m: float = 0.1
    softness: float = 0.01

    def check(self) -> list[tuple[str, str]]:
        errors = []
        model = g1.g1_mjmodel()
        links = {model.body(b).name for b in range(model.nbody)}
        unknown = sorted({name for pair in self.self_pairs for name in pair} - links)
        if any(len(pair) != 2 for pair in self.self_pairs) or unknown:
            errors.append(("self_pairs", f"needs pairs of G1 link names; unknown: {unknown}"))
        for kind in KINDS:
            value = getattr(self, kind)
            if value not in TREATMENTS:
                # YAML 1.1 reads an unquoted off as false.
                hint = ' (an unquoted off is YAML for false: write "off")' if value is False else ""
                errors.append((kind, f"must be one of {list(TREATMENTS)}, got {value!r}{hint}"))
        if self.length_m <= 0.0:
            errors.append(("length_m", "must be > 0 m"))
        if self.softness <= 0.0:
            errors.append(("softness", "must be > 0"))
        if self.smoothing_m <= 0.0 or self.margin_m < np.log(3.0) * self.smoothing_m:
            errors.append(("margin_m", "needs smoothing_m > 0 and margin_m >= ln(3) smoothing_m"))
        return errors


# The fields of CollisionCfg that hold a treatment.
KINDS = (
    "self_collision",
    "object_body",
    "hands_environment",
    "feet_environment",
    "object_environment",
)


@dataclasses.dataclass(frozen=True)
class Obstacle:
    """A fixed box of the scene.

    Attributes:
        name: ``<object>/<primitive>``.
        centre: (3,) world [m].
        yaw: About world z [rad].
        half_extents: (3,) [m].
    """

    name: str
    centre: np.ndarray
    yaw: float
    half_extents: np.ndarray

    @property
    def rotation(self) -> np.ndarray:
        return rpy_to_matrix(np.array([0.0, 0.0, self.yaw]))

    def frame(self) -> tuple[ca.SX, ca.SX, ca.SX]:
        """Centre (3,) [m], rotation (3, 3) and half sizes (3,) [m] as CasADi values,
        whether the fields are numbers or the symbols of
        :class:`locoman.to.parameters.SymbolicGlobals`."""
        return column(self.centre), rot_z(self.yaw), column(self.half_extents)


def column(x) -> ca.SX | ca.DM:
    """A CasADi column of numbers (DM) or of an expression (unchanged)."""
    return x if isinstance(x, ca.SX | ca.MX) else ca.DM(np.asarray(x, dtype=float).ravel())


def obstacles_from_objects(objects: dict[str, dict]) -> tuple[Obstacle, ...]:
    """One box per fixed object of the scene (``objects.json``): the bounding box of its
    primitives in the object's frame (a table's top and legs make one block, so that nothing
    passes under the top)."""
    out = []
    for name, spec in sorted(objects.items()):
        if spec["movable"]:
            continue
        lows, highs = [], []
        for prim in spec["primitives"]:
            if prim["shape"] != "box":
                raise ValueError(
                    f"{name}/{prim['name']}: the TO's collision model knows boxes, "
                    f"not {prim['shape']!r}"
                )
            lows.append(np.asarray(prim["pos"]) - prim["size"])
            highs.append(np.asarray(prim["pos"]) + prim["size"])
        if not lows:
            continue
        low, high = np.min(lows, axis=0), np.max(highs, axis=0)
        R = rpy_to_matrix(np.array([0.0, 0.0, spec["yaw_rad"]]))
        centre = np.asarray(spec["pos_m"], dtype=float) + R @ (0.5 * (low + high))
        out.append(Obstacle(name, centre, float(spec["yaw_rad"]), 0.5 * (high - low)))
    return tuple(out)


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
    centre_sphere: ca.SX, radius: float, box_centre: ca.SX, R: ca.SX, half: ca.SX, cfg
) -> ca.SX:
    """(11) for a sphere (radius 0: a point) and a box: p = (c - r - margin) / L, c the
    clearance of its centre."""
    clearance = box_clearance(centre_sphere, box_centre, R, half, cfg.smoothing_m)
    return (clearance - radius - cfg.margin_m) / cfg.length_m


def sphere_sphere_penetration(a: ca.SX, b: ca.SX, radius: float) -> ca.SX:
    """(11) of two spheres whose radii (and margin) sum to ``radius``: d = |a - b| / radius,
    p = d^2 - 1."""
    return ca.sumsqr(a - b) / radius**2 - 1.0


def penetration_residual(p: ca.SX, softness: float) -> ca.SX:
    """The residual r of (12), whose square is the penalty: min(p, 0) smoothed over
    ``softness`` (-softness ln(1 + exp(-p / softness)), written so that it cannot overflow).

    The paper's p^2 for p < 0 is only once differentiable; with it IPOPT reached the
    optimum of ``tiny`` at 69 nodes by iteration 160 and then cycled between a penalty's
    active and inactive sides for 770 more. Smoothed, r and its Gauss-Newton curvature turn
    on before contact; for |p| >> softness r is min(p, 0), and at p = 0 it is -softness ln 2.
    """
    return ca.fmin(p, 0.0) - softness * ca.log1p(ca.exp(-ca.fabs(p) / softness))


_CORNER_SIGNS = [(x, y, z) for x in (-1.0, 1.0) for y in (-1.0, 1.0) for z in (-1.0, 1.0)]


def box_corners(half_extents) -> list[ca.SX | ca.DM]:
    """The 8 corners (3,) of a box of ``half_extents`` (3,) [m] in its frame, which sits at
    the bottom face's centre; numbers or CasADi expressions."""
    half = column(half_extents)
    lift = ca.vertcat(0.0, 0.0, half[2])
    return [ca.DM(signs) * half + lift for signs in _CORNER_SIGNS]


def edge_point_counts(half_extents: np.ndarray, spacing: float) -> tuple[int, int, int]:
    """Points per edge of :func:`edge_points` along an obstacle's x, y and z axes, ends
    included, at most ``spacing`` apart [m]; a count is structure, so it comes from the
    numbers."""
    return tuple(int(np.ceil(2.0 * h / spacing)) + 1 for h in np.asarray(half_extents))


def edge_points(obstacle: Obstacle, counts: tuple[int, int, int]) -> list[ca.SX | ca.DM]:
    """World points (3,) along an obstacle's four vertical edges, from the top corners
    down, and along its four top edges between those corners (:func:`edge_point_counts`):
    an edge that enters a carried box between the box's corners is caught by one of them,
    a table's leg and the rim of its top alike (a box lifted off a table and swung over
    the rim, its corners outside the top, was not caught by corners alone). The bottom
    edges lie on the floor, where a carried object does not go."""
    centre, R, half = obstacle.frame()
    n_x, n_y, n_z = counts
    signs = [(x, y, z) for x in (-1.0, 1.0) for y in (-1.0, 1.0) for z in np.linspace(1, -1, n_z)]
    signs += [(x, y, 1.0) for x in np.linspace(-1, 1, n_x)[1:-1] for y in (-1.0, 1.0)]
    signs += [(x, y, 1.0) for x in (-1.0, 1.0) for y in np.linspace(-1, 1, n_y)[1:-1]]
    return [centre + R @ (ca.DM(sign) * half) for sign in signs]


@dataclasses.dataclass(frozen=True)
class Sphere:
    """A collision sphere fixed to a link: centre in the link frame [m], radius [m]."""

    link: str
    centre: np.ndarray
    radius: float


@functools.cache
def link_spheres(link: str) -> tuple[Sphere, ...]:
    """The spheres of a G1 link's collision capsules."""
    model = g1.g1_mjmodel()
    body = model.body(link).id
    spheres = []
    for geom in range(model.ngeom):
        if model.geom_bodyid[geom] != body or model.geom_group[geom] != g1.COLLISION_GROUP:
            continue
        if model.geom_type[geom] != mujoco.mjtGeom.mjGEOM_CAPSULE:
            continue
        spheres += [Sphere(link, c, r) for c, r in g1.capsule_spheres(model, geom)]
    if not spheres:
        raise ValueError(f"the G1 link {link!r} has no collision capsule")
    return tuple(spheres)


def self_collision_penetrations(frame_pose, pairs: list[list[str]], margin: float) -> list[ca.SX]:
    """p of (11) between the spheres of each link pair, each sphere pair an ellipsoid (a
    ball) of radius r_a + r_b + margin about one centre.

    Args:
        frame_pose: name -> (R, p) symbolic world pose of a link.
        pairs: Link pairs.
        margin: [m].
    """
    out = []
    poses = {}
    for link in {name for pair in pairs for name in pair}:
        R, p = frame_pose(link)
        poses[link] = [(p + R @ ca.DM(s.centre), s.radius) for s in link_spheres(link)]
    for a, b in pairs:
        for ca_, ra in poses[a]:
            for cb, rb in poses[b]:
                out.append(sphere_sphere_penetration(ca_, cb, ra + rb + margin))
    return out


@dataclasses.dataclass
class CollisionTerms:
    """The scaled penetrations p (11) of one node, sorted by how the configuration treats
    their kind: the penalty (12) or the hard constraint (11)."""

    penalized: list[ca.SX] = dataclasses.field(default_factory=list)
    constrained: list[ca.SX] = dataclasses.field(default_factory=list)

    def add(self, treatment: str, penetrations: list[ca.SX]) -> None:
        """Add the p of one kind, treated by ``treatment`` (:data:`TREATMENTS`)."""
        if treatment == "penalty":
            self.penalized += penetrations
        elif treatment == "constraint":
            self.constrained += penetrations

    def residuals(self, softness: ca.SX, weight: ca.SX) -> ca.SX:
        """The residuals of (12), scaled by sqrt(weight): their sum of squares is the
        weighted penalty."""
        r = [penetration_residual(p, softness) for p in self.penalized]
        return ca.sqrt(weight) * ca.vertcat(*r) if r else ca.SX(0, 1)

    def inequalities(self) -> ca.SX:
        """The left-hand sides of (11), p >= 0."""
        return ca.vertcat(*self.constrained) if self.constrained else ca.SX(0, 1)
