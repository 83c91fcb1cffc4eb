"""A sparse NLP assembled from compiled terms called over index lists.

The TO is written as a few kinds of *terms* (:class:`Term`): small CasADi functions
``F(x, p) -> (g, l, r)`` of a handful of decision variables ``x`` and numbers ``p``, each with
constraint rows ``g``, a smooth cost ``l`` and residuals ``r`` whose squares are costs
(the collision penalties (12)). A *block* (:class:`Block`) calls one term many times: for
each call it names which entries of the NLP's decision vector make up ``x`` (a gather), the
numbers ``p``, and the NLP's constraint rows that ``g`` adds to (a scatter; several blocks may
add to the same rows, as every contact adds its wrench to a body's momentum rows (1a)).

The terms' derivatives are compiled once per term kind (:func:`term_recipe`), whatever the
scenario: which terms are called where, on which variables and with which numbers is data.
The NLP's Jacobian, gradient and Hessian of the Lagrangian are the terms' own, scattered into
IPOPT's sparse structure by constant index maps and summed where they land on the same entry
(the chain rule of a gather is a scatter). So a new scenario, contact schedule or collision
pair builds a new assembly (index bookkeeping, under a second), and compiles nothing.

The cost is sum l + ||r||^2. Per term the Hessian comes in two flavours:

- ``gauss_newton``: sigma nabla^2 l + 2 sigma J_r' J_r, without the constraints' curvature;
- ``exact``: sigma nabla^2 l + nabla^2 (lambda' g) + 2 sigma (J_r' J_r + sum_i r_i nabla^2 r_i),
  but for terms whose residuals stay Gauss-Newton (:attr:`Term.exact_residuals` False).
"""

from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
import dataclasses
import hashlib
import inspect
import sys
import time
from collections.abc import Iterator, Sequence
from pathlib import Path

import casadi as ca
import numpy as np

from locoman.to.compile import Recipe, SolverBuildError, load_or_compile
from locoman.to.oracles import OracleCallback, Oracles, unavailable_jacobian
from locoman.to.progress import ProgressLog

# The Hessian flavours: without the constraints' curvature; with it, each call's projected
# onto the positive semidefinite cone (:mod:`locoman.to.convexify`); with it as it is.
HESSIANS = ("gauss_newton", "projected", "exact")


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
            (:data:`locoman.to.oracles.NEGLIGIBLE_COST`).
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


def term_derivatives(term: Term) -> tuple[tuple[ca.Function, ...], dict]:
    """The compiled functions of one term, each mapped over calls by the assembly:
    ``val`` (g, cost), ``jac`` (g, nz(J_g)), ``grad`` (cost, grad), ``hess_gn`` and
    ``hess_exact`` (nz of the upper triangle, inputs x, p, lambda, sigma), and the
    sparsity patterns of J_g and of each Hessian as JSON-able triplets."""
    fn = term.function
    x, p = ca.SX.sym("x", term.nx), ca.SX.sym("p", term.np)
    lam, sigma = ca.SX.sym("lam", term.ng), ca.SX.sym("sigma")
    g, smooth, residuals = fn(x, p)
    cost = smooth + ca.sumsqr(residuals)
    jac = ca.jacobian(g, x)
    grad = ca.densify(ca.gradient(cost, x))
    jac_r = ca.jacobian(residuals, x)
    gauss_newton = ca.triu(ca.hessian(sigma * smooth, x)[0] + 2.0 * sigma * (jac_r.T @ jac_r))
    if term.exact_residuals:
        exact = ca.hessian(sigma * cost + ca.dot(lam, g), x)[0]
    else:
        exact = ca.hessian(sigma * smooth + ca.dot(lam, g), x)[0] + 2.0 * sigma * (jac_r.T @ jac_r)
    exact = ca.triu(exact)
    name = term.name
    functions = (
        ca.Function(f"{name}_val", [x, p], [g, cost]),
        ca.Function(f"{name}_jac", [x, p], [g, ca.vertcat(*jac.nonzeros())]),
        ca.Function(f"{name}_grad", [x, p], [cost, grad]),
        ca.Function(f"{name}_hgn", [x, p, lam, sigma], [ca.vertcat(*gauss_newton.nonzeros())]),
        ca.Function(f"{name}_hex", [x, p, lam, sigma], [ca.vertcat(*exact.nonzeros())]),
    )
    data = {
        "jac": _triplet(jac.sparsity()),
        "gauss_newton": _triplet(gauss_newton.sparsity()),
        "exact": _triplet(exact.sparsity()),
    }
    return functions, data


