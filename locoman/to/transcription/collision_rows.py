"""The collision pairs' calls (11)-(13): each pair under its kind's treatment, the
spheres between nodes, the calls kept from one round of found pairs to the next."""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from locoman.config.to import CollisionCfg, CostWeights
from locoman.to.collisions.pairs import CollisionPair
from locoman.to.collisions.spheres import SphereSet
from locoman.to.terms.collisions import collision_kind, homotopy_weight_kind
from locoman.to.terms.library import RobotTerms
from locoman.to.terms.term import Calls
from locoman.to.transcription.builder import BlockBuilder
from locoman.to.transcription.index import NodeIndex


@dataclasses.dataclass(frozen=True)
class PairCalls:
    """A transcription's collision pairs as calls, kept so that the next transcription
    whose pairs start with the same ones (a round's found pairs appended to them) adds
    only its new pairs' calls: S2 transcribes its 111 188 pairs once, not once a round.

    Attributes:
        pairs: The pairs, in order.
        context: What the calls depend on beyond the pairs: the nodes, the node layout's
            width, the spheres (their virtual slots), the collision settings and weights.
        stacked: Each (geometry, treatment, between) kind's calls, (x, p) stacked, in the
            order the kinds first came.
        between: The virtual sphere centres between nodes that the pairs asked for.
        n_y: The virtual variables after them.
        homotopy_nodes: The nodes with a homotopy pair (13b).
    """

    pairs: tuple[CollisionPair, ...]
    context: tuple
    stacked: dict[tuple[str, str, bool], tuple[np.ndarray, np.ndarray]]
    between: dict[tuple[int, float, str], np.ndarray]
    n_y: int
    homotopy_nodes: frozenset[int]

    def starts(self, pairs: list[CollisionPair], context: tuple) -> bool:
        """Whether ``pairs`` begin with these very pairs, in this context."""
        n = len(self.pairs)
        return (
            n <= len(pairs)
            and context == self.context
            and all(a is b for a, b in zip(self.pairs, pairs[:n], strict=True))
        )


def pair_robot_spheres(pair: CollisionPair) -> list[tuple[str, str]]:
    """The pair's x slots that are a robot sphere's centre, each with the pair's attribute
    holding that sphere."""
    if pair.geometry == "sphere_sphere":
        return [("a", "sphere"), ("b", "other")]
    return [] if pair.sphere is None else [("c", "sphere")]


def pair_rows(
    b, at: NodeIndex, pairs, cfg: CollisionCfg, w: CostWeights, context: tuple, reused
) -> PairCalls:
    """Every pair under its kind's treatment, after ``reused``'s (a :class:`PairCalls`
    of the first pairs, or None); (13b) at each node with a homotopy pair."""
    homotopy_nodes = set()
    # The calls of each (geometry, treatment, between) kind, in the order the kinds come.
    calls: dict[tuple[str, str, bool], Calls] = {}
    start = 0
    if reused is not None:
        for key, (x, p) in reused.stacked.items():
            calls[key] = b.own(collision_kind(*key))
            calls[key].start_with(x, p)
        at.between, at.n_y = dict(reused.between), reused.n_y
        homotopy_nodes |= reused.homotopy_nodes
        start = len(reused.pairs)
    # The new pairs by kind, in order. The sphere centres between two nodes are virtual
    # variables handed out as the pairs ask for them, so in the pairs' order.
    groups: dict[tuple[str, str, bool], list[CollisionPair]] = {}
    between: dict[tuple[str, str, bool], list[list[np.ndarray]]] = {}
    for pair in pairs[start:]:
        key = (pair.geometry, getattr(cfg, pair.kind), pair.fraction > 0.0)
        if key not in calls:
            calls[key] = b.own(collision_kind(*key))
        groups.setdefault(key, []).append(pair)
        if key[2]:
            centres = [
                at.sphere_between(pair.node, pair.fraction, getattr(pair, attr))
                for _, attr in pair_robot_spheres(pair)
            ]
            between.setdefault(key, []).append(centres)
    for key, group in groups.items():
        x, p = pair_columns(at, group, key, cfg, w, between.get(key))
        calls[key].add_columns(len(group), x, p)
        if key[1] == "homotopy":
            nodes = {pair.node for pair in group}
            homotopy_nodes |= nodes
            if key[2]:
                homotopy_nodes |= {k + 1 for k in nodes}
    stacked = {key: c.arrays() for key, c in calls.items()}
    for k in sorted(homotopy_nodes):
        b.own(homotopy_weight_kind()).add({"alpha": at.var(k, "alpha")}, {"weight": w.homotopy})
    return PairCalls(
        tuple(pairs), context, stacked, dict(at.between), at.n_y, frozenset(homotopy_nodes)
    )


