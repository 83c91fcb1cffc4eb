"""The collision pairs a solution needs, found along it (paper A's minimal set is the start).

After a solve, the solution is replayed in the MuJoCo scene (:mod:`locoman.sim.audit`): every
pair of bodies closer than a margin that the contact schedule does not let touch is mapped
to the TO's own pairs that keep them apart (the robot link's spheres against the other
link's spheres, the object's box nearest the contact, the fixed object's box or the floor;
points along a carried object's edges against what it came close to), at the nodes around where it
happened. Those the problem does not have yet join it, under the ``found`` kind's
treatment, and the solve goes on from the previous primal-dual point. Since the terms are
compiled once per robot, a round costs a new assembly (seconds) and the warm-started solve.
"""

from __future__ import annotations

import dataclasses
import time

import mujoco
import numpy as np

from locoman.retarget.robot import ContactFrames
from locoman.scene import g1
from locoman.scene.rotations import rpy_to_matrix
from locoman.sim.audit import ROBOT, Body, ClosePair, allowed_at, close_pairs
from locoman.to.collision import (
    CollisionCfg,
    Obstacle,
    box_edge_points,
    edge_point_counts,
    edge_points,
)
from locoman.to.collision_pairs import (
    CollisionPair,
    object_boxes,
    object_environment_pairs,
    object_point_pairs,
    obstacle_pairs,
    sphere_box_pairs,
)
from locoman.to.layout import ObjectModel
from locoman.to.optimizer import Trajectory, TrajectoryOptimizer
from locoman.to.seats import Seat, seated_boxes
from locoman.to.spheres import RobotSphere, foot_spheres, link_sphere_list

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
ARM_LINKS = tuple(
    tuple(
        f"{side}_{link}"
        for link in (
            "shoulder_pitch_link",
            "shoulder_roll_link",
            "shoulder_yaw_link",
            "elbow_link",
            "wrist_roll_link",
            "wrist_pitch_link",
            "wrist_yaw_link",
            "rubber_hand",
        )
    )
    for side in ("left", "right")
)
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
class Scene:
    """What the search maps MuJoCo's bodies to: the TO's objects (in its order) with their
    poses along the solution, the fixed objects' boxes, the robot's frames, and the
    solution's contact schedule (:func:`trajectory_arrays`; None: touching allowed
    nowhere), how far apart the points along a carried object's edges lie [m]
    (:attr:`CollisionCfg.found_spacing_m`), and per node each object's seat on a fixed
    support (:mod:`locoman.to.seats`; empty: none anywhere)."""

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
    k: int, j: int, other: Body, point: np.ndarray, scene: Scene
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
    close: ClosePair, k: int, scene: Scene, every_box: bool = False
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


def candidates(close: ClosePair, scene: Scene, around: int = 1) -> list[CollisionPair]:
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


def found_pairs(
    close: list[ClosePair], existing: list[CollisionPair], scene: Scene, around: int = 1
) -> list[CollisionPair]:
    """The :func:`candidates` of each of ``close`` that ``existing`` lacks, once each."""
    known = {p.identity for p in existing}
    out = []
    for c in close:
        for pair in candidates(c, scene, around):
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


def arm_nodes(scene: Scene, node: int, side: int, around: int) -> range:
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
    close: list[ClosePair], existing: list[CollisionPair], scene: Scene, around: int
) -> list[CollisionPair]:
    """For each of ``close`` between an arm's link and a body not the robot: every link of
    both arms against every box of that body (:func:`pairs_for` with ``every_box``), each
    arm at the :func:`arm_nodes` of its hand around it, where the schedule does not let them
    touch; those ``existing`` lacks, once each. A restart's pairs (:func:`search`): the
    rounds' own cover the one link and box found, which moved the penetration to the next
    link, box or node, and widened to the one arm, to the other arm (S1's Foot+WarmStart,
    2.5 kg, 0.6 rad: the left elbow's whole arm kept out of the basket, the right palm ended
    65 mm in its right wall)."""
    known = {p.identity for p in existing}
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


