"""Paper A's TO (Sec. IV) written as calls of compiled term kinds: which term acts at which
node, on which variables, with which numbers. Everything here is data; nothing compiles.

Over each step k -> k + 1 (nodes 0 .. N - 1, modes from :mod:`locoman.to.modes`):

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
(:func:`locoman.to.collision_pairs.collision_pairs`), each kind under its treatment.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from locoman.config.to import ContactCfg
from locoman.errors import ConfigError
from locoman.retarget.robot import ContactFrames
from locoman.to.assembly import Block, RowSpace
from locoman.to.collision import (
    CollisionCfg,
    Obstacle,
)
from locoman.to.collision_pairs import (
    CollisionPair,
    collision_pairs,
    prehensile,
    used_spheres,
)
from locoman.to.costs import CostWeights
from locoman.to.layout import (
    FEET,
    HANDS,
    KINEMATICS,
    N_KIN,
    ORIENTATION,
    POSITION,
    NodeLayout,
    ObjectModel,
    limb,
)
from locoman.to.modes import NodeMode
from locoman.to.spheres import (
    RobotSphere,
    SphereSet,
    link_sphere_list,
)
from locoman.to.terms import Calls, TermKind
from locoman.to.terms.collisions import collision_kind, homotopy_weight_kind
from locoman.to.terms.contacts import (
    foot_cone_kind,
    foot_patch_kind,
    hand_contact_kind,
    object_face_cone_kind,
    sole_depth_kind,
)
from locoman.to.terms.costs import (
    REGULARIZATION_WEIGHTS,
    STANCE_WEIGHTS,
    WALKING_WEIGHTS,
    keyframe_base_kind,
    keyframe_foot_kind,
    object_pose_kind,
    regularization_kind,
    squared_kind,
    stance_kind,
    walking_kind,
    weight_values,
)
from locoman.to.terms.dynamics import (
    object_step_kind,
    robot_step_kind,
    same_object_wrench_kind,
    wrench_kind,
)
from locoman.to.terms.supports import (
    object_numbers,
    support_contact_kind,
    support_wrench_kind,
)


@dataclasses.dataclass(frozen=True)
class RobotTerms:
    """The robot-specific term kinds: its kinematics, its links' capsule spheres and points
    fixed to its links."""

    kinematics: TermKind
    link_spheres: dict[str, TermKind]
    link_points: dict[str, TermKind]
    link_spheres_between: dict[str, TermKind]
    link_points_between: dict[str, TermKind]
    mass: float  # [kg]
    frames: ContactFrames


@dataclasses.dataclass(frozen=True)
class Numbers:
    """The numbers of a problem that a sweep changes without changing which terms exist:
    cost weights, contact numbers, collision numbers, the objects' masses, sizes and
    frictions, the obstacles' boxes."""

    weights: CostWeights
    contact: ContactCfg
    collision: CollisionCfg
    objects: tuple[ObjectModel, ...]
    obstacles: tuple[Obstacle, ...]


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


