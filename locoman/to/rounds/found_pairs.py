"""Which of the TO's collision pairs answer a close pair that MuJoCo found along a solution.

A pair of bodies closer than a margin (:mod:`locoman.sim.audit`) maps to the pairs that keep
them apart: the robot link's spheres against the other link's spheres, the object's box
nearest the contact, the fixed object's box or the floor; points along a carried object's
edges against what it came close to; at the nodes around where it happened
(:func:`found_pairs`). A pair that keeps coming back is promoted to the hard (11)
(:func:`promoted_pairs`). The rounds that add them: :mod:`locoman.to.rounds.search`.
"""

from __future__ import annotations

import dataclasses
import functools

import numpy as np

from locoman.config.to import CollisionCfg
from locoman.retarget.robot import ContactFrames
from locoman.scene import g1
from locoman.scene.rotations import rpy_to_matrix
from locoman.sim.audit import ROBOT, Body, ClosePair, allowed_at
from locoman.to.collisions.boxes import (
    Seat,
    box_edge_points,
    edge_point_counts,
    edge_points,
    seated_boxes,
)
from locoman.to.collisions.pairs import (
    CollisionPair,
    object_boxes,
    object_environment_pairs,
    object_point_pairs,
    obstacle_pairs,
    sphere_box_pairs,
)
from locoman.to.collisions.spheres import RobotSphere, foot_spheres, link_sphere_list
from locoman.to.problem.objects import ObjectModel, Obstacle

KIND = "found"

PROMOTED = "found_hard"  # a found pair still penetrated after a round with it

# The links between each palm and its forearm. Holding an object they sit millimetres off
# its face, so their found pairs against it keep them out of it (touching allowed), not a
# margin away: at the margin they pushed the palm off the face by its whole slack (S2's
# AllKeyframe, 5 kg, 1.2 rad: the wrists 7-8 mm from the held box, the palm 4-5.7 mm off it).
WRIST_LINKS = tuple(
    tuple(f"{side}_wrist_{joint}_link" for joint in ("roll", "pitch", "yaw"))
    for side in ("left", "right")
)

# Each arm's links, shoulder to palm. With ``CollisionCfg.restart_arm_nodes`` a restart
# keeps both arms whole out of what one of them was found in: S1's AllKeyframe (2.5 kg,
# 1.2 rad) found the right palm in the basket's back wall, then in its right wall, the
# shoulder in the shelf's top, each round's pairs pushing the arm into the next link's or
# box's blind spot.
ARM_LINKS = tuple(tuple(f"{side}_{link}" for link in g1.ARM_CHAIN) for side in ("left", "right"))

# The floor as a box under it, for a link or a carried object that reaches it.
FLOOR_BOX = Obstacle("floor", np.array([0.0, 0.0, -0.5]), 0.0, np.array([50.0, 50.0, 0.5]))


def robot_spheres(link: str, frames: ContactFrames) -> list[RobotSphere]:
    """The TO's spheres of a G1 link: a foot's heel and toe, else its capsules' chain."""
    if link in g1.FOOT_LINKS:
        return foot_spheres(frames, g1.FOOT_LINKS.index(link))
    return link_sphere_list(link)


def _nearest_box(boxes: list, pose: np.ndarray, point: np.ndarray) -> int:
    """The index of the collision box (centre, half sizes in the object's frame [m]) of
    ``boxes`` nearest ``point`` [m, world], the object at ``pose`` (p, rpy)."""
    local = rpy_to_matrix(pose[3:6]).T @ (point - pose[:3])
    gaps = [np.linalg.norm(np.maximum(np.abs(local - c) - h, 0.0)) for c, h in boxes]
    return int(np.argmin(gaps))


