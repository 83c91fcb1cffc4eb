"""The term data model: what a kind of term is and how it is called.

A :class:`Term` is one small compiled CasADi function ``F(x, p) -> (g, l, r)``; a
:class:`TermKind` names the slices of its inputs (``x``: decision variables, gathered per
call; ``p``: numbers) and builds its rows (:class:`Rows`) from named symbols
(:class:`Symbols`) by :func:`term_kind`. :class:`Calls` collects a kind's calls (which
variables, which numbers), a :class:`Block` is those calls placed in the NLP, and
:class:`RowSpace` hands out the NLP's constraint rows. The kinds themselves are in the
sibling modules, by area of paper A; which kind is called where is the transcription's
business (:mod:`locoman.to.transcription`): data.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable, Mapping, Sequence

import casadi as ca
import numpy as np

from locoman.errors import SolverBuildError


@dataclasses.dataclass(frozen=True)
class Rows:
    """What a term kind's body returns: equality rows (= 0), inequality rows (>= 0), the
    smooth cost and the residuals (the cost's ||r||^2 part)."""

    equalities: Sequence[ca.SX] = ()
    inequalities: Sequence[ca.SX] = ()
    cost: ca.SX | float = 0.0
    residuals: Sequence[ca.SX] = ()


class Symbols:
    """A term's inputs by name: ``s["q"]`` is the slot's SX column."""

    def __init__(self, name: str, slots: Mapping[str, int]) -> None:
        self.vector = ca.SX.sym(name, sum(slots.values()))
        self.slices: dict[str, slice] = {}
        start = 0
        for slot, size in slots.items():
            self.slices[slot] = slice(start, start + size)
            start += size

    def __getitem__(self, slot: str) -> ca.SX:
        return self.vector[self.slices[slot]]


@dataclasses.dataclass(frozen=True)
class TermKind:
    """A compiled term with named input slots.

    Attributes:
        term: The function ``(x, p) -> (g, l, r)``.
        x_slots, p_slots: slot -> size, in input order.
        lower, upper: Bounds of its rows when it owns them (equalities first, then the
            inequalities).
    """

    term: Term
    x_slots: dict[str, int]
    p_slots: dict[str, int]
    lower: np.ndarray
    upper: np.ndarray

    @functools.cached_property
    def name(self) -> str:
        # Cached: a transcription asks it once per call (S2: half a million), and CasADi's
        # Function.name() is a call into C++ each time.
        return self.term.name


def term_kind(
    name: str,
    x: Mapping[str, int],
    p: Mapping[str, int],
    body: Callable[[Symbols, Symbols], Rows],
    exact_residuals: bool = True,
    lifts: bool = False,
    one_sided: bool = False,
) -> TermKind:
    """A term kind from its slots and a ``body(x, p) -> Rows`` on their symbols; ``lifts``,
    ``one_sided``: see :class:`locoman.to.terms.term.Term` (a lifting kind's last slot is what
    it lifts)."""
    xs, ps = Symbols("x", x), Symbols("p", p)
    out = body(xs, ps)
    eq = ca.vertcat(*out.equalities) if out.equalities else ca.SX(0, 1)
    ineq = ca.vertcat(*out.inequalities) if out.inequalities else ca.SX(0, 1)
    residuals = ca.vertcat(*out.residuals) if out.residuals else ca.SX(0, 1)
    cost = ca.SX(out.cost) if not isinstance(out.cost, ca.SX) else out.cost
    fn = ca.Function(name, [xs.vector, ps.vector], [ca.vertcat(eq, ineq), cost, residuals])
    lower = np.zeros(eq.numel() + ineq.numel())
    upper = np.r_[np.zeros(eq.numel()), np.full(ineq.numel(), np.inf)]
    return TermKind(Term(fn, exact_residuals, lifts, one_sided), dict(x), dict(p), lower, upper)


class Calls:
    """The calls of one term kind, added one by one, then a :class:`Block`.

    ``add(x={slot: variable indices}, p={slot: numbers})`` takes every slot of the kind;
    the values are joined slot by slot when the block is made (a matrix column-major, as
    CasADi reshapes it).
    """

    def __init__(self, kind: TermKind) -> None:
        self.kind = kind
        self._x: list[Mapping] = []
        self._p: list[Mapping] = []
        self._x_keys, self._p_keys = set(kind.x_slots), set(kind.p_slots)
        self._stacked: tuple[np.ndarray, np.ndarray] | None = None

    def __len__(self) -> int:
        return len(self._x) + (0 if self._stacked is None else len(self._stacked[0]))

    def start_with(self, x: np.ndarray, p: np.ndarray) -> None:
        """Calls already stacked (:meth:`arrays` of an earlier set of these calls) come
        first."""
        if len(self):
            raise SolverBuildError(f"{self.kind.name}: stacked calls come before any other")
        self._stacked = (x, p)

    def add(self, x: Mapping[str, object], p: Mapping[str, object] | None = None) -> None:
        p = p or {}
        if x.keys() != self._x_keys or p.keys() != self._p_keys:
            _refuse(self.kind, "x", self.kind.x_slots, x)
            _refuse(self.kind, "p", self.kind.p_slots, p)
        self._x.append(x)
        self._p.append(p)

    def add_columns(self, n: int, x: Mapping[str, object], p: Mapping[str, object]) -> None:
        """``n`` calls at once, each slot's values for every call (a sequence or an array
        whose first axis is the call): a transcription's hundred thousand collision pairs
        without a dict per call. They come after the calls so far."""
        if x.keys() != self._x_keys or p.keys() != self._p_keys:
            _refuse(self.kind, "x", self.kind.x_slots, x)
            _refuse(self.kind, "p", self.kind.p_slots, p)
        self._join(
            _stacked(self.kind, "x", self.kind.x_slots, x, n, int),
            _stacked(self.kind, "p", self.kind.p_slots, p, n, float),
        )

    def arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """(calls, nx) variable indices, (calls, np) numbers. The calls added so far are
        stacked once: later calls come after them."""
        if self._x or self._stacked is None:
            n = len(self._x)
            x = {slot: [c[slot] for c in self._x] for slot in self.kind.x_slots}
            p = {slot: [c[slot] for c in self._p] for slot in self.kind.p_slots}
            self._x, self._p = [], []
            self._join(
                _stacked(self.kind, "x", self.kind.x_slots, x, n, int),
                _stacked(self.kind, "p", self.kind.p_slots, p, n, float),
            )
        return self._stacked

    def _join(self, x: np.ndarray, p: np.ndarray) -> None:
        """Stacked calls after those stacked so far (the calls added one by one come
        first: :meth:`arrays` stacks them)."""
        if self._x:
            self.arrays()
        if self._stacked is not None:
            x, p = np.concatenate([self._stacked[0], x]), np.concatenate([self._stacked[1], p])
        self._stacked = (x, p)

    def own(self, rows: RowSpace) -> Block:
        """The block, its rows new (with the kind's bounds)."""
        x, p = self.arrays()
        owned = rows.allocate(len(x), self.kind.lower, self.kind.upper)
        return Block(self.kind.term, x, p, owned)

    def onto(self, targets: list[np.ndarray]) -> Block:
        """The block, each call's rows adding to existing ``targets[call]``."""
        x, p = self.arrays()
        width = self.kind.term.ng
        target = np.array(targets, dtype=int).reshape(len(x), width)
        return Block(self.kind.term, x, p, target)

    def costs(self) -> Block:
        """The block of a kind without rows."""
        x, p = self.arrays()
        return Block(self.kind.term, x, p, np.zeros((len(x), 0), dtype=int))


def _refuse(kind: TermKind, what: str, slots: Mapping[str, int], values: Mapping) -> None:
    missing = sorted(set(slots) - set(values))
    extra = sorted(set(values) - set(slots))
    if missing or extra:
        raise SolverBuildError(f"{kind.name}: {what} slots missing {missing}, unknown {extra}")


def _stacked(
    kind: TermKind, what: str, slots: Mapping[str, int], columns: Mapping, n: int, dtype
) -> np.ndarray:
    """(n, sum of the slots' sizes): each slot's values (``columns[slot]``, one per call),
    one row per call."""
    if n == 0:
        return np.zeros((0, sum(slots.values())), dtype=dtype)
    parts = []
    for slot, size in slots.items():
        values = np.asarray(columns[slot], dtype=dtype)
        if values.ndim == 3:  # matrices, column-major as CasADi reshapes them
            values = values.transpose(0, 2, 1)
        if values.ndim == 0 or len(values) != n:
            raise SolverBuildError(
                f"{kind.name}: {what} slot {slot!r} has values for "
                f"{0 if values.ndim == 0 else len(values)} calls, not {n}"
            )
        values = values.reshape(n, -1)
        if values.shape[1] != size:
            raise SolverBuildError(
                f"{kind.name}: {what} slot {slot!r} has {values.shape[1]} values, not {size}"
            )
        parts.append(values)
    return np.concatenate(parts, axis=1) if parts else np.zeros((n, 0), dtype=dtype)


@dataclasses.dataclass(frozen=True)
class Term:
    """One kind of term: ``function(x, p) -> (g, l, r)``, SX, with the cost l + ||r||^2.

    Attributes:
        function: Inputs ``x`` (nx,) and ``p`` (np,); outputs ``g`` (ng,), ``l`` (1,) and
            ``r`` (nr,).
        exact_residuals: The exact Hessian includes the residuals' curvature sum r nabla^2 r;
            False keeps them Gauss-Newton in both flavours.
        lifts: Its rows are c - f(y) for x = (y, c): it defines the variables c (a lifted
            kinematic quantity), which :func:`evaluate` at c = 0 gives as -g.
        one_sided: Its cost is residuals that vanish with their derivatives (a one-sided
            penalty (12)): a call whose cost is negligible is skipped in the derivatives
            (:data:`locoman.to.nlp.oracles.NEGLIGIBLE_COST`).
    """

    function: ca.Function
    exact_residuals: bool = True
    lifts: bool = False
    one_sided: bool = False

    @property
    def name(self) -> str:
        return self.function.name()

    @property
    def nx(self) -> int:
        return int(self.function.size1_in(0))

    @property
    def np(self) -> int:
        return int(self.function.size1_in(1))

    @property
    def ng(self) -> int:
        return int(self.function.size1_out(0))


@dataclasses.dataclass(frozen=True)
class Block:
    """``n`` calls of one term.

    Attributes:
        term: The term.
        x: (n, nx) int: the NLP variable of each local input, per call (no repeats in a call).
        p: (n, np) float: the numbers of each call.
        rows: (n, ng) int: the NLP constraint row each output row adds to.
        defines: A lifting term (:attr:`Term.lifts`) whose lifted variables are not the
            NLP's but virtual ones, indices from ``n_x`` on, defined by it: its rows are not
            constraints, and the other terms' derivatives with respect to them reach the
            NLP's variables by the chain rule (:class:`BlockNLP`). ``rows`` is empty.
    """

    term: Term
    x: np.ndarray
    p: np.ndarray
    rows: np.ndarray
    defines: bool = False

    def __post_init__(self) -> None:
        n = len(self.x)
        shapes = {
            "x": (self.x.shape, (n, self.term.nx)),
            "p": (self.p.shape, (n, self.term.np)),
            "rows": (self.rows.shape, (n, 0 if self.defines else self.term.ng)),
        }
        for name, (got, want) in shapes.items():
            if got != want:
                raise SolverBuildError(f"{self.term.name}: {name} has shape {got}, not {want}")
        if self.defines and not self.term.lifts:
            raise SolverBuildError(f"{self.term.name} lifts nothing: it cannot define variables")

    @property
    def calls(self) -> int:
        return len(self.x)


class RowSpace:
    """The NLP's constraint rows, handed out with their bounds."""

    def __init__(self) -> None:
        self._lower: list[np.ndarray] = []
        self._upper: list[np.ndarray] = []
        self.size = 0

    def allocate(self, calls: int, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
        """(calls, len(lower)) new rows, each call's with the bounds ``lower``, ``upper``."""
        lower, upper = np.asarray(lower, dtype=float), np.asarray(upper, dtype=float)
        width = len(lower)
        rows = self.size + np.arange(calls * width).reshape(calls, width)
        self._lower.append(np.tile(lower, calls))
        self._upper.append(np.tile(upper, calls))
        self.size += calls * width
        return rows

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        if not self._lower:
            return np.zeros(0), np.zeros(0)
        return np.concatenate(self._lower), np.concatenate(self._upper)