class _Index:
    """Indices into the NLP's x (node-major blocks of ``layout.width``), then into its
    virtual variables (node-major blocks: the kinematics, the sphere centres)."""

    def __init__(self, layout: NodeLayout, spheres: SphereSet, nodes: int) -> None:
        self.layout, self.spheres, self.width, self.nodes = layout, spheres, layout.width, nodes
        self.n_x = nodes * layout.width
        self.virtual_width = N_KIN + 3 * len(spheres)
        # Sphere centres between two nodes: (node, fraction, link or point name) -> their
        # virtual indices, after every node's, handed out as the pairs ask for them.
        self.between: dict[tuple[int, float, str], np.ndarray] = {}
        self.n_y = nodes * self.virtual_width
        # A sphere's entries in a node's virtual block: the pairs ask for them by the
        # hundred thousand.
        self._sphere_slots: dict[str, np.ndarray] = {}

    def var(self, k: int, name: str) -> np.ndarray:
        return self._at(k, self.layout.variables[name])

    def limb(self, k: int, name: str, i: int) -> np.ndarray:
        """Limb i's share of a per-limb variable (``foot_wrench``, ``hand_slack``, ...)."""
        return self._at(k, limb(self.layout.variables[name], i))

    def _at(self, k: int, s: slice) -> np.ndarray:
        return k * self.width + np.arange(s.start, s.stop)

    def virtual(self, k: int) -> int:
        """Node k's first virtual variable."""
        return self.n_x + k * self.virtual_width

    def kinematics(self, k: int) -> np.ndarray:
        return self.virtual(k) + np.arange(N_KIN)

    def kin(self, k: int, name: str) -> np.ndarray:
        s = KINEMATICS[name]
        return self.virtual(k) + np.arange(s.start, s.stop)

    def obj(self, k: int, j: int, quantity: str) -> np.ndarray:
        return self._at(k, self.layout.object_variables(j, quantity))

    def foot(self, k: int, i: int, quantity: str) -> np.ndarray:
        return self.kin(k, f"{FEET[i]}_{quantity}")

    def hand(self, k: int, i: int, quantity: str) -> np.ndarray:
        return self.kin(k, f"{HANDS[i]}_{quantity}")

    def sphere(self, k: int, sphere: RobotSphere) -> np.ndarray:
        return self.virtual(k) + self._slots(sphere)

    def _slots(self, sphere: RobotSphere) -> np.ndarray:
        slots = self._sphere_slots.get(sphere.name)
        if slots is None:
            slots = self._sphere_slots[sphere.name] = N_KIN + self.spheres.slots(sphere)
        return slots

    # The same, for many nodes at once: (n,) nodes -> (n, size) indices.

    def vars_at(self, k: np.ndarray, name: str) -> np.ndarray:
        s = self.layout.variables[name]
        return k[:, None] * self.width + np.arange(s.start, s.stop)

    def objects_at(self, k: np.ndarray, objects: list[int], quantity: str) -> np.ndarray:
        """Object ``objects[i]``'s ``quantity`` at node ``k[i]``."""
        owners = np.asarray(objects, dtype=int)
        slices = {j: self.layout.object_variables(j, quantity) for j in set(objects)}
        size = {s.stop - s.start for s in slices.values()}.pop()
        starts = np.zeros(max(slices) + 1, dtype=int)
        for j, s in slices.items():
            starts[j] = s.start
        return k[:, None] * self.width + starts[owners][:, None] + np.arange(size)

    def spheres_at(self, k: np.ndarray, spheres: list[RobotSphere]) -> np.ndarray:
        """The centre of ``spheres[i]`` at node ``k[i]``."""
        slots = np.array([self._slots(sphere) for sphere in spheres]).reshape(len(k), 3)
        return self.n_x + k[:, None] * self.virtual_width + slots

    def link_spheres(self, k: int, link: str) -> np.ndarray:
        return self.virtual(k) + N_KIN + self.spheres.link_slots(link)

    def sphere_between(self, k: int, fraction: float, sphere: RobotSphere) -> np.ndarray:
        """(3,) the virtual centre of ``sphere`` at the configuration ``fraction`` along
        the step from node k (a capsule's link's spheres come together)."""
        if sphere.index is None:
            key = (k, fraction, sphere.name)
            count = 1
        else:
            key = (k, fraction, sphere.link)
            count = len(link_sphere_list(sphere.link))
        if key not in self.between:
            self.between[key] = self.n_x + self.n_y + np.arange(3 * count)
            self.n_y += 3 * count
        start = 0 if sphere.index is None else 3 * sphere.index
        return self.between[key][start : start + 3]


# --- the blocks -------------------------------------------------------------------------------