def unmodelled(
    close: list[ClosePair], existing: list[CollisionPair], scene: Scene
) -> list[ClosePair]:
    """Those of ``close`` that ``existing`` lacks a :func:`candidates` pair of (each has
    :func:`found_pairs`), with ``existing``'s keys made once: per close pair they took
    minutes on a check with thousands of pairs."""
    known = {p.identity for p in existing}
    return [c for c in close if any(p.identity not in known for p in candidates(c, scene))]


def promoted_pairs(
    close: list[ClosePair], existing: list[CollisionPair], scene: Scene, around: int = 1
) -> list[CollisionPair]:
    """The pairs that keep coming back: for each of ``close`` that penetrates although the
    problem has its pairs already, those pairs again as ``PROMOTED`` (the hard (11) by
    default), once each, where ``existing`` does not have them so yet."""
    promoted = {p.identity for p in existing if p.kind == PROMOTED}
    known = {p.identity for p in existing}
    out = []
    for c in close:
        if c.distance >= 0.0:
            continue
        pairs = candidates(c, scene, around)
        if any(p.identity not in known for p in pairs):
            continue  # not all modelled yet: found_pairs adds them first
        for pair in pairs:
            if pair.identity not in promoted:
                promoted.add(pair.identity)
                out.append(dataclasses.replace(pair, kind=PROMOTED))
    return out


def round_pairs(
    close: list[ClosePair], existing: list[CollisionPair], scene: Scene, cfg: CollisionCfg
) -> list[CollisionPair]:
    """What a check of a solution adds: the :func:`found_pairs` of ``close`` (``found``'s
    treatment) and, with ``found_hard`` on and not the same as ``found`` (the same pair
    again would be a duplicate row), the :func:`promoted_pairs`."""
    new = found_pairs(close, existing, scene)
    if cfg.found_hard in ("off", cfg.found):
        return new
    return new + promoted_pairs(close, existing, scene)


def trajectory_arrays(traj: Trajectory, names: list[str]) -> dict[str, np.ndarray]:
    """What :func:`locoman.sim.audit.close_pairs` reads of a trajectory."""
    fields = (
        "q",
        "object_q",
        "foot_object",
        "feet_contact",
        "hand_object",
        "support_kind",
        "support_base",
    )
    return {f: getattr(traj, f) for f in fields} | {
        "object_active": traj.object_active,
        "object_names": np.array(names),
    }


@dataclasses.dataclass(frozen=True)
class Round:
    """One check of a solution, and the solve it led to.

    Attributes:
        close_pairs: Pairs closer than the margin the schedule does not allow.
        deepest_m: The least distance among them [m] (negative: inside).
        pairs_added: Pairs the problem lacked that join it.
        iterations, solve_time_s, status: Of the warm-started solve with them (0, 0, "":
            none, after the last check).
        deepest_pair: The geoms of the closest pair (``a | b``; "" with none).
        demoted: Pairs promoted to (11) in this round whose solve ended infeasible, left out of the
            second attempt (:func:`search`).
        restart: No check: the solve started again from the guess with every pair found
            (the rounds before had left pairs missing or unfreed).
    """

    close_pairs: int
    deepest_m: float
    pairs_added: int
    iterations: int = 0
    solve_time_s: float = 0.0
    status: str = ""
    deepest_pair: str = ""
    demoted: int = 0
    restart: bool = False


# IPOPT's statuses for "no feasible point here": a round ending so with promotions is
# solved again without them (:func:`search`).
INFEASIBLE = ("Infeasible_Problem_Detected", "Restoration_Failed")


