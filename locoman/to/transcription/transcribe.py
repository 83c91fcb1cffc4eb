"""Paper A's TO (Sec. IV) written as calls of compiled term kinds: which term acts at which
node, on which variables, with which numbers. Everything here is data; nothing compiles.

Over each step k -> k + 1 (nodes 0 .. N - 1, modes from :mod:`locoman.to.problem.modes`):

- the dynamics (1) of the robot and of every object simulated at k + 1, each body's step
  with gravity (:mod:`locoman.to.terms.dynamics`), to which every contact acting at node k
  adds its wrench: a foot's and a hand's on the robot, and, by (6), the opposite on the
  object the hand touches or the foot stands on; an object's support on it, and the
  opposite on the object that carries it;
- the contacts of node k + 1 (:mod:`locoman.to.terms.contacts`, :mod:`.supports`): each
  foot's patch (2), each hand's interactive contact (4), (5), each simulated object's
  support, at touchdown or held;
- the friction cones (3) and support rows of node k's wrenches.

At every node: the lifted kinematics and collision spheres, the costs of Table I by the
node's mode, L_reg, the slacks, (9), (10) and the objects' goals, and the collision pairs
(:func:`locoman.to.collisions.pairs.collision_pairs`), each kind under its treatment.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from locoman.to.collisions.pairs import CollisionPair, collision_pairs, used_spheres
from locoman.to.collisions.spheres import SphereSet
from locoman.to.problem.layout import (
    NodeLayout,
)
from locoman.to.problem.modes import NodeMode
from locoman.to.problem.numbers import Numbers
from locoman.to.terms.library import RobotTerms
from locoman.to.terms.term import Block, RowSpace
from locoman.to.transcription.builder import BlockBuilder
from locoman.to.transcription.collision_rows import PairCalls, between_rows, pair_rows
from locoman.to.transcription.index import NodeIndex
from locoman.to.transcription.objective import cost_rows
from locoman.to.transcription.physics import (
    contact_rows,
    dynamics_rows,
    kinematics_rows,
    wrench_rows,
)
from locoman.to.transcription.section import Section


@dataclasses.dataclass(frozen=True)
class Transcription:
    """The problem as data: its layout, lifted spheres, collision pairs, term calls and the
    constraint rows they own."""

    layout: NodeLayout
    nodes: int
    spheres: SphereSet
    pairs: tuple[CollisionPair, ...]
    blocks: tuple[Block, ...]
    rows: RowSpace
    n_y: int
    pair_calls: PairCalls | None = None

    @property
    def n_x(self) -> int:
        """The NLP's variables."""
        return self.nodes * self.layout.width

    def rows_of(self, term: str) -> np.ndarray:
        """(calls, ng) the rows the calls of ``term`` own (they may have others' shares)."""
        return np.concatenate([b.rows for b in self.blocks if b.term.name == term])

    def extended(self, x: np.ndarray) -> np.ndarray:
        """z = (x, y): ``x`` and the virtual variables its defining blocks give."""
        z = np.r_[np.asarray(x, dtype=float), np.zeros(self.n_y)]
        for block in self.blocks:
            if block.defines and block.calls:
                lifted = block.x[:, -block.term.ng :]
                g = block.term.function.map(block.calls)(z[block.x].T, block.p.T)[0]
                z[lifted] = -np.asarray(g.full()).T
        return z

    def values(self, x: np.ndarray) -> tuple[np.ndarray, dict[str, float]]:
        """Every constraint row at the NLP's point ``x``, and the cost by term, with the
        terms' own (uncompiled) functions: for checks and reports, not for solving."""
        g = np.zeros(self.rows.size)
        costs: dict[str, float] = {}
        x = self.extended(x)
        for block in self.blocks:
            if not block.calls or block.defines:
                continue
            out = block.term.function.map(block.calls)(x[block.x].T, block.p.T)
            gb, lb, rb = (np.asarray(v.full()) for v in out)
            np.add.at(g, block.rows.ravel(), gb.T.ravel())
            cost = float(lb.sum()) + float(np.square(rb).sum())
            costs[block.term.name] = costs.get(block.term.name, 0.0) + cost
        return g, costs


def transcribe(
    modes: list[NodeMode],
    P: np.ndarray,
    numbers: Numbers,
    robot: RobotTerms,
    pairs: list[CollisionPair] | None = None,
    previous: Transcription | None = None,
) -> Transcription:
    """The problem as term calls.

    Args:
        modes: The contact mode of every node.
        P: (n_params, N) the per-node numbers (:func:`locoman.to.problem.numbers.node_parameters`).
        numbers: Weights, contact and collision numbers, objects, obstacles.
        robot: The robot's own term kinds.
        pairs: The collision pairs; None: the configuration's
            (:func:`locoman.to.collisions.pairs.collision_pairs`).
        previous: An earlier transcription: where ``pairs`` begin with its pairs in the
            same context (:class:`PairCalls`), their calls are reused, not rebuilt. The
            result is the same either way.
    """
    if pairs is None:
        pairs = collision_pairs(modes, numbers, robot.frames)
    spheres = used_spheres(pairs)
    layout = NodeLayout.of(len(numbers.objects))
    n = len(modes)
    at = NodeIndex(layout, spheres, n)
    par = NodeLayout.of(len(numbers.objects)).parameters
    opar = NodeLayout.of(len(numbers.objects)).object_parameters
    b = BlockBuilder()
    kinematics_rows(b, at, robot, n)
    section = Section(b, at, modes, numbers, robot, P, par, opar)
    dynamics_rows(section)
    contact_rows(section)
    wrench_rows(section)
    cost_rows(section)
    names = tuple(s.name for s in spheres.spheres)
    context = (n, layout.width, names, numbers.collision, numbers.weights)
    reused = previous.pair_calls if previous is not None else None
    if reused is not None and not reused.starts(pairs, context):
        reused = None
    pair_calls = pair_rows(b, at, pairs, numbers.collision, numbers.weights, context, reused)
    between_rows(b, at, robot, spheres)
    blocks = b.close()
    return Transcription(
        layout, n, spheres, tuple(pairs), tuple(blocks), b.rows, at.n_y, pair_calls
    )