@dataclasses.dataclass(frozen=True)
class SolutionScene:
    """What the search maps MuJoCo's bodies to: the TO's objects (in its order) with their
    poses along the solution, the fixed objects' boxes, the robot's frames, and the
    solution's contact schedule (:func:`trajectory_arrays`; None: touching allowed
    nowhere), how far apart the points along a carried object's edges lie [m]
    (:attr:`CollisionCfg.found_spacing_m`), and per node each object's seat on a fixed
    support (:mod:`locoman.to.collisions.boxes`; empty: none anywhere)."""

    objects: tuple[ObjectModel, ...]
    object_q: np.ndarray  # (N, M, 6)
    obstacles: dict[str, Obstacle]
    frames: ContactFrames
    schedule: dict[str, np.ndarray] | None = None
    spacing_m: float = 0.04
    seats: tuple[tuple[Seat | None, ...], ...] = ()

    def boxes(self, k: int, j: int) -> list:
        """Object j's collision boxes at node k, as the TO has them there."""
        seat = self.seats[k][j] if self.seats else None
        return seated_boxes(object_boxes(self.objects[j]), seat)

    def holding_wrist(self, k: int, link: str, j: int) -> bool:
        """``link`` is a wrist link (:data:`WRIST_LINKS`) of a hand that holds object j at
        node k."""
        return self.schedule is not None and any(
            link in WRIST_LINKS[i] and int(self.schedule["hand_object"][k, i]) == j
            for i in range(2)
        )

    def allowed(self, k: int, close: ClosePair) -> bool:
        """The schedule lets ``close``'s bodies touch at node k."""
        return self.schedule is not None and allowed_at(
            self.schedule, k, close.a, close.b, self.names
        )

    @property
    def names(self) -> list[str]:
        return [obj.name for obj in self.objects]


def _object_side(
    k: int, j: int, other: Body, point: np.ndarray, scene: SolutionScene
) -> list[CollisionPair]:
    """Pairs keeping carried object j off ``other``: points along all its edges
    (``scene.spacing_m`` apart) against a fixed box or the floor (with the obstacle's
    edges against it; not the floor's, which lie far away); against another object, the
    points along the edges of j's box nearest the contact against that object's nearest
    box, and points along that box's vertical and top edges (spaced alike, or by j's
    smallest half size where less) against j's box, so that a platform's rim cannot cut
    into j's bottom, nor a tilted edge of j into a post, between two points."""
    obj = scene.objects[j]
    if other.kind in ("fixed", "floor"):
        obstacle = FLOOR_BOX if other.kind == "floor" else scene.obstacles[other.name]
        edges = other.kind == "fixed"
        return list(object_environment_pairs(k, j, obj, (obstacle,), KIND, scene.spacing_m, edges))
    if other.kind != "object":
        return []
    i = scene.names.index(other.name)
    own_boxes, their_boxes = scene.boxes(k, j), scene.boxes(k, i)
    a = _nearest_box(own_boxes, scene.object_q[k, j], point)
    b = _nearest_box(their_boxes, scene.object_q[k, i], point)
    (own_centre, own_half), (centre, half) = own_boxes[a], their_boxes[b]
    points = box_edge_points(own_centre, own_half, scene.spacing_m)
    rim = Obstacle("rim", centre, 0.0, half)
    spacing = min(scene.spacing_m, float(min(own_half)))
    edges = edge_points(rim, edge_point_counts(half, spacing))
    names = scene.names
    own = (f"{names[j]}/{a}/point", f" | {names[i]}/{b}")
    theirs = (f"{names[i]}/{b}/edge", f" | {names[j]}/{a}")
    return [
        *object_point_pairs(k, KIND, j, points, i, (centre, half), own),
        *object_point_pairs(k, KIND, i, edges, j, (own_centre, own_half), theirs),
    ]