def search(
    optimizer: TrajectoryOptimizer,
    traj: Trajectory,
    model: mujoco.MjModel,
    scene: Scene,
    cfg: CollisionCfg,
) -> tuple[Trajectory, list[Round], list[ClosePair], list[ClosePair]]:
    """Check ``traj``, add the pairs it needs and solve on from it, at most ``cfg.rounds``
    times (:func:`_rounds`); if pairs are left missing or unfreed, solve again from Sec.
    IV-C.2's guess with every pair found so far and go on with the rounds from there, at
    most ``cfg.restarts`` times. Returns the last trajectory (its iterations and solve time
    those of every solve), the rounds, the close pairs the problem still lacks pairs for
    after the last check (empty: the solution needs none it lacks) and those still deeper
    than ``cfg.unfreed_m``, modelled or not; with ``found`` off, no rounds or a failed
    ``traj``: ``traj``.

    Why start again: pairs that join a solution already through an object can hold it in
    a local minimum that they cannot free. S1 without the keyframes' warm start: the first
    solve, without the wrist's pairs against the basket, reaches under the basket's floor;
    once found, the floor's pair pushes the wrist down into the shelf and the shelf's pair
    pushes it up (three rounds, 30 mm deep at the end). Present from the first iteration,
    the same pairs kept the reach out in three of the six S1 Fig. 6 cells that ended so
    (docs/figures.md). A failed solve ends the search with that failure: its point is no
    motion to check.
    """
    pairs = list(optimizer.transcription.pairs)
    rounds: list[Round] = []
    totals = _Totals(traj)
    if cfg.found == "off" or cfg.rounds == 0 or not traj.success:
        return traj, rounds, [], []  # a failed solve is no solution to check
    promote, restarts, seen = cfg.found_hard, 0, []
    while True:
        traj, remaining, unfreed, promote = _rounds(
            optimizer, traj, model, scene, cfg, pairs, rounds, totals, promote, seen
        )
        if not (remaining or unfreed) or not traj.success or restarts == cfg.restarts:
            return totals.of(traj), rounds, remaining, unfreed
        restarts += 1
        arms = []
        if cfg.restart_arm_nodes > 0:
            arms = arm_pairs(seen, pairs, _checked(scene, traj, cfg), cfg.restart_arm_nodes)
            pairs.extend(arms)
        print(
            f"[solve] restart {restarts}: {len(remaining)} pairs missing, {len(unfreed)} "
            f"unfreed; solving again from the guess with the {len(pairs)} pairs"
            + (f" ({len(arms)} of them the found arms' whole)" if arms else ""),
            flush=True,
        )
        tic = time.perf_counter()
        traj = optimizer.solve(pairs=pairs)
        seconds = time.perf_counter() - tic
        solved = _round([], None, arms, traj, seconds, traj.iterations)
        rounds.append(dataclasses.replace(solved, restart=True))
        totals.add(traj)
        if not traj.success:
            return totals.of(traj), rounds, [], []


