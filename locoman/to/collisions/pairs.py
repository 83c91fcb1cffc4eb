"""The collision pairs of a problem: which robot sphere, object point or box is kept out of
which box or sphere at which node (:class:`CollisionPair`). :func:`collision_pairs` is paper
A's minimal set (Sec. V-A) by each node's mode; the rounds of found pairs
(:mod:`locoman.to.rounds.search`) add to it. Each pair is data for one call of a collision
term (:mod:`locoman.to.terms.collisions`): adding one compiles nothing."""

from __future__ import annotations

import dataclasses
import functools
import itertools
from collections.abc import Iterator

import numpy as np

from locoman.config.to import CollisionCfg, ContactCfg
from locoman.retarget.robot import ContactFrames
from locoman.to.collisions.boxes import (
    box_corners,
    box_edge_points,
    edge_point_counts,
    edge_points,
    seated_boxes,
)
from locoman.to.collisions.spheres import (
    ELBOW_LINKS,
    FOREARM_LINKS,
    LEG_LINKS,
    RobotSphere,
    SphereSet,
    body_point_spheres,
    foot_spheres,
    link_sphere_list,
    palm_spheres,
)
from locoman.to.problem.modes import NodeMode
from locoman.to.problem.numbers import Numbers
from locoman.to.problem.objects import ObjectModel, Obstacle


@dataclasses.dataclass(frozen=True)
class CollisionPair:
    """One collision term at one node: what is kept out of what.

    Attributes:
        node: The node.
        kind: Its :class:`CollisionCfg` kind (which decides its treatment).
        geometry: A key of :data:`locoman.to.terms.collisions.GEOMETRIES`.
        sphere: The robot's sphere (the ``sphere_*`` geometries).
        other: ``sphere_sphere``'s second sphere.
        obj: The moving object of the ``*object*`` geometries (the point's, for
            ``object_point_*``).
        box_obj: ``object_point_object_box``'s other object, whose box it is.
        numbers: The geometry's numbers (box centre and half sizes, a point, a yaw) [m, rad].
        touching: Kept out of the box only, with the least margin (a hand holding an open
            object keeps its forearm out of it).
        fraction: Where along the step from ``node`` to the next [-]: 0 at ``node``.
        label: What the pair is, for reports (``left_elbow_link/1 | basket/floor``).
    """

    node: int
    kind: str
    geometry: str
    sphere: RobotSphere | None = None
    other: RobotSphere | None = None
    obj: int | None = None
    box_obj: int | None = None
    numbers: dict = dataclasses.field(default_factory=dict)
    touching: bool = False
    fraction: float = 0.0
    label: str = ""

    @functools.cached_property
    def identity(self) -> tuple:
        """What makes two pairs the same, whatever their kind: where, the geometry, the
        spheres (either way round), the objects and the numbers (to 1e-9). Not the label: a
        hand's pairs against the trolley's handle frame were labelled like those against its
        platform (both ``trolley/0``), so once it had the platform's, the frame's never
        joined. Made once per pair: a round of found pairs compares thousands of them."""
        spheres = tuple(sorted(s.name for s in (self.sphere, self.other) if s is not None))
        numbers = tuple(
            (name, tuple(map(round, np.ravel(value).tolist(), itertools.repeat(9))))
            for name, value in sorted(self.numbers.items())
        )
        where = (self.node, round(self.fraction, 6))
        return (*where, self.geometry, spheres, self.obj, self.box_obj, numbers)


def prehensile(contact: ContactCfg, obj: ObjectModel) -> bool:
    return bool(contact.prehensile or obj.prehensile)


def _smallest_half_size(obj: ObjectModel) -> float:
    """An object box's smallest half size [m]: its patch's half sizes and half its height
    (its CoM sits at half height)."""
    return float(min(np.min(obj.half_extents), obj.com[2]))


def _object_box(obj: ObjectModel) -> tuple[np.ndarray, np.ndarray]:
    """A solid object's collision box in its frame: centre [m] (its CoM) and half sizes [m]
    (its patch's, and half its height: its frame sits at the bottom face)."""
    return np.asarray(obj.com, dtype=float), np.r_[obj.half_extents, obj.com[2]]


def _boxes(obj: ObjectModel, parts: tuple) -> list[tuple[np.ndarray, np.ndarray]]:
    return [(np.asarray(c, dtype=float), np.asarray(h, dtype=float)) for c, h in parts]


def object_boxes(obj: ObjectModel) -> list[tuple[np.ndarray, np.ndarray]]:
    """An object's collision boxes in its frame, (centre [m], half sizes [m]) each: a solid
    one's box, else its parts."""
    return [_object_box(obj)] if obj.solid else _boxes(obj, obj.parts)


def sphere_box_pairs(
    node: int,
    kind: str,
    spheres,
    boxes,
    j: int,
    name: str,
    touching: bool = False,
    first: int = 0,
) -> Iterator[CollisionPair]:
    """Each sphere against each of object j's ``boxes``, labelled by box index from ``first``
    (a slice of the object's boxes keeps their own)."""
    for b, (centre, half) in enumerate(boxes, start=first):
        for s in spheres:
            yield CollisionPair(
                node,
                kind,
                "sphere_object_box",
                sphere=s,
                obj=j,
                numbers={"centre": centre, "half": half},
                touching=touching,
                label=f"{s.name} | {name}/{b}",
            )