# A term's derivatives are a function of its function, its residual switch and of
# term_derivatives' code: together they fingerprint its compiled library.
_DERIVATION = inspect.getsource(term_derivatives)


def _triplet(sp: ca.Sparsity) -> list:
    rows, cols = sp.get_triplet()
    return [sp.size1(), sp.size2(), list(rows), list(cols)]


def term_recipe(term: Term) -> Recipe:
    """The compiled derivatives of ``term`` as a cache recipe (:mod:`locoman.to.compile`)."""
    parts = [term.function.serialize(), str(term.exact_residuals), _DERIVATION]
    fingerprint = hashlib.sha256("\0".join(parts).encode()).hexdigest()
    return Recipe(fingerprint, lambda: term_derivatives(term))


@dataclasses.dataclass(frozen=True)
class Derivatives:
    """One term's derivative functions (compiled or interpreted) and their patterns."""

    val: ca.Function
    jac: ca.Function
    grad: ca.Function
    hess: dict[str, ca.Function]
    jac_pattern: tuple[np.ndarray, np.ndarray]
    hess_pattern: dict[str, tuple[np.ndarray, np.ndarray]]


def _derivatives(functions: Sequence[ca.Function], data: dict) -> Derivatives:
    val, jac, grad, hgn, hex_ = functions

    def pattern(key: str) -> tuple[np.ndarray, np.ndarray]:
        _, _, rows, cols = data[key]
        return np.asarray(rows, dtype=int), np.asarray(cols, dtype=int)

    return Derivatives(
        val,
        jac,
        grad,
        {"gauss_newton": hgn, "exact": hex_},
        pattern("jac"),
        {"gauss_newton": pattern("gauss_newton"), "exact": pattern("exact")},
    )


def load_derivatives(
    terms: Sequence[Term], cache_dir: Path | None, flags: Sequence[str] = ("-O0",)
) -> dict[str, Derivatives]:
    """Every term's derivatives by name: compiled into (or loaded from) ``cache_dir``, one
    library per term, or interpreted where ``cache_dir`` is None."""
    names = [t.name for t in terms]
    if len(set(names)) != len(names):
        raise SolverBuildError(f"two terms share a name: {sorted(names)}")
    if cache_dir is None:
        made = [term_derivatives(t) for t in terms]
    else:
        made = load_or_compile([term_recipe(t) for t in terms], cache_dir, flags)
    return {t.name: _derivatives(fns, data) for t, (fns, data) in zip(terms, made, strict=True)}


@dataclasses.dataclass(frozen=True)
class WarmStart:
    """A primal-dual point of an NLP of the same structure to start IPOPT from: primal x,
    bound multipliers lam_x, constraint multipliers lam_g; ``rows``: which calls own its
    constraint rows (:func:`row_owners`), so that a problem with more rows can take the
    multipliers of the calls it shares (:func:`carried_multipliers`)."""

    x: np.ndarray
    lam_x: np.ndarray
    lam_g: np.ndarray
    rows: dict[tuple[str, int], Block] | None = None


def row_owners(blocks: Sequence[Block]) -> dict[tuple[str, int], Block]:
    """The blocks with constraint rows, by (term name, occurrence of that name)."""
    seen: dict[str, int] = {}
    out = {}
    for block in blocks:
        if block.defines or not block.rows.size:
            continue
        name = block.term.name
        out[(name, seen.get(name, 0))] = block
        seen[name] = seen.get(name, 0) + 1
    return out


def carried_multipliers(warm: WarmStart, blocks: Sequence[Block], n_g: int) -> WarmStart | None:
    """``warm`` for a problem of ``blocks`` with ``n_g`` rows that extends its own (a round
    of found pairs under a hard treatment adds rows): each block's first calls, where they
    are the same calls (the same numbers), take their multipliers, the new rows start at
    0. None without ``warm.rows``. Starting the new rows' multipliers at 0 keeps IPOPT's
    warm start: from the primal point alone it restarted its barrier, and S1's Base+Foot
    at 5 kg, 1.2 rad wandered through restoration to its iteration limit where the
    carried start converged (docs/trajectory-optimisation.md)."""
    if warm.rows is None:
        return None
    lam = np.zeros(n_g)
    new = row_owners(blocks)
    for key, old in warm.rows.items():
        block = new.get(key)
        if block is None:
            continue
        n = min(old.calls, block.calls)
        same = np.all(old.p[:n] == block.p[:n], axis=1)
        lam[block.rows[:n][same].ravel()] = warm.lam_g[old.rows[:n][same].ravel()]
    return WarmStart(warm.x, warm.lam_x, lam, row_owners(blocks))