class _Builder:
    """Collects the calls of every kind, then hands out their blocks."""

    def __init__(self) -> None:
        self.rows = RowSpace()
        self.blocks: list[Block] = []
        self._calls: dict[str, Calls] = {}
        self._targets: dict[str, list[np.ndarray]] = {}

    def calls(self, kind: TermKind) -> Calls:
        return self._calls.setdefault(kind.name, Calls(kind))

    def own(self, kind: TermKind) -> Calls:
        """Calls whose rows are their own (flushed by :meth:`close`)."""
        return self.calls(kind)

    def onto(self, kind: TermKind, x: dict, p: dict, target: np.ndarray) -> None:
        """A call whose rows add to existing ``target`` rows."""
        key = f"onto:{kind.name}"
        calls = self._calls.setdefault(key, Calls(kind))
        calls.add(x, p)
        self._targets.setdefault(key, []).append(np.asarray(target))

    def define(self, kind: TermKind) -> None:
        """The calls of ``kind`` so far define virtual variables (:attr:`Block.defines`)."""
        calls = self._calls.pop(kind.name, None)
        if calls is not None and len(calls):
            x, p = calls.arrays()
            self.blocks.append(Block(kind.term, x, p, np.zeros((len(x), 0), int), defines=True))

    def flush_owned(self, kind: TermKind) -> np.ndarray:
        """The rows of the calls of ``kind`` so far, as one block (n, ng); the kind's calls
        start afresh."""
        calls = self._calls.pop(kind.name)
        block = calls.own(self.rows)
        self.blocks.append(block)
        return block.rows

    def close(self) -> list[Block]:
        for key, calls in self._calls.items():
            if not len(calls):
                continue
            if key.startswith("onto:"):
                self.blocks.append(calls.onto(self._targets[key]))
            elif calls.kind.term.ng:
                self.blocks.append(calls.own(self.rows))
            else:
                self.blocks.append(calls.costs())
        self._calls.clear()
        return self.blocks


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
        P: (n_params, N) the per-node numbers (:func:`locoman.to.node_parameters.node_parameters`).
        numbers: Weights, contact and collision numbers, objects, obstacles.
        robot: The robot's own term kinds.
        pairs: The collision pairs; None: the configuration's
            (:func:`locoman.to.collision_pairs.collision_pairs`).
        previous: An earlier transcription: where ``pairs`` begin with its pairs in the
            same context (:class:`PairCalls`), their calls are reused, not rebuilt. The
            result is the same either way.
    """
    if pairs is None:
        pairs = collision_pairs(modes, numbers, robot.frames)
    spheres = used_spheres(pairs)
    layout = NodeLayout.of(len(numbers.objects))
    n = len(modes)
    at = _Index(layout, spheres, n)
    par = NodeLayout.of(len(numbers.objects)).parameters
    opar = NodeLayout.of(len(numbers.objects)).object_parameters
    b = _Builder()
    _kinematics(b, at, robot, n)
    _dynamics(b, at, modes, numbers, robot, P, par)
    _contacts(b, at, modes, numbers, robot, P, par, opar)
    _wrench_rows(b, at, modes, numbers, robot, P, par)
    _costs(b, at, modes, numbers, robot, P, par, opar)
    names = tuple(s.name for s in spheres.spheres)
    context = (n, layout.width, names, numbers.collision, numbers.weights)
    reused = previous.pair_calls if previous is not None else None
    if reused is not None and not reused.starts(pairs, context):
        reused = None
    pair_calls = _collisions(b, at, pairs, numbers.collision, numbers.weights, context, reused)
    _between(b, at, robot, spheres)
    blocks = b.close()
    return Transcription(
        layout, n, spheres, tuple(pairs), tuple(blocks), b.rows, at.n_y, pair_calls
    )


def _kinematics(b: _Builder, at: _Index, robot: RobotTerms, n: int) -> None:
    """The kinematics and the sphere centres at every node: virtual variables."""
    calls = b.calls(robot.kinematics)
    for k in range(n):
        calls.add({"q": at.var(k, "q"), "v": at.var(k, "v"), "kin": at.kinematics(k)})
    b.define(robot.kinematics)
    for link in at.spheres.links:
        calls = b.calls(robot.link_spheres[link])
        for k in range(n):
            calls.add({"q": at.var(k, "q"), "c": at.link_spheres(k, link)})
        b.define(robot.link_spheres[link])
    for point in at.spheres.points:
        calls = b.calls(robot.link_points[point.link])
        for k in range(n):
            calls.add({"q": at.var(k, "q"), "c": at.sphere(k, point)}, {"offset": point.offset})
    for kind in {id(k): k for k in robot.link_points.values()}.values():
        b.define(kind)


def _dynamics(b, at: _Index, modes, numbers: Numbers, robot: RobotTerms, P, par) -> None:
    """(1) of the robot and of each object simulated at k + 1, with the wrenches of node
    k's contacts, over every step."""
    objects = numbers.objects
    robot_step, object_step = robot_step_kind(), object_step_kind()
    steps = b.own(robot_step)
    object_steps = b.own(object_step)
    which: list[tuple[int, int]] = []
    for k in range(len(modes) - 1):
        steps.add(
            {
                "h": at.kin(k, "h"),
                "h1": at.kin(k + 1, "h"),
                "q": at.var(k, "q"),
                "q1": at.var(k + 1, "q"),
                "v1": at.var(k + 1, "v"),
                "dt": at.var(k, "dt"),
            },
            {"mass": robot.mass},
        )
        for j, obj in enumerate(objects):
            if not modes[k + 1].objects[j].active:
                continue
            object_steps.add(
                {
                    "q": at.obj(k, j, "q"),
                    "v": at.obj(k, j, "v"),
                    "q1": at.obj(k + 1, j, "q"),
                    "v1": at.obj(k + 1, j, "v"),
                    "dt": at.var(k, "dt"),
                },
                {"mass": obj.mass, "inertia": obj.inertia, "com": obj.com},
            )
            which.append((k, j))
    robot_rows = b.flush_owned(robot_step)[:, 0:6]
    object_rows = {
        kj: rows[0:6] for kj, rows in zip(which, b.flush_owned(object_step), strict=True)
    }
    on_lifted = wrench_kind("point", "point")
    at_object = wrench_kind("object", "point")
    on_object = wrench_kind("point", "object")
    same_object = same_object_wrench_kind()
    for k, mode in enumerate(modes[:-1]):
        dt = at.var(k, "dt")
        for i in range(2):
            foot = at.limb(k, "foot_wrench", i)
            if mode.feet[i]:
                r = at.foot(k, i, "r")
                x = {"wrench": foot, "r": r, "c": at.kin(k, "com"), "dt": dt}
                b.onto(on_lifted, x, {"sign": 1.0}, robot_rows[k])
                j = mode.feet_on[i]
                if j is not None and (k, j) in object_rows:
                    x = {"wrench": foot, "r": r, "c_q": at.obj(k, j, "q"), "dt": dt}
                    p = {"sign": -1.0, "c_local": objects[j].com}
                    b.onto(on_object, x, p, object_rows[(k, j)])
            j = mode.hands[i]
            if j is None:
                continue
            hand = at.limb(k, "hand_wrench", i)
            point = P[limb(par["hand_points"], i), k]
            x = {"wrench": hand, "r_q": at.obj(k, j, "q"), "c": at.kin(k, "com"), "dt": dt}
            b.onto(at_object, x, {"sign": 1.0, "r_local": point}, robot_rows[k])
            if (k, j) in object_rows:
                x = {"wrench": hand, "q": at.obj(k, j, "q"), "dt": dt}
                p = {"sign": -1.0, "r_local": point, "c_local": objects[j].com}
                b.onto(same_object, x, p, object_rows[(k, j)])
        for j, obj in enumerate(objects):
            if (k, j) not in object_rows:
                continue
            # An object not yet simulated rests on its support's fixed wrench: the step
            # into its first simulated node needs it.
            if mode.objects[j].support is not None:
                x = {"wrench": at.obj(k, j, "support_wrench"), "q": at.obj(k, j, "q"), "dt": dt}
                p = {"sign": 1.0, "r_local": np.zeros(3), "c_local": obj.com}
                b.onto(same_object, x, p, object_rows[(k, j)])
            for rider in mode.riders(j):
                x = {
                    "wrench": at.obj(k, rider, "support_wrench"),
                    "r": at.obj(k, rider, "q")[POSITION],
                    "c_q": at.obj(k, j, "q"),
                    "dt": dt,
                }
                b.onto(on_object, x, {"sign": -1.0, "c_local": obj.com}, object_rows[(k, j)])


