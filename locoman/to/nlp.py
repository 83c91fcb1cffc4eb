"""A multiple-shooting NLP whose constraints and costs are stage functions, with
derivatives assembled from per-stage SX derivatives (issue 6's prototype: "a per-node
exact Hessian, one small SX function mapped over the nodes and given to IPOPT via
``hess_lag``, was the fastest").

The decision vector is x = (z_0, ..., z_{N-1}), one block of ``width`` variables per node;
the parameters are one column of ``n_params`` per node and one vector theta shared by every
node (:mod:`locoman.to.parameters`). A stage k couples z_k and z_{k+1}:
``F(z_k, z_{k+1}, p_k, p_{k+1}, theta) -> (g_k, l_k, r_k)``; a node function touches one
node only: ``F(z_k, p_k, theta) -> (g_k, l_k, r_k)``. Numbers that are inputs are not
constants in the generated C, so its hash, which keys the compiled cache, changes only with
the problem's structure. Stages or nodes with the same constraint kinds
share one function (a :class:`StageGroup`) mapped over them. Expensive node-local terms
(the robot's kinematics) belong in a node function: its derivatives are half the size, and
one function serves every node whatever the contact mode.

The cost of a stage is l_k + ||r_k||^2, r_k the residuals of the collision penalties (12).
For each group the Jacobian of g, the gradient of the cost and the Hessian
sigma ∇²l + ∇²(lambda' g) + 2 sigma J_r' J_r with respect to (z_k, z_{k+1}) are SX functions
of one stage: exact, but for the residuals' Gauss-Newton part. Their exact Hessian adds
2 r ∇²r, negative wherever a penalty acts (r < 0, and ∇²r of a distance is positive), and
IPOPT had to regularise every iteration for it. The global matrices are the stages'
nonzeros scattered (and, where blocks overlap on z_{k+1}, summed) by constant index maps, so
IPOPT's oracles cost N small evaluations and a sparse gather.
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
import scipy.sparse as sps

from locoman.to.compile import Recipe, SolverBuildError, load_or_compile


@dataclasses.dataclass(frozen=True)
class StageGroup:
    """Stages (or nodes) sharing one function.

    Attributes:
        function: ``(z, z_next, p, p_next, theta) -> (g, l, r)`` for a stage,
            ``(z, p, theta) -> (g, l, r)`` for a node function, the cost being
            l + ||r||^2; SX.
        stages: Stage indices k (a stage couples nodes k and k + 1), or node indices.
        lower: (rows,) lower bounds of g.
        upper: (rows,) upper bounds of g.
        constraint_curvature: The Hessian of the Lagrangian includes lambda' nabla^2 g of
            this group; False leaves it out (a Gauss-Newton Hessian for its constraints).
        residual_curvature: The Hessian of ||r||^2 is exact, 2 (J_r' J_r + sum_i r_i
            nabla^2 r_i); False: its Gauss-Newton part 2 J_r' J_r. An active penalty (12)
            has r != 0 at the optimum, so without its curvature the Newton step is not
            Newton's there: S1's exact phase crawled (1000 iterations; with it, 110).
    """

    function: ca.Function
    stages: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    constraint_curvature: bool = True
    residual_curvature: bool = False

    @property
    def rows(self) -> int:
        return int(self.function.size1_out(0))

    @property
    def span(self) -> int:
        """Nodes one call touches: 2 for a stage, 1 for a node function."""
        return (self.function.n_in() - 1) // 2


@dataclasses.dataclass(frozen=True)
class WarmStart:
    """A primal-dual point of an NLP of the same structure (the previous cell of a grid) to
    start IPOPT from: primal x, bound multipliers lam_x, constraint multipliers lam_g."""

    x: np.ndarray
    lam_x: np.ndarray
    lam_g: np.ndarray


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
    """IPOPT's answer; ``status`` is its return status."""

    status: str
    success: bool
    iterations: int
    x: np.ndarray
    lam_g: np.ndarray
    cost: float
    max_constraint_violation: float
    solve_time_s: float
    lam_x: np.ndarray

    @property
    def warm_start(self) -> WarmStart:
        return WarmStart(self.x, self.lam_x, self.lam_g)