# IPOPT's warm start: the point is taken as it is, pushed off the bounds by little, and the
# barrier starts small, as near an optimum it should.
WARM_START_OPTIONS = {
    "warm_start_init_point": "yes",
    "warm_start_bound_push": 1e-6,
    "warm_start_bound_frac": 1e-6,
    "warm_start_slack_bound_push": 1e-6,
    "warm_start_slack_bound_frac": 1e-6,
    "warm_start_mult_bound_push": 1e-6,
    "mu_init": 1e-4,
}


@dataclasses.dataclass(frozen=True)
class NLPResult:
    """IPOPT's answer; ``status`` is its return status, ``timing`` its statistics [s]
    (function evaluations, and the rest: mostly the linear algebra)."""

    status: str
    success: bool
    iterations: int
    x: np.ndarray
    lam_g: np.ndarray
    cost: float
    max_constraint_violation: float
    solve_time_s: float
    lam_x: np.ndarray
    function_time_s: float = 0.0

    @property
    def warm_start(self) -> WarmStart:
        return WarmStart(self.x, self.lam_x, self.lam_g)


def structure_key(n_x: int, blocks: Sequence[Block]) -> str:
    """What an assembled NLP depends on: the variables' count, and per block its term, which
    variables each call takes and which rows it adds to (not the numbers ``p``)."""
    digest = hashlib.sha256(str(n_x).encode())
    for block in blocks:
        digest.update(f"{block.term.name} {block.defines}".encode())
        digest.update(np.ascontiguousarray(block.x, dtype=np.int64).tobytes())
        digest.update(np.ascontiguousarray(block.rows, dtype=np.int64).tobytes())
        digest.update(str(block.p.shape).encode())
    return digest.hexdigest()


def parameter_vector(blocks: Sequence[Block]) -> np.ndarray:
    """The NLP's parameter vector: every block's numbers, call after call."""
    parts = [np.asarray(b.p, dtype=float).ravel() for b in blocks]
    return np.concatenate(parts) if parts else np.zeros(0)