def node_collision_pairs(
    k: int,
    mode: NodeMode,
    objects: tuple[ObjectModel, ...],
    obstacles: tuple[Obstacle, ...],
    cfg: CollisionCfg,
    contact: ContactCfg,
    frames: ContactFrames,
) -> Iterator[CollisionPair]:
    """The collision pairs at node k, each of a kind that is not ``off``: the trunk's body
    points, the legs' and the feet's spheres and the arms not touching it against each
    object's boxes (reaching down through a fixed support: :mod:`locoman.to.collisions.boxes`); each
    carried object's corners against the obstacles and the other objects' boxes, and their
    edges against it; the palms, forearms and feet against the obstacles."""
    body = body_point_spheres()
    legs = [s for link in LEG_LINKS for s in link_sphere_list(link)]
    palms = [palm_spheres(frames, i) for i in range(2)]
    forearms = [link_sphere_list(link) for link in FOREARM_LINKS]
    elbows = [s for link in ELBOW_LINKS for s in link_sphere_list(link)]
    feet = [foot_spheres(frames, i) for i in range(2)]
    on = {kind for kind in ("object_body", "hands_object", "legs_object", "feet_object")}
    on = {kind for kind in on if getattr(cfg, kind) != "off"}
    for j, obj in enumerate(objects):
        boxes = seated_boxes(object_boxes(obj), mode.objects[j].seat)
        under = boxes if obj.solid else _boxes(obj, obj.wheels or obj.parts)
        name = obj.name
        if "object_body" in on:
            yield from sphere_box_pairs(k, "object_body", body, boxes, j, name)
        if "hands_object" in on:
            # A palm that does not touch the object; a solid box's own corners catch a
            # forearm, while a trolley's thin handle bar passes between the palms and the
            # body points, so an open object checks the forearm too. The elbows always:
            # taking a basket that overhangs a shelf, they went into its floor.
            arms, reaching = [], []
            for i in range(2):
                if mode.hands[i] == j:
                    continue
                spheres = palms[i] if obj.solid else palms[i] + forearms[i]
                free = obj.reached_from_outside and mode.hands[i] is None
                (reaching if free else arms).extend(spheres)
            yield from sphere_box_pairs(k, "hands_object", arms + elbows, boxes, j, name)
            # A free hand reaching for a basket: against its parts alone, the first solve
            # took S1's basket with a palm through its wall into its empty inside, and the
            # found pairs chased the hand from wall to wall (two Fig. 6 cells failed so).
            # Its bounding box (split over its seat like the parts) is numbered after them.
            if reaching:
                hull = seated_boxes([_object_box(obj)], mode.objects[j].seat)
                yield from sphere_box_pairs(
                    k, "hands_object", reaching, hull, j, name, first=len(boxes)
                )
            # The forearms of the hands holding an open object (a basket's wall) are kept
            # out of it, touching allowed; a gripped handle sits in the hand.
            if not obj.solid and not prehensile(contact, obj):
                holding = [s for i in range(2) if mode.hands[i] == j for s in forearms[i]]
                yield from sphere_box_pairs(
                    k, "hands_object", holding, boxes, j, name, touching=True
                )
        if "legs_object" in on:
            yield from sphere_box_pairs(k, "legs_object", legs, boxes, j, name)
        if "feet_object" in on and j in mode.underfoot:
            # Off an object on the floor (S1's box, S2's wheels), but for a foot on its top.
            feet_j = [s for i in range(2) if mode.feet_on[i] != j for s in feet[i]]
            yield from sphere_box_pairs(k, "feet_object", feet_j, under, j, name)
    for j, obj in enumerate(objects):
        if not mode.carried(j):
            continue
        if cfg.object_environment != "off":
            yield from object_environment_pairs(k, j, obj, obstacles)
        if cfg.object_object != "off":
            for i, other in enumerate(objects):
                if i != j:
                    yield from object_object_pairs(k, j, obj, i, other)
    arms = [s for i in range(2) for s in palms[i] + forearms[i]]
    both_feet = feet[0] + feet[1]
    for kind, spheres in (("hands_environment", arms), ("feet_environment", both_feet)):
        if getattr(cfg, kind) == "off":
            continue
        for obstacle in obstacles:
            yield from obstacle_pairs(k, kind, spheres, obstacle)


def obstacle_pairs(
    k: int, kind: str, spheres: list[RobotSphere], obstacle: Obstacle
) -> Iterator[CollisionPair]:
    """Each sphere against a fixed box at node k."""
    for s in spheres:
        yield CollisionPair(
            k,
            kind,
            "sphere_fixed_box",
            sphere=s,
            numbers=_obstacle_numbers(obstacle),
            label=f"{s.name} | {obstacle.name}",
        )


def _obstacle_numbers(obstacle: Obstacle) -> dict:
    return {"centre": obstacle.centre, "yaw": obstacle.yaw, "half": obstacle.half_extents}