def stage_derivatives(group: StageGroup, width: int) -> tuple[ca.Function, ...]:
    """Per-stage (g, l), (g, nz(J)), (l, grad l), nz(triu H) functions of one group; l is
    the whole cost, H the Hessian of the Lagrangian with the curvatures the group asks for
    (:attr:`StageGroup.constraint_curvature`, :attr:`StageGroup.residual_curvature`)."""
    fn, span = group.function, group.span
    zs = [ca.SX.sym(f"z{i}", width) for i in range(span)]
    ps = [ca.SX.sym(f"p{i}", fn.size1_in(span)) for i in range(span)]
    theta = ca.SX.sym("theta", fn.size1_in(2 * span))
    lam, sigma = ca.SX.sym("lam", group.rows), ca.SX.sym("sigma")
    g, smooth, residuals = fn(*zs, *ps, theta)
    cost = smooth + ca.sumsqr(residuals)
    zz = ca.vertcat(*zs)
    args = [*zs, *ps, theta]
    jac = ca.jacobian(g, zz)
    grad = ca.densify(ca.gradient(cost, zz))
    curvature = ca.dot(lam, g) if group.constraint_curvature else 0.0
    if group.residual_curvature:
        hess = ca.triu(ca.hessian(sigma * cost + curvature, zz)[0])
    else:
        jac_r = ca.jacobian(residuals, zz)
        gauss_newton = 2.0 * sigma * (jac_r.T @ jac_r)
        hess = ca.triu(ca.hessian(sigma * smooth + curvature, zz)[0] + gauss_newton)
    name = fn.name()
    return (
        ca.Function(f"{name}_val", args, [g, cost]),
        ca.Function(f"{name}_jac", args, [g, ca.vertcat(*jac.nonzeros())]),
        ca.Function(f"{name}_grad", args, [cost, grad]),
        ca.Function(f"{name}_hess", [*args, lam, sigma], [ca.vertcat(*hess.nonzeros())]),
    ), (jac.sparsity(), hess.sparsity())


# A group's derivatives are a function of its function, its curvature switches and of
# stage_derivatives' code: together they fingerprint its compiled library (see
# locoman.to.compile: a known fingerprint skips the differentiation and the C generation).
_DERIVATION = inspect.getsource(stage_derivatives)


def _triplet(sp: ca.Sparsity) -> list:
    rows, cols = sp.get_triplet()
    return [sp.size1(), sp.size2(), list(rows), list(cols)]


def _sparsities(data: dict) -> tuple[ca.Sparsity, ca.Sparsity]:
    return tuple(ca.Sparsity.triplet(*data[k]) for k in ("jac", "hess"))


def derivative_recipe(group: StageGroup, width: int) -> Recipe:
    """The compiled derivatives of ``group`` (:func:`stage_derivatives`) as a cache
    recipe; the sparsity patterns of J and H travel with them in the cache's index."""
    switches = f"{width} {group.constraint_curvature} {group.residual_curvature}"
    parts = [group.function.serialize(), switches, _DERIVATION]
    fingerprint = hashlib.sha256("\0".join(parts).encode()).hexdigest()

    def make() -> tuple[tuple[ca.Function, ...], dict]:
        functions, (jac, hess) = stage_derivatives(group, width)
        return functions, {"jac": _triplet(jac), "hess": _triplet(hess)}

    return Recipe(fingerprint, make)


def _local_to_global(stage: int, width: int, local: np.ndarray) -> np.ndarray:
    """Columns of (z_k, z_{k+1}) (or of z_k) -> indices of x."""
    return stage * width + local