class BlockNLP:
    """The NLP of ``blocks`` with its IPOPT solver, assembled once per structure.

    Virtual variables y (indices ``n_x`` .. ``n_x + n_y`` of the blocks' ``x``) are functions
    y = F(x) of the NLP's own, each defined by a block with ``defines`` (a robot sphere's
    centre from q). Every other term is assembled over z = (x, y) as if y were variables,
    and its derivatives reach x by the chain rule, with P = dz/dx = [I; dF/dx]:

        J_x = J_z P,   grad_x = P' grad_z,   H_x = P' H_z P  (+ sum_i mu_i nabla^2 F_i),

    (the identity block of P multiplied out by hand),
    the last term, with mu = dL/dy, in the exact and projected Hessians only (the
    Gauss-Newton one leaves it out, as it leaves out every constraint's curvature). So a
    collision pair's term is a small function of two sphere centres, and the NLP has no
    variable for them.

    IPOPT's oracles are evaluated numerically (:class:`locoman.to.oracles.Oracles`): the
    compiled terms on NumPy buffers, the sums and the chain rule in SciPy, the far calls of
    the collision penalties skipped. Building one is index bookkeeping (well under a second
    on S2): no graph is built and nothing is compiled.

    Args:
        n_x: Decision variables.
        blocks: The term calls.
        rows: The constraint rows the blocks add to, with their bounds.
        derivatives: Each block's term's derivatives, by name (:func:`load_derivatives`).
        hessian: A key of :data:`HESSIANS`.
        ipopt: IPOPT options.
        n_y: Virtual variables.
        previous: An NLP whose blocks may be the first calls of these (the round before
            this one): its patterns are extended, not made again (:class:`Oracles`).
        progress_every: Iterations between two progress lines
            (:class:`locoman.to.progress.ProgressLog`); 0: none.
    """

    def __init__(
        self,
        n_x: int,
        blocks: Sequence[Block],
        rows: RowSpace,
        derivatives: dict[str, Derivatives],
        hessian: str,
        ipopt: dict,
        n_y: int = 0,
        previous: BlockNLP | None = None,
        progress_every: int = 0,
    ) -> None:
        tic = time.perf_counter()
        if hessian not in HESSIANS:
            raise SolverBuildError(f"hessian must be one of {HESSIANS}, got {hessian!r}")
        self.n_x, self.n_y, self.n_g = n_x, n_y, rows.size
        self.lbg, self.ubg = rows.bounds()
        self.key = structure_key(n_x + n_y, blocks)
        self.n_p = sum(b.p.size for b in blocks)
        self.progress = (
            ProgressLog(n_x, self.n_g, self.n_p, self.lbg, self.ubg, progress_every)
            if progress_every > 0
            else None
        )
        before = previous.evaluate if previous is not None else None
        evaluate = Oracles(n_x, blocks, self.n_g, derivatives, hessian, n_y, before)
        self.evaluate = evaluate
        x_in = ("x", ca.Sparsity.dense(n_x, 1))
        p_in = ("p", ca.Sparsity.dense(self.n_p, 1))
        scalar = ca.Sparsity.dense(1, 1)
        g_out = ("g", ca.Sparsity.dense(self.n_g, 1))
        # f and g as one function of the problem's graph; IPOPT takes the derivatives from
        # the oracles below.
        fg_out = [("f", scalar), g_out]
        jacobian = unavailable_jacobian([x_in, p_in], fg_out)
        fg = OracleCallback("fg", [x_in, p_in], fg_out, evaluate.fg, jacobian)
        self.oracles = {
            "jac_g": OracleCallback(
                "jac_g",
                [x_in, p_in],
                [g_out, ("jac_g_x", evaluate.J_x.sparsity)],
                evaluate.jac_g,
            ),
            "grad_f": OracleCallback(
                "grad_f",
                [x_in, p_in],
                [("f", scalar), ("grad_f_x", ca.Sparsity.dense(n_x, 1))],
                evaluate.grad_f,
            ),
            "hess_lag": OracleCallback(
                "hess_lag",
                [x_in, p_in, ("lam_f", scalar), ("lam_g", ca.Sparsity.dense(self.n_g, 1))],
                [("triu_hess_gamma_x_x", evaluate.H_x.sparsity)],
                lambda x, p, lam_f, lam_g: [evaluate.hess_lag(x, p, float(lam_f[0]), lam_g)],
            ),
        }
        X, P = ca.MX.sym("x", n_x), ca.MX.sym("p", self.n_p)
        f, g = fg(X, P)
        self._callbacks = (fg, jacobian)  # CasADi holds them by reference only
        self._problem = {"x": X, "p": P, "f": f, "g": g}
        self._options = dict(ipopt)
        self.solver = self.ipopt(ipopt)
        self._warm_solver: ca.Function | None = None
        self.build_time_s = time.perf_counter() - tic

    def ipopt(self, options: dict) -> ca.Function:
        """An IPOPT instance on this NLP's oracles with ``options``."""
        opts = {"print_time": False, "calc_lam_p": False, "ipopt": options, **self.oracles}
        if self.progress is not None:
            opts |= {
                "iteration_callback": self.progress,
                "iteration_callback_step": self.progress.every,
            }
        return ca.nlpsol("to", "ipopt", self._problem, opts)

    def solve(
        self,
        x0: np.ndarray,
        lbx: np.ndarray,
        ubx: np.ndarray,
        p: np.ndarray,
        warm: WarmStart | None = None,
        limits: dict | None = None,
        label: str = "solve",
    ) -> NLPResult:
        """Solve from ``x0``, or from ``warm``'s primal-dual point (IPOPT's warm start), with
        the numbers ``p`` (:func:`parameter_vector`); ``limits``: IPOPT options for this
        solve only (``max_iter``, ``max_wall_time``); ``label``: what the progress lines
        call this solve. A failed solve is returned with IPOPT's status, not raised."""
        if p.shape != (self.n_p,):
            raise SolverBuildError(f"p has shape {p.shape}; this NLP takes ({self.n_p},)")
        args = {"x0": x0, "lbx": lbx, "ubx": ubx, "lbg": self.lbg, "ubg": self.ubg, "p": p}
        solver = self.solver
        if warm is not None:
            if warm.x.shape != (self.n_x,) or warm.lam_g.shape != (self.n_g,):
                raise SolverBuildError("the warm start is of an NLP of another structure")
            if self._warm_solver is None:
                self._warm_solver = self.ipopt(self._options | WARM_START_OPTIONS)
            solver = self._warm_solver
            args |= {"x0": np.clip(warm.x, lbx, ubx), "lam_x0": warm.lam_x, "lam_g0": warm.lam_g}
        if limits:
            options = self._options | (WARM_START_OPTIONS if warm is not None else {})
            solver = self.ipopt(options | limits)
        if self.progress is not None:
            self.progress.start(label)
        tic = time.perf_counter()
        with _heap_kept(), _single_threaded_blas():
            out = solver(**args)
        elapsed = time.perf_counter() - tic
        stats = solver.stats()
        x = np.asarray(out["x"]).ravel()
        g = np.asarray(out["g"]).ravel()
        violation = max(
            float(np.max(np.maximum(self.lbg - g, 0.0), initial=0.0)),
            float(np.max(np.maximum(g - self.ubg, 0.0), initial=0.0)),
            float(np.max(np.maximum(lbx - x, 0.0), initial=0.0)),
            float(np.max(np.maximum(x - ubx, 0.0), initial=0.0)),
        )
        sys.stdout.flush()
        functions = sum(
            float(stats.get(f"t_wall_{name}", 0.0))
            for name in ("nlp_f", "nlp_g", "nlp_grad_f", "nlp_jac_g", "nlp_hess_l")
        )
        return NLPResult(
            status=str(stats["return_status"]),
            success=bool(stats["success"]),
            iterations=int(stats["iter_count"]),
            x=x,
            lam_g=np.asarray(out["lam_g"]).ravel(),
            cost=float(out["f"]),
            max_constraint_violation=violation,
            solve_time_s=elapsed,
            lam_x=np.asarray(out["lam_x"]).ravel(),
            function_time_s=functions,
        )


