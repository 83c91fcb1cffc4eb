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
import sys
import time
from collections.abc import Iterator, Sequence
from pathlib import Path

import casadi as ca
import numpy as np

from locoman.config.to import HESSIANS
from locoman.errors import SolverBuildError
from locoman.to.nlp.callback import OracleCallback
from locoman.to.nlp.derivatives import Derivatives
from locoman.to.nlp.multipliers import WARM_START_OPTIONS, WarmStart
from locoman.to.nlp.oracles import Oracles, unavailable_jacobian
from locoman.to.nlp.progress import ProgressLog
from locoman.to.terms.term import Block, RowSpace


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

    IPOPT's oracles are evaluated numerically (:class:`locoman.to.nlp.oracles.Oracles`): the
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
            (:class:`locoman.to.nlp.progress.ProgressLog`); 0: none.
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
    each factorisation and the iterates follow, to the same optimum by a longer path
    (docs/performance.md). One thread makes the solve independent of the machine's core
    count, and on 2 cores it is faster."""
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