def pair_columns(
    at: NodeIndex,
    group: list[CollisionPair],
    key: tuple[str, str, bool],
    cfg: CollisionCfg,
    w: CostWeights,
    centres: list[list[np.ndarray]] | None,
) -> tuple[dict, dict]:
    """The x and p slots of the pairs of one (geometry, treatment, between) kind, each
    slot's values for every pair at once: their objects' poses, their spheres' centres
    (``centres``: those handed out between nodes, per pair) and their numbers."""
    geometry, treatment, is_between = key
    first, n = group[0], len(group)
    k = np.fromiter((pair.node for pair in group), dtype=int, count=n)
    x: dict[str, np.ndarray] = {}
    for i, (slot, attr) in enumerate(pair_robot_spheres(first)):
        if is_between:
            x[slot] = np.array([c[i] for c in centres])
        else:
            x[slot] = at.spheres_at(k, [getattr(pair, attr) for pair in group])
    if first.box_obj is not None:
        objects = {"q_a": "obj", "q_o": "box_obj"}
    elif first.obj is not None:
        objects = {"q_o": "obj"}
    else:
        objects = {}
    # A pair between nodes takes its objects' poses and alpha at both.
    for node, suffix in [(k, ""), (k + 1, "_next")] if is_between else [(k, "")]:
        for slot, attr in objects.items():
            owners = [getattr(pair, attr) for pair in group]
            x[slot + suffix] = at.objects_at(node, owners, "q")
        if treatment == "homotopy":
            x["alpha" + suffix] = at.vars_at(node, "alpha")
    if geometry == "sphere_sphere":
        radii = [pair.sphere.radius + pair.other.radius + cfg.margin_m for pair in group]
        p = {"radius": radii, "length": np.full(n, cfg.length_m)}
    else:
        p = {name: [pair.numbers[name] for pair in group] for name in first.numbers}
        if first.sphere is not None:
            p["radius"] = [pair.sphere.radius for pair in group]
        touching_margin = math.log(3.0) * cfg.smoothing_m
        p["margin"] = [touching_margin if pair.touching else cfg.margin_m for pair in group]
        p |= {"smoothing": np.full(n, cfg.smoothing_m), "length": np.full(n, cfg.length_m)}
    if treatment == "penalty":
        p |= {"weight": np.full(n, w.collision), "softness": np.full(n, cfg.softness)}
    elif treatment == "homotopy":
        p["stand_in_margin"] = np.full(n, cfg.margin_m)
    if is_between:
        p["fraction"] = [pair.fraction for pair in group]
    return x, p


def between_rows(b: BlockBuilder, at: NodeIndex, robot: RobotTerms, spheres: SphereSet) -> None:
    """The sphere centres the pairs between two nodes asked for: virtual variables at the
    configuration linear in q along the step."""
    for (k, fraction, name), centres in at.between.items():
        q = {"q": at.var(k, "q"), "q_next": at.var(k + 1, "q"), "c": centres}
        if name in robot.link_spheres_between:
            b.calls(robot.link_spheres_between[name]).add(q, {"fraction": fraction})
            continue
        point = next(s for s in spheres.points if s.name == name)
        kind = robot.link_points_between[point.link]
        b.calls(kind).add(q, {"offset": point.offset, "fraction": fraction})
    for kind in [*robot.link_spheres_between.values(), *robot.link_points_between.values()]:
        b.define(kind)