def _contacts(b, at: _Index, modes, numbers: Numbers, robot: RobotTerms, P, par, opar) -> None:
    """The contacts of node k + 1: feet, hands, supports."""
    k_z = numbers.contact.stiffness
    # A landing sole sinks no deeper than its slack may (sole_depth_kind: why touchdown).
    depth_max = numbers.contact.slack_max_m
    palm_radius = float(robot.frames.palm_radius)
    for k in range(len(modes) - 1):
        m, m1, k1 = modes[k], modes[k + 1], k + 1
        for i in range(2):
            if not m1.feet[i]:
                continue
            onset = "held" if m.feet[i] else "touchdown"
            x = {
                "r": at.foot(k1, i, "r"),
                "r_dot": at.foot(k1, i, "r_dot"),
                "R": at.foot(k1, i, "R"),
                "slack": at.var(k1, "foot_slack")[i],
            }
            x |= (
                {"w": at.foot(k1, i, "w")}
                if onset == "touchdown"
                else {"r_before": at.foot(k, i, "r")}
            )
            surface_z = P[par["foot_surface_z"], k1][i]
            b.own(foot_patch_kind(onset)).add(x, {"surface_z": surface_z, "k_z": k_z})
            if depth_max is not None and onset == "touchdown":
                p = {"surface_z": surface_z, "depth_max": depth_max}
                b.own(sole_depth_kind()).add({"r": x["r"]}, p)
        for i in range(2):
            j = m1.hands[i]
            if j is None:
                continue
            onset = "held" if m.hands[i] == j else "touchdown"
            x = {
                "r": at.hand(k1, i, "r"),
                "R": at.hand(k1, i, "R"),
                "w": at.hand(k1, i, "w"),
                "slack": at.limb(k1, "hand_slack", i),
                "q_o": at.obj(k1, j, "q"),
                "v_o": at.obj(k1, j, "v"),
            }
            p = {
                "point": P[limb(par["hand_points"], i), k1],
                "face": P[limb(par["hand_frames"], i), k1],
                "palm_radius": palm_radius,
            }
            b.own(hand_contact_kind(onset)).add(x, p)
        for j, obj in enumerate(numbers.objects):
            # Where an object starts to move its state at k and the wrenches on it are
            # fixed, so (1) alone fixes its state at k + 1: a support contact there too
            # would repeat it and make the constraint Jacobian rank-deficient.
            support = m1.objects[j].support
            if support is None or not (m.objects[j].active and m1.objects[j].active):
                continue
            held = m.objects[j].support == support
            x = {
                "q": at.obj(k1, j, "q"),
                "v": at.obj(k1, j, "v"),
                "slack": at.obj(k1, j, "support_slack"),
            }
            if held:
                x |= {"q_before": at.obj(k, j, "q"), "v_before": at.obj(k, j, "v")}
            base = getattr(support, "base", None)
            if base is not None:
                x |= {"base_q": at.obj(k1, base, "q"), "base_v": at.obj(k1, base, "v")}
                if held:
                    x |= {
                        "base_q_before": at.obj(k, base, "q"),
                        "base_v_before": at.obj(k, base, "v"),
                    }
            p = {"height": P[opar(j, "support_z"), k1][0], "k_z": k_z, **object_numbers(obj)}
            kind = support_contact_kind(type(support), "held" if held else "touchdown")
            b.own(kind).add(x, p)


