"""Penetration per node by class, each geom pair once (paper A, Sec. V-B and Fig. 5).

Paper A counts "self-collisions and robot-object collisions", the total penetration at each
node. MuJoCo reports a box lying 100 mm inside a table as four contact points, and a robot
sole on the floor as contacts too; summing every contact's depth would count both. Here each
penetrating geom pair counts once per node, at its deepest contact, in one class:

- ``self``: two of the robot's links (pairs MuJoCo excludes, adjacent links, never appear);
- ``robot_object``: a robot link against a movable object, but a scheduled contact;
- ``robot_environment``: a robot link against fixed furniture, or against the floor where
  it is not a sole standing on it;
- ``scheduled_contact``: a foot on what it stands on while it stands (the floor or an
  object), a hand on the object it holds while it holds it;
- ``object_environment``: an object against furniture, the floor or another object.

Paper A's headline (:data:`HEADLINE`) is ``self`` + ``robot_object`` + ``robot_environment``.
"""

from __future__ import annotations

import dataclasses

import mujoco
import numpy as np

from locoman.sim.audit import Body, body_of, scheduled
from locoman.sim.evaluate import ROBOT, scene_qpos

# Shallower than this is touching, not penetrating [m]: MuJoCo reports a sole standing on
# the floor at -1e-9 m and a box on a table at -1e-17 m.
RESOLUTION_M = 1e-6
CLASSES = ("self", "robot_object", "robot_environment", "scheduled_contact", "object_environment")
HEADLINE = ("self", "robot_object", "robot_environment")  # paper A's penetration


def classify(traj: dict[str, np.ndarray], k: int, a: Body, b: Body, names: list[str]) -> str:
    """The class (:data:`CLASSES`) of a penetrating pair ``a``, ``b`` at node k."""
    if a.kind != ROBOT:
        a, b = b, a
    if a.kind != ROBOT:
        return "object_environment"
    if b.kind == ROBOT:
        return "self"
    if scheduled(traj, k, a, b, names):
        return "scheduled_contact"
    return "robot_object" if b.kind == "object" else "robot_environment"


@dataclasses.dataclass(frozen=True)
class PairDepth:
    """One geom pair inside each other at one node.

    Attributes:
        node: The node.
        kind: Its class (:data:`CLASSES`).
        geoms: The two geoms' names, sorted.
        depth_m: The deepest of its contacts [m] (> 0).
    """

    node: int
    kind: str
    geoms: tuple[str, str]
    depth_m: float


def pair_depths(
    model: mujoco.MjModel, data: mujoco.MjData, traj: dict, k: int, names: list[str]
) -> list[PairDepth]:
    """Every geom pair of ``data`` (after ``mj_forward``) deeper than :data:`RESOLUTION_M`
    inside each other once, at its deepest contact, classified with node k's schedule."""
    deepest: dict[tuple[str, str], PairDepth] = {}
    for c in data.contact[: data.ncon]:
        if c.dist >= -RESOLUTION_M:
            continue
        a, b = body_of(model, c.geom1, names), body_of(model, c.geom2, names)
        geoms = tuple(sorted((a.geom, b.geom)))
        if geoms not in deepest or -c.dist > deepest[geoms].depth_m:
            deepest[geoms] = PairDepth(k, classify(traj, k, a, b, names), geoms, -float(c.dist))
    return list(deepest.values())


@dataclasses.dataclass(frozen=True)
class Penetrations:
    """Penetration along a trajectory of N nodes.

    Attributes:
        pairs: Every penetrating geom pair at every node, once per node.
        contact_sum: (N,) the sum of every contact's depth at each node, all classes [m]
            (a pair with four contact points counts four times: kept to compare).
    """

    pairs: tuple[PairDepth, ...]
    contact_sum: np.ndarray

    def per_node(self, kinds: tuple[str, ...]) -> np.ndarray:
        """(N,) the sum of the depths of the pairs of ``kinds`` at each node [m]."""
        out = np.zeros(len(self.contact_sum))
        for pair in self.pairs:
            if pair.kind in kinds:
                out[pair.node] += pair.depth_m
        return out

    def deepest(self, kinds: tuple[str, ...], node: int | None = None) -> PairDepth | None:
        """The deepest pair of ``kinds`` (at ``node``, or anywhere), None if there is none."""
        found = [p for p in self.pairs if p.kind in kinds and node in (None, p.node)]
        return max(found, key=lambda p: p.depth_m, default=None)

    def deepest_depth(self, kinds: tuple[str, ...]) -> float:
        """The depth of the deepest pair of ``kinds`` anywhere, 0 if none [m]: each contact
        on its own, where :meth:`per_node` sums the pairs of a node."""
        pair = self.deepest(kinds)
        return 0.0 if pair is None else pair.depth_m

    def by_class(self) -> dict[str, dict]:
        """Per class: ``max_m`` and ``avg_m`` over the nodes of its per-node sum [m], its
        ``deepest_pair`` (geoms, node, depth) and ``nodes_penetrating``."""
        out = {}
        for kind in CLASSES:
            values, pair = self.per_node((kind,)), self.deepest((kind,))
            out[kind] = {
                "max_m": float(values.max()),
                "avg_m": float(values.mean()),
                "deepest_pair": None
                if pair is None
                else {"geoms": list(pair.geoms), "node": pair.node, "depth_m": pair.depth_m},
                "nodes_penetrating": int(np.count_nonzero(values)),
            }
        return out


def penetrations(model: mujoco.MjModel, traj: dict[str, np.ndarray]) -> Penetrations:
    """Replay ``traj`` kinematically at its nodes and classify every penetrating pair."""
    names = [str(n) for n in traj["object_names"]]
    data = mujoco.MjData(model)
    pairs, contact_sum = [], []
    for k, (qk, object_qk) in enumerate(zip(traj["q"], traj["object_q"], strict=True)):
        data.qpos[:] = scene_qpos(model, qk, names, object_qk)
        mujoco.mj_forward(model, data)
        contact_sum.append(-sum(min(c.dist, 0.0) for c in data.contact[: data.ncon]))
        pairs += pair_depths(model, data, traj, k, names)
    return Penetrations(tuple(pairs), np.array(contact_sum))