@contextlib.contextmanager
def _single_threaded_blas() -> Iterator[None]:
    """Run IPOPT's MUMPS on one thread of CasADi's OpenBLAS while IPOPT runs; the process's
    setting is restored after. With one per core, parallel sums change the last bits of
    each factorisation and the iterates follow: on ``tiny`` 2 threads took 808 iterations
    where 1 took 225, to the same optimum. One thread makes the solve independent of the
    machine's core count, and on 2 cores it is faster."""
    library = Path(ca.__file__).parent / "libcasadi-tp-openblas.so.0"
    if not library.is_file():
        yield
        return
    blas = ctypes.CDLL(str(library))
    threads = blas.openblas_get_num_threads()
    blas.openblas_set_num_threads(1)
    try:
        yield
    finally:
        blas.openblas_set_num_threads(threads)


# glibc's mallopt parameters and their defaults.
_M_TRIM_THRESHOLD, _M_MMAP_MAX = -1, -4
_TRIM_DEFAULT, _MMAP_MAX_DEFAULT = 128 * 1024, 65536


@contextlib.contextmanager
def _heap_kept() -> Iterator[None]:
    """Keep freed memory in the process while IPOPT runs. MUMPS allocates and frees its
    work arrays at every factorisation; by default glibc maps large blocks afresh and gives
    them back, and the kernel zeroes every page again: on ``tiny`` that was 7 s of 56 (sys
    time and page faults). The iterates do not change. Elsewhere than glibc, a no-op."""
    name = ctypes.util.find_library("c")
    libc = ctypes.CDLL(name) if name else None
    if libc is None or not hasattr(libc, "mallopt"):
        yield
        return
    libc.mallopt(_M_MMAP_MAX, 0)
    libc.mallopt(_M_TRIM_THRESHOLD, 2**31 - 1)
    try:
        yield
    finally:
        libc.mallopt(_M_MMAP_MAX, _MMAP_MAX_DEFAULT)
        libc.mallopt(_M_TRIM_THRESHOLD, _TRIM_DEFAULT)
        libc.malloc_trim(0)