def _wrench_rows(b, at: _Index, modes, numbers: Numbers, robot: RobotTerms, P, par) -> None:
    """Node k's rows on its wrenches: the friction cones and CoP (3), the supports' rows."""
    contact = numbers.contact
    sole_half = np.asarray(robot.frames.sole_half_extents, dtype=float)
    for k, mode in enumerate(modes[:-1]):
        for i in range(2):
            if mode.feet[i]:
                x = {"wrench": at.limb(k, "foot_wrench", i), "R": at.foot(k, i, "R")}
                p = {"mu": contact.floor_friction, "half": sole_half}
                b.own(foot_cone_kind()).add(x, p)
            j = mode.hands[i]
            if j is not None and not prehensile(contact, numbers.objects[j]):
                x = {"wrench": at.limb(k, "hand_wrench", i), "rpy": at.obj(k, j, "q")[ORIENTATION]}
                p = {
                    "mu": numbers.objects[j].friction,
                    "half": contact.palm_half_extents_m,
                    "face": P[limb(par["hand_frames"], i), k],
                }
                b.own(object_face_cone_kind()).add(x, p)
        for j, obj in enumerate(numbers.objects):
            if mode.supported(j):
                support = mode.objects[j].support
                x = {"wrench": at.obj(k, j, "support_wrench"), "q": at.obj(k, j, "q")}
                b.own(support_wrench_kind(type(support))).add(x, object_numbers(obj))


def _carried(mode: NodeMode, k: int) -> list[int]:
    carried = [j for j in range(len(mode.objects)) if mode.carried(j)]
    if len(carried) > 1:
        raise ConfigError(
            f"node {k} carries objects {carried}: the stance cost's CoM c_all takes one "
            "carried object at most"
        )
    return carried