def pairs_for(
    close: ClosePair, k: int, scene: SolutionScene, every_box: bool = False
) -> list[CollisionPair]:
    """The TO's pairs at node k that keep the two bodies of ``close`` apart (a holding
    hand's wrist and the object it holds: out of it, touching allowed); a robot link against
    an object: against its box nearest the contact, or with ``every_box`` each of them."""
    a, b = close.a, close.b
    if a.kind != ROBOT and b.kind == ROBOT:
        a, b = b, a
    if a.kind == ROBOT:
        spheres = robot_spheres(a.name, scene.frames)
        if b.kind == ROBOT:
            others = robot_spheres(b.name, scene.frames)
            return [
                CollisionPair(
                    k, KIND, "sphere_sphere", sphere=s, other=o, label=f"{s.name} | {o.name}"
                )
                for s in spheres
                for o in others
            ]
        if b.kind == "object":
            j = scene.names.index(b.name)
            boxes = scene.boxes(k, j)
            i = 0 if every_box else _nearest_box(boxes, scene.object_q[k, j], close.point)
            chosen = boxes if every_box else boxes[i : i + 1]
            touching = scene.holding_wrist(k, a.name, j)
            return list(
                sphere_box_pairs(k, KIND, spheres, chosen, j, b.name, touching=touching, first=i)
            )
        obstacle = FLOOR_BOX if b.kind == "floor" else scene.obstacles[b.name]
        return list(obstacle_pairs(k, KIND, spheres, obstacle))
    if a.kind != "object" and b.kind == "object":
        a, b = b, a
    if a.kind == "object":
        return _object_side(k, scene.names.index(a.name), b, close.point, scene)
    return []


def candidates(close: ClosePair, scene: SolutionScene, around: int = 1) -> list[CollisionPair]:
    """The pairs that keep ``close``'s bodies apart: at its node and ``around`` nodes either
    side (the next node too, for a pose between two, and that pose itself: a hand through a
    post between two nodes that both keep it out); never at node 0, which is given."""
    nodes = len(scene.object_q)
    last = close.node + around + (1 if close.fraction > 0.0 else 0)
    # Not where the schedule lets them touch (a box set down on the platform it grazed
    # while carried): there the pair would hold it off its support.
    out = [
        pair
        for k in range(max(close.node - around, 1), min(last, nodes - 1) + 1)
        if not scene.allowed(k, close)
        for pair in pairs_for(close, k, scene)
    ]
    k = close.node
    if close.fraction > 0.0 and not (scene.allowed(k, close) or scene.allowed(k + 1, close)):
        out += [
            dataclasses.replace(pair, fraction=close.fraction)
            for pair in pairs_for(close, k, scene)
        ]
    return out


@dataclasses.dataclass(frozen=True)
class Check:
    """One check of a solution: its close pairs, each with its :func:`candidates` in
    ``scene`` (``around`` nodes either side), made once. A round reads them up to three
    times (:func:`found_pairs`, :func:`promoted_pairs`, :func:`unmodelled`), and making
    them, thousands of pairs with their identities, was most of a check's time."""

    close: list[ClosePair]
    scene: SolutionScene
    around: int = 1

    @functools.cached_property
    def candidates(self) -> list[list[CollisionPair]]:
        return [candidates(c, self.scene, self.around) for c in self.close]

    @functools.cached_property
    def nodes(self) -> frozenset[int]:
        """The nodes of the candidates."""
        return frozenset(p.node for pairs in self.candidates for p in pairs)


def _known(existing: list[CollisionPair], nodes: frozenset[int] | set[int]) -> set[tuple]:
    """The identities of ``existing``'s pairs at ``nodes``. An identity starts with its
    node, so no other pair can be a candidate's; making one (the numbers rounded) for each
    of a problem's 100 000 pairs was most of a first check's mapping."""
    return {p.identity for p in existing if p.node in nodes}


def found_pairs(check: Check, existing: list[CollisionPair]) -> list[CollisionPair]:
    """The :func:`candidates` of each of ``check``'s close pairs that ``existing`` lacks,
    once each."""
    known = _known(existing, check.nodes)
    out = []
    for pairs in check.candidates:
        for pair in pairs:
            if pair.identity not in known:
                known.add(pair.identity)
                out.append(pair)
    return out


def _arm_against(close: ClosePair) -> Body | None:
    """The body not the robot that ``close`` has an arm's link (:data:`ARM_LINKS`)
    against; None for any other pair."""
    for robot, other in ((close.a, close.b), (close.b, close.a)):
        if robot.kind == ROBOT and other.kind != ROBOT:
            return other if any(robot.name in arm for arm in ARM_LINKS) else None
    return None


