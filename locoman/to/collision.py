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
"""

from __future__ import annotations

import dataclasses
import functools

import casadi as ca
import mujoco
import numpy as np
import pinocchio as pin

from locoman.scene import g1
from locoman.scene.rotations import rpy_to_matrix

# The links whose spheres the default self-collision pairs use; the pairs measured most in
# MuJoCo replays of tiny: the arms against the torso and the hips. Every arm link from the
# shoulder's yaw link to the palm: without the wrist's roll and pitch links, a solve started
# away from the keyframes (S2's NoKeyframe, 2.5 kg, 0.6 rad) swung the forearm through the
# torso between the modelled links (141 mm deep), and the found pairs' rounds spent 1600
# iterations on it (docs/trajectory-optimisation.md). The knees against each other are a
# kind of their own (paper A, S2: "between the knees when walking", with (11)).
_ARM_LINKS = g1.ARM_CHAIN[g1.ARM_CHAIN.index("shoulder_yaw_link") :]
_TRUNK_LINKS = ("torso_link", "pelvis", "{side}_hip_roll_link", "{side}_hip_yaw_link")
_THIGHS = ("hip_roll_link", "hip_yaw_link")


# How a collision kind enters the TO: not at all, as the penalty (12) on p, as the hard
# constraint (11) p >= 0, or through the homotopy (13) from a smooth stand-in body.
TREATMENTS = ("off", "penalty", "constraint", "homotopy")


def _default_self_pairs() -> list[list[str]]:
    pairs = []
    for side in ("left", "right"):
        for arm in _ARM_LINKS:
            for trunk in _TRUNK_LINKS:
                if arm == "shoulder_yaw_link" and trunk != "torso_link":
                    continue
                pairs.append([f"{side}_{arm}", trunk.format(side=side)])
    # The thighs against the trunk: a bend and a step up fold them onto it.
    pairs += [[f"{side}_{thigh}", "torso_link"] for side in ("left", "right") for thigh in _THIGHS]
    return pairs


@dataclasses.dataclass
class CollisionCfg:
    """The collision terms of the TO (paper A, Sec. IV-D). Each kind has a treatment of
    :data:`TREATMENTS`: ``off``, ``penalty`` (12), ``constraint`` (11) or ``homotopy``
    (13) (the kinds against boxes: a sphere pair is its own smooth stand-in). A treatment is
    data: changing one compiles nothing.

    The defaults follow Sec. V-A's minimal set, but with (12) for the legs against the
    objects and the knees against each other where the paper has (13) and (11): with those
    S2 diverged (``docs/trajectory-optimisation.md``). Pairs the solution needs beyond the
    set are found along it (``found``).

    Attributes:
        self_pairs: Link pairs of the G1 kept apart between their spheres (the arms and
            the trunk).
        self_collision: Treatment of ``self_pairs``.
        knee_pairs: Link pairs of the legs kept apart while walking.
        knee_collision: Treatment of ``knee_pairs``; not ``homotopy``.
        object_body: Between the trunk's body points (pelvis, torso) and each object (its
            box; a trolley's chassis and handle frame).
        hands_object: Between each palm while it does not touch the object, and the
            object; a non-solid object's parts check the forearms too; the elbows always.
            The forearms of the hands holding an open object (a basket) are kept out of
            its parts with the least margin (touching allowed); a free hand is kept out of
            a basket's bounding box (``ObjectModel.reached_from_outside``).
        legs_object: Between the hips', thighs' and shins' spheres and each object's boxes.
        feet_object: Between the feet (a heel and a toe sphere each) and every object
            resting on the floor, but for a foot whose sole rests on its top (S1's box,
            S2's wheels: a wheeled object's wheels, not its chassis box, which the feet
            pass under while pushing).
        hands_environment: Between the palms and forearms and every fixed object's
            bounding box.
        feet_environment: Between the feet and every fixed object's bounding box (off by
            default: with it S2's exact phase crawled).
        found: The pairs found along a solution (:mod:`locoman.to.pair_search`): every pair
            of bodies that a replay of the solution in MuJoCo finds closer than
            ``audit_margin_m`` and the TO does not model joins the problem at the nodes
            around, and the solve goes on from where it stopped, at most ``rounds`` times;
            ``off``: no rounds, the minimal set alone.
        found_hard: The found pairs still penetrated after a round with them (the pairs that
            keep coming back: a hand through a post, a carried box into a platform) join
            again under this treatment; ``off``, or the same as ``found``: they stay as
            they are.
        rounds: The most rounds of :attr:`found` pairs after the first solve (and after
            each restart).
        restarts: When the rounds end with pairs missing or unfreed, or a round's solve
            fails, the solve starts again from Sec. IV-C.2's guess with every pair found so
            far (present from the first iteration, they keep the motion out of the minimum
            that held it), and the rounds go on from its solution; at most this many times
            (0: never).
        restart_arm_nodes: A restart keeps both arms whole out of each body (an object,
            a fixed object, the floor) that the checks found an arm's link against: every
            link from shoulder to palm against every box of that body, at up to this many
            nodes either side of where it was found while each hand's contact stays the
            same (``found_pairs.arm_pairs``); the rounds' pairs cover the one link and box,
            and moved the penetration to the next. 0 (the default): the pairs found, as
            they are; on S1's three Fig. 6 cells that restart, widening converged as often
            as not (docs/trajectory-optimisation.md).
        audit_margin_m: A pair of bodies closer than this in the replay is found [m].
        audit_substeps: Poses checked between two nodes (linear in q) besides the nodes.
        found_spacing_m: A carried object's found pairs take points along its edges (and
            along the other body's edges) at most this far apart [m]: an edge cuts about
            half this deep into a post between two points (its corners alone let a tilted
            box 30 mm into S2's trolley post).
        unfreed_m: A pair still deeper than this at the last check fails the solve
            (``Collision_Pairs_Unfreed``, the pairs in ``pairs_unfreed``), modelled or not:
            the rounds could not free it [m]. The evaluation's ``max_penetration_tol_m``.
        object_environment: Between the corners of the object, while no support holds it,
            and every fixed object's bounding box, and between the obstacles' vertical and
            top edges and the object (as (11) the bottom corners of a level box are
            dependent, and IPOPT stalled: keep it a penalty).
        object_object: Between the corners of a carried object and every other object's
            boxes, and between those boxes' vertical and top edges and the carried object.
            Off by default: on, S2's box no longer goes 88 mm through the trolley's post in
            the first solve of 7.5 kg, 1.2 rad (which then converges and passes), but S2's
            default solve ends ``Collision_Pairs_Missing``, its box cutting the table's
            corner between two nodes (docs/trajectory-optimisation.md).
        margin_m: Clearance added to every pair [m].
        smoothing_m: Log-sum-exp temperature of the box clearance [m]; it may overstate
            the clearance by up to ln(3) times this, so keep it below ``margin_m``.
        length_m: L, the length that scales a pair's penetration [m] (boxes and spheres).
        softness: Width, in p, over which (12)'s min(p, 0) is smoothed [-]
            (:func:`penetration_residual`); 0.01 is about a millimetre on a box.
    """

    self_pairs: list[list[str]] = dataclasses.field(default_factory=_default_self_pairs)
    self_collision: str = "penalty"
    knee_pairs: list[list[str]] = dataclasses.field(
        default_factory=lambda: [["left_knee_link", "right_knee_link"]]
    )
    knee_collision: str = "penalty"
    object_body: str = "penalty"
    hands_object: str = "penalty"
    legs_object: str = "penalty"
    feet_object: str = "penalty"
    hands_environment: str = "penalty"
    feet_environment: str = "off"
    object_environment: str = "penalty"
    object_object: str = "off"
    found: str = "penalty"
    found_hard: str = "constraint"
    rounds: int = 3
    restarts: int = 1
    restart_arm_nodes: int = 0
    audit_margin_m: float = 0.005
    audit_substeps: int = 3
    found_spacing_m: float = 0.04
    unfreed_m: float = 0.02
    margin_m: float = 0.01
    smoothing_m: float = 0.004
    length_m: float = 0.1
    softness: float = 0.01

    def check(self) -> list[tuple[str, str]]:
        errors = []
        # Pinocchio's link frames: the URDF read in 20 ms, where compiling the MuJoCo model
        # took a second of every stage's start-up.
        model = g1.g1_pinocchio_model()
        links = {f.name for f in model.frames if f.type == pin.FrameType.BODY}
        for field in ("self_pairs", "knee_pairs"):
            pairs = getattr(self, field)
            unknown = sorted({name for pair in pairs for name in pair} - links)
            if any(len(pair) != 2 for pair in pairs) or unknown:
                errors.append((field, f"needs pairs of G1 link names; unknown: {unknown}"))
        for kind in KINDS:
            value = getattr(self, kind)
            if value not in TREATMENTS:
                # YAML 1.1 reads an unquoted off as false.
                hint = ' (an unquoted off is YAML for false: write "off")' if value is False else ""
                errors.append((kind, f"must be one of {list(TREATMENTS)}, got {value!r}{hint}"))
        for kind in SPHERE_KINDS:
            if getattr(self, kind) == "homotopy":
                errors.append(
                    (kind, "spheres are their own smooth stand-in: use constraint, not homotopy")
                )
        if self.length_m <= 0.0:
            errors.append(("length_m", "must be > 0 m"))
        if not 0 <= self.rounds <= 20:
            errors.append(("rounds", "must be in 0 .. 20"))
        if not 0 <= self.restarts <= 5:
            errors.append(("restarts", "must be in 0 .. 5"))
        if self.restart_arm_nodes < 0:
            errors.append(("restart_arm_nodes", "must be >= 0 (0: no arm widened)"))
        if not 0 <= self.audit_substeps <= 20:
            errors.append(("audit_substeps", "must be in 0 .. 20"))
        if not 0.0 <= self.audit_margin_m <= 0.1:
            errors.append(("audit_margin_m", "must be in [0, 0.1] m"))
        if not 0.005 <= self.found_spacing_m <= 1.0:
            errors.append(("found_spacing_m", "must be in [0.005, 1] m"))
        if self.unfreed_m < 0.0:
            errors.append(("unfreed_m", "must be >= 0 m"))
        if self.softness <= 0.0:
            errors.append(("softness", "must be > 0"))
        if self.smoothing_m <= 0.0 or self.margin_m < np.log(3.0) * self.smoothing_m:
            errors.append(("margin_m", "needs smoothing_m > 0 and margin_m >= ln(3) smoothing_m"))
        return errors

    @property
    def homotopy(self) -> bool:
        """Some kind is treated by (13): the nodes carry its alpha."""
        return any(getattr(self, kind) == "homotopy" for kind in KINDS)


# The fields of CollisionCfg that hold a treatment; those between two of the G1's spheres.
SPHERE_KINDS = ("self_collision", "knee_collision")
KINDS = (
    *SPHERE_KINDS,
    "object_body",
    "hands_object",
    "legs_object",
    "feet_object",
    "hands_environment",
    "feet_environment",
    "object_environment",
    "object_object",
    "found",
    "found_hard",
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
    through the corners, sqrt(3) a_i, held S2's hips away from the box they carry; from
    there the solve diverged, cost 4e6 after 150 iterations.)"""
    x = R.T @ (centre_sphere - box_centre)
    return ca.sumsqr(x / (half + radius + cfg.margin_m)) - 1.0


def sphere_sphere_penetration(
    a: ca.SX, b: ca.SX, radius: ca.SX | float, length: ca.SX | float
) -> ca.SX:
    """(11) of two spheres whose radii (and margin) sum to ``radius`` [m], in the box pairs'
    units: p = (|a - b| - radius) / L, L = ``length`` [m] (|.| smoothed over 1 mm).

    The paper's d^2 - 1, d = |a - b| / radius, saturates at -1 as the centres meet, and its
    gradient 2 d grad d vanishes there, so (12) hardly pushed a deep pair out: S2's Foot cell
    at 2.5 kg, 0.6 rad ended its first solve with a wrist 123 mm in the torso and took 2 153
    iterations to converge, failing a check; with this p, whose gradient keeps its size at
    any depth, 236 iterations and every check passed (docs/performance.md)."""
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


_CORNER_SIGNS = [(x, y, z) for x in (-1.0, 1.0) for y in (-1.0, 1.0) for z in (-1.0, 1.0)]


def box_corners(half_extents) -> np.ndarray:
    """(8, 3) the corners of a box of ``half_extents`` (3,) [m] in its frame, which sits at
    the bottom face's centre."""
    half = np.asarray(half_extents, dtype=float).ravel()
    return np.array(_CORNER_SIGNS) * half + np.array([0.0, 0.0, half[2]])


def edge_point_counts(half_extents: np.ndarray, spacing: float) -> tuple[int, int, int]:
    """Points per edge of :func:`edge_points` along an obstacle's x, y and z axes, ends
    included, at most ``spacing`` apart [m]; a count is structure, so it comes from the
    numbers."""
    return tuple(int(np.ceil(2.0 * h / spacing)) + 1 for h in np.asarray(half_extents))


def edge_points(obstacle: Obstacle, counts: tuple[int, int, int]) -> np.ndarray:
    """(n, 3) world points along an obstacle's four vertical edges, from the top corners
    down, and along its four top edges between those corners (:func:`edge_point_counts`):
    an edge that enters a carried box between the box's corners is caught by one of them,
    a table's leg and the rim of its top alike (a box lifted off a table and swung over
    the rim, its corners outside the top, was not caught by corners alone). The bottom
    edges lie on the floor, where a carried object does not go."""
    n_x, n_y, n_z = counts
    signs = [(x, y, z) for x in (-1.0, 1.0) for y in (-1.0, 1.0) for z in np.linspace(1, -1, n_z)]
    signs += [(x, y, 1.0) for x in np.linspace(-1, 1, n_x)[1:-1] for y in (-1.0, 1.0)]
    signs += [(x, y, 1.0) for x in (-1.0, 1.0) for y in np.linspace(-1, 1, n_y)[1:-1]]
    local = np.array(signs) * np.asarray(obstacle.half_extents, dtype=float)
    return np.asarray(obstacle.centre, dtype=float) + local @ obstacle.rotation.T


def box_edge_points(centre, half_extents, spacing: float) -> np.ndarray:
    """(n, 3) points along all twelve edges of a box (centre [m], half sizes [m], in its
    frame), corners included, each once, at most ``spacing`` [m] apart. A carried box's
    corners alone miss its edge cutting into a thin post: tilted, it went 30 mm into S2's
    trolley post between them; along an edge, it goes at most about half the spacing in
    before a point is inside."""
    half = np.asarray(half_extents, dtype=float).ravel()
    points = []
    for axis in range(3):
        u, v = (a for a in range(3) if a != axis)
        n = int(np.ceil(2.0 * half[axis] / spacing)) + 1
        for s_u in (-1.0, 1.0):
            for s_v in (-1.0, 1.0):
                along = np.linspace(-1.0, 1.0, n)
                # The ends are corners: the edges along x hold them, the others skip them.
                for t in along if axis == 0 else along[1:-1]:
                    sign = np.zeros(3)
                    sign[[axis, u, v]] = t, s_u, s_v
                    points.append(sign * half)
    return np.asarray(centre, dtype=float).ravel() + np.array(points)


@dataclasses.dataclass(frozen=True)
class Sphere:
    """A collision sphere fixed to a link: centre in the link frame [m], radius [m]."""

    link: str
    centre: np.ndarray
    radius: float


# The G1's collision geoms the TO covers with spheres: its fitted capsules and spheres, and
# the shoulders' cylinders (a chain of spheres along the axis, which rounds their ends).
_SPHERED = tuple(
    int(t)
    for t in (
        mujoco.mjtGeom.mjGEOM_CAPSULE,
        mujoco.mjtGeom.mjGEOM_SPHERE,
        mujoco.mjtGeom.mjGEOM_CYLINDER,
    )
)


@functools.cache
def link_spheres(link: str) -> tuple[Sphere, ...]:
    """The spheres of a G1 link's collision geoms (but the feet's boxes, which the TO covers
    with its sole frames' heel and toe spheres)."""
    model = g1.g1_mjmodel()
    body = model.body(link).id
    spheres = []
    for geom in range(model.ngeom):
        if model.geom_bodyid[geom] != body or model.geom_group[geom] != g1.COLLISION_GROUP:
            continue
        if int(model.geom_type[geom]) not in _SPHERED:
            continue
        spheres += [Sphere(link, c, r) for c, r in _axis_spheres(model, geom)]
    if not spheres:
        raise ValueError(f"the G1 link {link!r} has no collision capsule, sphere or cylinder")
    return tuple(spheres)


def _axis_spheres(model: mujoco.MjModel, geom: int) -> list[tuple[np.ndarray, float]]:
    """A capsule or sphere as :func:`g1.capsule_spheres` has it; a cylinder as the capsule
    of its radius and axis."""
    if model.geom_type[geom] != mujoco.mjtGeom.mjGEOM_CYLINDER:
        return g1.capsule_spheres(model, geom)
    radius, half = model.geom_size[geom][:2]
    rot = np.zeros(9)
    mujoco.mju_quat2Mat(rot, model.geom_quat[geom])
    axis = rot.reshape(3, 3)[:, 2]
    count = int(np.ceil(2.0 * half / radius)) + 1
    pos = model.geom_pos[geom]
    return [(pos + t * half * axis, float(radius)) for t in np.linspace(-1.0, 1.0, count)]