def _costs(b, at: _Index, modes, numbers: Numbers, robot: RobotTerms, P, par, opar) -> None:
    """(8) per node by its mode, L_reg, L_slack, (9), (10) and the objects' poses."""
    w = numbers.weights
    stance_w = weight_values(w, STANCE_WEIGHTS)
    walking_w = weight_values(w, WALKING_WEIGHTS)
    reg_w = weight_values(w, REGULARIZATION_WEIGHTS)
    for k, mode in enumerate(modes):
        q, yaw_ref = at.var(k, "q"), P[par["yaw_ref"], k][0]
        surface = P[par["foot_surface_z"], k]
        if mode.stance:
            x = {
                "q": q,
                "com": at.kin(k, "com"),
                "r_l": at.foot(k, 0, "r"),
                "r_r": at.foot(k, 1, "r"),
                "R_l": at.foot(k, 0, "R"),
                "R_r": at.foot(k, 1, "R"),
            }
            p = stance_w | {"yaw_ref": yaw_ref}
            carried = _carried(mode, k)
            if carried:
                obj = numbers.objects[carried[0]]
                x |= {"q_o": at.obj(k, carried[0], "q")}
                p |= {"robot_mass": robot.mass, "object_mass": obj.mass, "object_com": obj.com}
            b.own(stance_kind(bool(carried))).add(x, p)
            x = {"r_l": at.foot(k, 0, "r"), "r_r": at.foot(k, 1, "r")}
            p = {
                "weight": w.keyframe_foot * P[par["kf_foot_on"], k][0],
                "target": P[par["kf_foot"], k],
            }
            b.own(keyframe_foot_kind()).add(x, p)
        else:
            swing = next(i for i in range(2) if not mode.feet[i])
            x = {"q": q, "r_swing": at.foot(k, swing, "r")}
            p = walking_w | {"yaw_ref": yaw_ref, "surface_z": surface[swing]}
            b.own(walking_kind()).add(x, p)
        # The base height is over the surface the feet stand on (the floor, or a box's top).
        down = [i for i in range(2) if mode.feet[i]]
        ground = sum(surface[i] for i in down) / len(down)
        x = {
            "q": q,
            "v": at.var(k, "v"),
            "foot_wrench": at.var(k, "foot_wrench"),
            "hand_wrench": at.var(k, "hand_wrench"),
            "dt": at.var(k, "dt"),
        }
        b.own(regularization_kind()).add(x, reg_w | {"ground": ground})
        slacks = [at.var(k, "foot_slack"), at.var(k, "hand_slack")]
        slacks += [at.obj(k, j, "support_slack") for j in range(len(numbers.objects))]
        for s in np.concatenate(slacks):
            b.own(squared_kind(1)).add({"x": s}, {"weight": w.slack})
        on = P[par["kf_base_on"], k][0]
        height, orientation = w.keyframe_base
        p = {
            "w_height": height * on,
            "w_orientation": orientation * on,
            "reference": P[par["kf_base"], k],
        }
        b.own(keyframe_base_kind()).add({"base": q[2:6]}, p)
        for j in range(len(numbers.objects)):
            if not mode.objects[j].active:
                continue
            b.own(squared_kind(6)).add({"x": at.obj(k, j, "support_wrench")}, {"weight": w.force})
            p = {
                "w_goal": w.object_goal * P[opar(j, "goal_on"), k][0],
                "goal": P[opar(j, "goal"), k],
                "w_upright": w.object_upright,
            }
            b.own(object_pose_kind()).add({"q": at.obj(k, j, "q")}, p)


def _robot_spheres(pair: CollisionPair) -> list[tuple[str, str]]:
    """The pair's x slots that are a robot sphere's centre, each with the pair's attribute
    holding that sphere."""
    if pair.geometry == "sphere_sphere":
        return [("a", "sphere"), ("b", "other")]
    return [] if pair.sphere is None else [("c", "sphere")]


def _collisions(
    b, at: _Index, pairs, cfg: CollisionCfg, w: CostWeights, context: tuple, reused
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
                for _, attr in _robot_spheres(pair)
            ]
            between.setdefault(key, []).append(centres)
    for key, group in groups.items():
        x, p = _pair_columns(at, group, key, cfg, w, between.get(key))
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


def _pair_columns(
    at: _Index,
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
    for i, (slot, attr) in enumerate(_robot_spheres(first)):
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


def _between(b: _Builder, at: _Index, robot: RobotTerms, spheres: SphereSet) -> None:
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