def _rounds(
    optimizer: TrajectoryOptimizer,
    traj: Trajectory,
    model: mujoco.MjModel,
    scene: Scene,
    cfg: CollisionCfg,
    pairs: list[CollisionPair],
    rounds: list[Round],
    totals: _Totals,
    promote: str,
    seen: list[ClosePair],
) -> tuple[Trajectory, list[ClosePair], list[ClosePair], str]:
    """At most ``cfg.rounds`` rounds from ``traj`` (a successful solve): check it, add the
    pairs it needs to ``pairs`` and solve on from its primal-dual point. Appends to
    ``rounds`` and ``totals``, and each check's close pairs to ``seen``. Returns the last
    trajectory, the close pairs still unmodelled and those deeper than ``cfg.unfreed_m`` at
    its check, and whether a later round may still promote (``promote``:
    ``cfg.found_hard`` or ``off``).

    A round whose solve ends infeasible (:data:`INFEASIBLE`) with pairs promoted to (11) is
    solved again without the promotions (their pairs keep the penalty (12) they joined
    with), and no later round promotes: (11) on a pair that keeps coming back can leave no
    feasible point near the previous optimum (S1: an elbow held out of the shelf while the
    hand holds the basket). Another failure is not retried: a solve that ran out of
    iterations would likely run out again (S2: 2 x 1000 iterations, 45 min).
    """
    after = 0
    while True:
        scene = _checked(scene, traj, cfg)
        close = close_pairs(model, scene.schedule, cfg.audit_margin_m, cfg.audit_substeps)
        seen.extend(close)
        deepest = min(close, key=lambda c: c.distance, default=None)
        new = round_pairs(close, pairs, scene, dataclasses.replace(cfg, found_hard=promote))
        if not new or after == cfg.rounds:
            rounds.append(_round(close, deepest, []))
            unfreed = [c for c in close if c.distance < -cfg.unfreed_m]
            return traj, unmodelled(close, pairs, scene), unfreed, promote
        after += 1
        print(
            f"[solve] round {after}: {len(close)} close pairs (deepest {_mm(deepest)}), "
            f"{len(new)} pairs added; solving on",
            flush=True,
        )
        tic = time.perf_counter()
        # From an optimum, the exact Hessian converges in a few iterations where the
        # Gauss-Newton one, cycling near the penalties' optimum, used all 150 of its own.
        solved = optimizer.solve(pairs=pairs + new, warm_start=traj, hessian="exact")
        iterations, promoted = solved.iterations, [p for p in new if p.kind == PROMOTED]
        demoted = len(promoted) if solved.status in INFEASIBLE else 0
        if demoted:
            print(
                f"[solve] round {after} ended {solved.status} with {demoted} pairs "
                "promoted to (11); solving it again without them, and promoting none from here",
                flush=True,
            )
            totals.add(solved)
            promote = "off"
            new = [p for p in new if p.kind != PROMOTED]
            solved = optimizer.solve(pairs=pairs + new, warm_start=traj, hessian="exact")
            iterations += solved.iterations
        pairs.extend(new)
        seconds = time.perf_counter() - tic
        rounds.append(_round(close, deepest, new, solved, seconds, iterations, demoted))
        totals.add(solved)
        traj = solved
        if not traj.success:
            return traj, [], [], promote


def _checked(scene: Scene, traj: Trajectory, cfg: CollisionCfg) -> Scene:
    """``scene`` along ``traj``: its objects' poses and its contact schedule."""
    arrays = trajectory_arrays(traj, scene.names)
    return dataclasses.replace(
        scene, object_q=traj.object_q, schedule=arrays, spacing_m=cfg.found_spacing_m
    )


def _mm(pair: ClosePair | None) -> str:
    return "none" if pair is None else f"{pair.distance * 1000:.1f} mm, {pair.label}"


def _round(
    close: list[ClosePair],
    deepest: ClosePair | None,
    new: list[CollisionPair],
    traj: Trajectory | None = None,
    seconds: float = 0.0,
    iterations: int = 0,
    demoted: int = 0,
) -> Round:
    """The record of one check (and of the solve it led to, if ``traj``: ``iterations``
    and ``seconds`` of its one or two attempts)."""
    solved = (
        {}
        if traj is None
        else {
            "iterations": iterations,
            "solve_time_s": seconds,
            "status": traj.status,
            "demoted": demoted,
        }
    )
    return Round(
        len(close),
        0.0 if deepest is None else deepest.distance,
        len(new),
        deepest_pair="" if deepest is None else deepest.label,
        **solved,
    )


class _Totals:
    """A solve's counts summed over its IPOPT calls (the first phase, the rounds)."""

    def __init__(self, first: Trajectory) -> None:
        self.iterations, self.exact_iterations = first.iterations, first.exact_iterations
        self.solve_time_s, self.function_time_s = first.solve_time_s, first.function_time_s

    def add(self, traj: Trajectory) -> None:
        self.iterations += traj.iterations
        self.exact_iterations += traj.exact_iterations
        self.solve_time_s += traj.solve_time_s
        self.function_time_s += traj.function_time_s

    def of(self, traj: Trajectory) -> Trajectory:
        return dataclasses.replace(
            traj,
            iterations=self.iterations,
            exact_iterations=self.exact_iterations,
            solve_time_s=self.solve_time_s,
            function_time_s=self.function_time_s,
        )