def object_environment_pairs(
    k: int,
    j: int,
    obj: ObjectModel,
    obstacles: tuple[Obstacle, ...],
    kind: str = "object_environment",
    spacing: float | None = None,
    obstacle_edges: bool = True,
) -> Iterator[CollisionPair]:
    """Points of carried object j against each obstacle, and the obstacles' vertical and
    top edges (points, spaced by the object's smallest half size) against the object. The
    object's points are its corners, or with ``spacing`` [m] points along all its edges at
    most that far apart (:func:`box_edge_points`), which then spaces the obstacles' edge
    points too where it is the smaller; ``obstacle_edges`` False: the object's points alone
    (the floor, whose edges lie far away)."""
    centre, half = _object_box(obj)
    if spacing is None:
        points, edge_spacing = box_corners(half), _smallest_half_size(obj)
    else:
        points = box_edge_points(centre, half, spacing)
        edge_spacing = min(spacing, _smallest_half_size(obj))
    for obstacle in obstacles:
        for n, c in enumerate(points):
            yield CollisionPair(
                k,
                kind,
                "object_point_fixed_box",
                obj=j,
                numbers={"point": c, **_obstacle_numbers(obstacle)},
                label=f"{obj.name}/point{n} | {obstacle.name}",
            )
        if not obstacle_edges:
            continue
        counts = edge_point_counts(obstacle.half_extents, edge_spacing)
        for n, point in enumerate(edge_points(obstacle, counts)):
            yield CollisionPair(
                k,
                kind,
                "fixed_point_object_box",
                obj=j,
                numbers={"point": point, "centre": centre, "half": half},
                label=f"{obstacle.name}/edge{n} | {obj.name}",
            )


def object_object_pairs(
    k: int, j: int, obj: ObjectModel, i: int, other: ObjectModel
) -> Iterator[CollisionPair]:
    """Carried object j against object i, both moving: j's corners against each of i's
    boxes, and each box's vertical and top edges (points spaced by j's smallest half size)
    against j's box, as :func:`object_environment_pairs` keeps j off a fixed box (S2's box
    swung past the trolley went 88 mm through its post before any found pair held it)."""
    centre, half = _object_box(obj)
    spacing = _smallest_half_size(obj)
    kind = "object_object"
    for b, (centre_b, half_b) in enumerate(object_boxes(other)):
        corners = box_corners(half)
        label = (f"{obj.name}/point", f" | {other.name}/{b}")
        yield from object_point_pairs(k, kind, j, corners, i, (centre_b, half_b), label)
        part = Obstacle(f"{other.name}/{b}", centre_b, 0.0, half_b)
        edges = edge_points(part, edge_point_counts(half_b, spacing))
        label = (f"{other.name}/{b}/edge", f" | {obj.name}")
        yield from object_point_pairs(k, kind, i, edges, j, (centre, half), label)


def object_point_pairs(
    k: int,
    kind: str,
    obj: int,
    points: np.ndarray,
    box_obj: int,
    box: tuple[np.ndarray, np.ndarray],
    label: tuple[str, str],
) -> Iterator[CollisionPair]:
    """Each of ``points`` (n, 3) fixed to object ``obj`` (in its frame [m]) against a box
    (centre [m], half sizes [m], in its frame) of object ``box_obj``, both moving; the n-th
    pair's label is ``label[0]``, n, ``label[1]``."""
    centre, half = box
    for n, point in enumerate(points):
        yield CollisionPair(
            k,
            kind,
            "object_point_object_box",
            obj=obj,
            box_obj=box_obj,
            numbers={"point": point, "centre": centre, "half": half},
            label=f"{label[0]}{n}{label[1]}",
        )


def self_collision_pairs(k: int, cfg: CollisionCfg) -> Iterator[CollisionPair]:
    """The spheres of each link pair of ``self_pairs`` and ``knee_pairs`` whose kind is on."""
    for kind, pairs in (("self_collision", cfg.self_pairs), ("knee_collision", cfg.knee_pairs)):
        if getattr(cfg, kind) == "off":
            continue
        for a, b in pairs:
            for sa in link_sphere_list(a):
                for sb in link_sphere_list(b):
                    yield CollisionPair(
                        k,
                        kind,
                        "sphere_sphere",
                        sphere=sa,
                        other=sb,
                        label=f"{sa.name} | {sb.name}",
                    )


def collision_pairs(
    modes: list[NodeMode], numbers: Numbers, frames: ContactFrames
) -> list[CollisionPair]:
    """Every collision pair of the problem: at every node those of its mode, and the
    robot's own pairs at every node but the first (fixed)."""
    out = []
    for k, mode in enumerate(modes):
        out += node_collision_pairs(
            k, mode, numbers.objects, numbers.obstacles, numbers.collision, numbers.contact, frames
        )
        if k > 0:
            out += self_collision_pairs(k, numbers.collision)
    return out


def used_spheres(pairs: list[CollisionPair]) -> SphereSet:
    return SphereSet(s for pair in pairs for s in (pair.sphere, pair.other) if s is not None)