def arm_nodes(scene: SolutionScene, node: int, side: int, around: int) -> range:
    """The nodes at most ``around`` from ``node`` (never node 0) over which the hand of arm
    ``side`` keeps the contact it has at ``node`` (without a schedule: all of them)."""
    nodes = len(scene.object_q)
    first, last = max(node - around, 1), min(node + around, nodes - 1)
    if scene.schedule is None:
        return range(first, last + 1)
    held = scene.schedule["hand_object"][:, side]
    lo = hi = min(max(node, 1), nodes - 1)
    while lo > first and held[lo - 1] == held[hi]:
        lo -= 1
    while hi < last and held[hi + 1] == held[lo]:
        hi += 1
    return range(lo, hi + 1)


def arm_pairs(
    close: list[ClosePair], existing: list[CollisionPair], scene: SolutionScene, around: int
) -> list[CollisionPair]:
    """For each of ``close`` between an arm's link and a body not the robot: every link of
    both arms against every box of that body (:func:`pairs_for` with ``every_box``), each
    arm at the :func:`arm_nodes` of its hand around it, where the schedule does not let them
    touch; those ``existing`` lacks, once each. A restart's pairs (:func:`search`): the
    rounds' own cover the one link and box found, which moved the penetration to the next
    link, box or node, and widened to the one arm, to the other arm (S1's Foot+WarmStart,
    2.5 kg, 0.6 rad: the left elbow's whole arm kept out of the basket, the right palm ended
    65 mm in its right wall)."""
    known = _known(existing, {c.node + d for c in close for d in range(-around, around + 1)})
    done: set[tuple[str, Body, int]] = set()
    out = []
    for c in close:
        other = _arm_against(c)
        if other is None:
            continue
        other = dataclasses.replace(other, geom="")  # a body, whichever geom was close
        for side, arm in enumerate(ARM_LINKS):
            for k in arm_nodes(scene, c.node, side, around):
                for link in arm:
                    if (link, other, k) in done:
                        continue
                    done.add((link, other, k))
                    body = Body(ROBOT, link, link)
                    moved = ClosePair(k, 0.0, body, other, c.distance, c.point)
                    if scene.allowed(k, moved):
                        continue
                    for pair in pairs_for(moved, k, scene, every_box=True):
                        if pair.identity not in known:
                            known.add(pair.identity)
                            out.append(pair)
    return out


def unmodelled(check: Check, existing: list[CollisionPair]) -> list[ClosePair]:
    """Those of ``check``'s close pairs that ``existing`` lacks a :func:`candidates` pair of
    (each has :func:`found_pairs`), with ``existing``'s keys made once: per close pair they
    took minutes on a check with thousands of pairs."""
    known = _known(existing, check.nodes)
    return [
        c
        for c, pairs in zip(check.close, check.candidates, strict=True)
        if any(p.identity not in known for p in pairs)
    ]


def promoted_pairs(check: Check, existing: list[CollisionPair]) -> list[CollisionPair]:
    """The pairs that keep coming back: for each of ``check``'s close pairs that penetrates
    although the problem has its pairs already, those pairs again as ``PROMOTED`` (the hard
    (11) by default), once each, where ``existing`` does not have them so yet."""
    known = _known(existing, check.nodes)
    promoted = _known([p for p in existing if p.kind == PROMOTED], check.nodes)
    out = []
    for c, pairs in zip(check.close, check.candidates, strict=True):
        if c.distance >= 0.0:
            continue
        if any(p.identity not in known for p in pairs):
            continue  # not all modelled yet: found_pairs adds them first
        for pair in pairs:
            if pair.identity not in promoted:
                promoted.add(pair.identity)
                out.append(dataclasses.replace(pair, kind=PROMOTED))
    return out


def round_pairs(
    check: Check, existing: list[CollisionPair], cfg: CollisionCfg
) -> list[CollisionPair]:
    """What a check of a solution adds: the :func:`found_pairs` of its close pairs
    (``found``'s treatment) and, with ``found_hard`` on and not the same as ``found`` (the
    same pair again would be a duplicate row), the :func:`promoted_pairs`."""
    new = found_pairs(check, existing)
    if cfg.found_hard in ("off", cfg.found):
        return new
    return new + promoted_pairs(check, existing)