class StageNLP:
    """The NLP of :mod:`locoman.to` with its IPOPT solver, built once.

    Args:
        width: Variables per node.
        nodes: N.
        n_params: Parameters per node.
        n_theta: Global parameters (theta, shared by every node).
        groups: Every stage 0 .. N - 2 in exactly one stage group, and any node groups.
        ipopt: IPOPT options.
        cache_dir: Where the groups' compiled derivatives are cached, one library per
            group; None runs them interpreted.
        compile_flags: The C compiler's flags.
    """

    def __init__(
        self,
        width: int,
        nodes: int,
        n_params: int,
        n_theta: int,
        groups: Sequence[StageGroup],
        ipopt: dict,
        cache_dir: Path | None = None,
        compile_flags: Sequence[str] = ("-O0",),
    ) -> None:
        tic = time.perf_counter()
        covered = np.sort(np.concatenate([g.stages for g in groups if g.span == 2]))
        if not np.array_equal(covered, np.arange(nodes - 1)):
            raise SolverBuildError("every stage 0 .. N-2 must be in exactly one group")
        self.width, self.nodes, self.n_params, self.n_theta = width, nodes, n_params, n_theta
        self.groups = list(groups)
        if cache_dir is None:
            derivs = [stage_derivatives(g, width) for g in self.groups]
        else:
            recipes = [derivative_recipe(g, width) for g in self.groups]
            loaded = load_or_compile(recipes, cache_dir, compile_flags)
            derivs = [(fns, _sparsities(data)) for fns, data in loaded]
        per_group = [fns for fns, _ in derivs]
        self.n_x = width * nodes
        X, P = ca.MX.sym("x", self.n_x), ca.MX.sym("p", n_params * nodes + n_theta)
        self.n_g = sum(len(g.stages) * g.rows for g in self.groups)
        lam_f, lam_g = ca.MX.sym("lam_f"), ca.MX.sym("lam_g", self.n_g)
        Z = ca.reshape(X, width, nodes)
        Pm = ca.reshape(P[: n_params * nodes], n_params, nodes)
        theta = P[n_params * nodes :]
        g_parts, cost, jac_parts, grad_parts, hess_parts = [], 0, [], [], []
        g_jac_parts, cost_grad = [], 0
        jac_trip: list[np.ndarray] = [[], []]
        grad_idx, hess_trip = [], [[], []]
        row = 0
        lower, upper = [], []
        for group, (val, jac_fn, grad_fn, hess_fn), (_, (jsp, hsp)) in zip(
            self.groups, per_group, derivs, strict=True
        ):
            k = np.asarray(group.stages, dtype=int)
            n = len(k)
            cols = [list(k + i) for i in range(group.span)]
            # theta has one column: map() hands the same to every call.
            args = [Z[:, c] for c in cols] + [Pm[:, c] for c in cols] + [theta]
            g, l = val.map(n)(*args)
            g_parts.append(ca.vec(g))
            cost += ca.sum2(l)
            g_jac, jnz = jac_fn.map(n)(*args)
            g_jac_parts.append(ca.vec(g_jac))
            jac_parts.append(ca.vec(jnz))
            jr, jc = jsp.get_triplet()
            for c, stage in enumerate(k):
                jac_trip[0].append(row + c * group.rows + np.asarray(jr, dtype=int))
                jac_trip[1].append(_local_to_global(stage, width, np.asarray(jc, dtype=int)))
            l_grad, gr = grad_fn.map(n)(*args)
            cost_grad += ca.sum2(l_grad)
            grad_parts.append(ca.vec(gr))
            for stage in k:
                grad_idx.append(_local_to_global(stage, width, np.arange(group.span * width)))
            lam = ca.reshape(lam_g[row : row + n * group.rows], group.rows, n)
            hnz = hess_fn.map(n)(*args, lam, ca.repmat(lam_f, 1, n))
            hess_parts.append(ca.vec(hnz))
            hr, hc = hsp.get_triplet()
            for stage in k:
                hess_trip[0].append(_local_to_global(stage, width, np.asarray(hr, dtype=int)))
                hess_trip[1].append(_local_to_global(stage, width, np.asarray(hc, dtype=int)))
            lower.append(np.tile(group.lower, n))
            upper.append(np.tile(group.upper, n))
            row += n * group.rows
        self.lbg, self.ubg = np.concatenate(lower), np.concatenate(upper)
        G = ca.vertcat(*g_parts)
        hess_nz = ca.vertcat(*hess_parts)

        jrows, jcols = np.concatenate(jac_trip[0]), np.concatenate(jac_trip[1])
        jsp_all, jmap = ca.Sparsity.triplet(self.n_g, self.n_x, jrows, jcols, True)
        order = np.empty(len(jmap), dtype=int)
        order[np.asarray(jmap, dtype=int)] = np.arange(len(jmap))
        jac = ca.MX(jsp_all, ca.vertcat(*jac_parts)[list(order)])

        gidx = np.concatenate(grad_idx)
        grad_sum = _summing_matrix(gidx, np.arange(len(gidx)), self.n_x)
        grad = ca.mtimes(grad_sum, ca.vertcat(*grad_parts))

        hrows, hcols = np.concatenate(hess_trip[0]), np.concatenate(hess_trip[1])
        hsp_all, hmap = ca.Sparsity.triplet(self.n_x, self.n_x, hrows, hcols, True)
        hmap = np.asarray(hmap, dtype=int)
        hess_sum = _summing_matrix(hmap, np.arange(len(hmap)), hsp_all.nnz())
        hess = ca.MX(hsp_all, ca.mtimes(hess_sum, hess_nz))

        self.oracles = {
            "jac_g": ca.Function(
                "jac_g", [X, P], [ca.vertcat(*g_jac_parts), jac], ["x", "p"], ["g", "jac_g_x"]
            ),
            "grad_f": ca.Function(
                "grad_f", [X, P], [cost_grad, grad], ["x", "p"], ["f", "grad_f_x"]
            ),
            "hess_lag": ca.Function(
                "hess_lag",
                [X, P, lam_f, lam_g],
                [hess],
                ["x", "p", "lam_f", "lam_g"],
                ["triu_hess_gamma_x_x"],
            ),
        }
        self._problem = {"x": X, "p": P, "f": cost, "g": G}
        self._options = dict(ipopt)
        self.solver = self.ipopt(ipopt)
        self._warm_solver: ca.Function | None = None
        _single_threaded_blas()
        self.build_time_s = time.perf_counter() - tic

    def ipopt(self, options: dict) -> ca.Function:
        """An IPOPT instance on this NLP's oracles with ``options``; set it as
        :attr:`solver` to solve with other options without rebuilding."""
        opts = {"print_time": False, "calc_lam_p": False, "ipopt": options, **self.oracles}
        return ca.nlpsol("to", "ipopt", self._problem, opts)

    def solve(
        self,
        x0: np.ndarray,
        lbx: np.ndarray,
        ubx: np.ndarray,
        params: np.ndarray,
        theta: np.ndarray,
        warm: WarmStart | None = None,
        limits: dict | None = None,
    ) -> NLPResult:
        """Solve from ``x0``, or from ``warm``'s primal-dual point (IPOPT's warm start);
        ``params`` is (n_params, N), ``theta`` (n_theta,); ``limits``: IPOPT options for
        this solve only (``max_iter``, ``max_wall_time``). A failed solve is returned with
        IPOPT's status, not raised."""
        if theta.shape != (self.n_theta,):
            raise SolverBuildError(
                f"theta has shape {theta.shape}; this NLP was built for ({self.n_theta},)"
            )
        p = np.r_[params.ravel(order="F"), theta]
        args = {"x0": x0, "lbx": lbx, "ubx": ubx, "lbg": self.lbg, "ubg": self.ubg, "p": p}
        solver = self.solver
        if warm is not None:
            if warm.x.shape != (self.n_x,) or warm.lam_g.shape != (self.n_g,):
                raise SolverBuildError("the warm start is of an NLP of another structure")
            if self._warm_solver is None:
                self._warm_solver = self.ipopt(self._options | WARM_START_OPTIONS)
            solver = self._warm_solver
            x_start = np.clip(warm.x, lbx, ubx)
            args |= {"x0": x_start, "lam_x0": warm.lam_x, "lam_g0": warm.lam_g}
        if limits:
            options = self._options | (WARM_START_OPTIONS if warm is not None else {})
            solver = self.ipopt(options | limits)
        tic = time.perf_counter()
        with _heap_kept():
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
        )


def _single_threaded_blas() -> None:
    """Run IPOPT's MUMPS on one thread of CasADi's OpenBLAS. With one per core, parallel
    sums change the last bits of each factorisation and the iterates follow: on ``tiny``
    2 threads took 808 iterations where 1 took 225, to the same optimum. One thread makes
    the solve independent of the machine's core count, and on 2 cores it is faster."""
    library = Path(ca.__file__).parent / "libcasadi-tp-openblas.so.0"
    if library.is_file():
        ctypes.CDLL(str(library)).openblas_set_num_threads(1)


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


def _summing_matrix(target: np.ndarray, source: np.ndarray, size: int) -> ca.DM:
    """Constant 0/1 matrix S with S[target[i], source[i]] = 1: S @ values sums the values
    that land on the same entry."""
    mat = sps.csc_matrix((np.ones(len(target)), (target, source)), shape=(size, len(source)))
    mat.sum_duplicates()
    return ca.DM(ca.Sparsity(size, len(source), mat.indptr, mat.indices), mat.data)
