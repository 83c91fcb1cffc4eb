"""The NLP's oracles, evaluated numerically from the compiled terms.

IPOPT asks for f, g, grad f, J_g and the Lagrangian's Hessian at each iterate. Each is the
terms' own (compiled, called over each block's calls on NumPy buffers, no copies), summed
into a fixed sparsity by constant index maps, and carried from z = (x, y) to x by the chain
rule through the virtual variables y = F(x) (:class:`locoman.to.nlp.ipopt.BlockNLP`), with
SciPy's sparse products:

    J_x = J_zx + J_zy P,   grad_x = grad_zx + P' grad_zy,
    H_x = H_xx + triu(H_xy P + P' H_yx) + triu(P' H_yy P)  (+ sum_i mu_i nabla^2 F_i).

In the ``projected`` flavour each call's Hessian (and each definition's sum
mu_i nabla^2 F_i) is projected onto the positive semidefinite cone first
(:mod:`locoman.to.nlp.convexify`).

Two things make this cheaper than the same sums as a CasADi MX graph (the numbers
are in docs/performance.md):

- **Calls far from contact are skipped.** A one-sided penalty (:attr:`Term.one_sided`, the
  collision penalties (12)) and its derivatives vanish together; a call whose cost is below
  :data:`NEGLIGIBLE_COST` adds less than rounding to any derivative, and its gradient and
  Hessian are not evaluated. At any iterate most collision pairs are far apart (on `tiny`'s
  solution 515 of 29 853 calls are within 9 cm), and their zeros then stay out of the sums
  and the chain rule's products. f still sums every call.
- **One iterate, one evaluation.** The virtual variables, their Jacobian P and each term's
  values at a point are kept for the oracles that IPOPT calls at the same point.
"""

from __future__ import annotations

from collections.abc import Sequence

import casadi as ca
import numpy as np
import scipy.sparse as sps

from locoman.errors import SolverBuildError
from locoman.to.nlp.callback import OracleCallback
from locoman.to.nlp.convexify import block_pattern, project_psd
from locoman.to.nlp.oracle_state import BlockCalls, Definition, Point
from locoman.to.nlp.sparsity import Mapped, Pattern, joined, split_at, structural

# [cost units] A one-sided penalty's call whose cost ||r||^2 is below this is skipped in the
# derivatives: its gradient is about 2 ||r||^2 / softness, below 1e-17 (softness >= 1 mm).
NEGLIGIBLE_COST = 1e-20


class Oracles:
    """f, g and the derivatives of the NLP of ``blocks`` (:class:`BlockNLP`'s arguments)."""

    def __init__(
        self,
        n_x: int,
        blocks: Sequence,
        n_g: int,
        derivatives: dict,
        hessian: str,
        n_y: int,
        previous: Oracles | None = None,
    ) -> None:
        """``previous``: the oracles of an earlier NLP (a round of found pairs before this
        one). Where its blocks are the first calls of these, with the same Hessian, its
        patterns are extended by the new calls instead of made again (:meth:`_carried`);
        the patterns are the same either way."""
        self.project = hessian == "projected"
        self.flavour = hessian
        # The terms' flavour: the projected Hessian projects the exact one's calls.
        hessian = "exact" if self.project else hessian
        self.n_x, self.n_y, self.n_g, self.hessian = n_x, n_y, n_g, hessian
        n_z = n_x + n_y
        offsets = np.cumsum([0] + [b.p.size for b in blocks])
        definitions, calls = [], []
        for block, start in zip(blocks, offsets, strict=False):
            if not block.calls:
                continue
            params = slice(int(start), int(start) + block.p.size)
            d = derivatives[block.term.name]
            if block.defines:
                definitions.append(self._definition(block, params, d))
            else:
                calls.append((block, params, d))
        self._definitions = definitions
        target = joined([e.lifted.ravel() for e in definitions])
        if len(np.unique(target)) != len(target) or len(target) != n_y:
            raise SolverBuildError("every virtual variable must be defined exactly once")
        carried = self._carried(previous, [block for block, _, _ in calls])
        # Patterns of the terms' triplets: J_z (n_g, n_z), H_z upper (n_z, n_z), P (n_y, n_x).
        jac_r, jac_c, hess_r, hess_c, projected, widths = [], [], [], [], [], []
        for (block, _, d), before in zip(calls, carried or [None] * len(calls), strict=True):
            if block.term.ng:
                jr, jc = d.jac_pattern
                jac_r.append(block.rows[:, jr].ravel())
                jac_c.append(block.x[:, jc].ravel())
            hr, hc = d.hess_pattern[hessian]
            dense = block_pattern(hr, hc) if self.project and len(hr) else None
            if dense is not None:
                hr, hc = dense.rows, dense.cols
            projected.append(dense)
            # A carried block's first calls are in the previous pattern already.
            widths.append(len(hr))
            a, b = (block.x[before.block.calls if before else 0 :, i] for i in (hr, hc))
            hess_r.append(np.minimum(a, b).ravel())
            hess_c.append(np.maximum(a, b).ravel())
        self.J_z = Pattern(joined(jac_r), joined(jac_c), (n_g, n_z))
        hess_rc = joined(hess_r), joined(hess_c)
        if carried is None:
            self.H_z, self._moved = Pattern(*hess_rc, (n_z, n_z)), None
        else:
            self.H_z, self._moved = previous.H_z.extended(*hess_rc, (n_z, n_z))
        jac_at = split_at(self.J_z.where, [len(r) for r in jac_r])
        hess_at = split_at(self.H_z.where, [len(r) for r in hess_r])
        self._calls: list[BlockCalls] = []
        for (block, params, d), dense, before, width in zip(
            calls, projected, carried or [None] * len(calls), widths, strict=True
        ):
            n = block.calls
            has_hess = len(d.hess_pattern[hessian][0]) > 0
            at = next(hess_at).reshape(n - (before.block.calls if before else 0), width)
            if before is not None:
                at = np.vstack([self._moved[before.hess_at], at])
            self._calls.append(
                BlockCalls(
                    block,
                    params,
                    Mapped(d.val, n),
                    Mapped(d.grad, n),
                    Mapped(d.jac, n) if block.term.ng else None,
                    Mapped(d.hess[hessian], n) if has_hess else None,
                    at,
                    next(jac_at).reshape(n, -1) if block.term.ng else np.zeros((n, 0), int),
                    dense,
                )
            )
        self._point: Point | None = None
        defined = self._carried(previous, [e.block for e in definitions], "_definitions")
        if carried is None or defined is None:
            self._structure(None, [None] * len(definitions))
        else:
            self._structure(previous, defined)

    def _carried(self, previous: Oracles | None, blocks: list, kept: str = "_calls") -> list | None:
        """For each of ``blocks``, the entry of ``previous``'s ``kept`` whose calls are its
        first calls (the same term, the same variables; matched in order per term), or
        None where the block is new. None when ``previous`` is of another Hessian or size,
        or when one of its entries is not among ``blocks`` (its pattern would hold entries
        these do not)."""
        if previous is None or (previous.flavour, previous.n_x) != (self.flavour, self.n_x):
            return None
        waiting: dict[str, list] = {}
        for entry in reversed(getattr(previous, kept)):
            waiting.setdefault(entry.block.term.name, []).append(entry)
        carried = []
        for block in blocks:
            queue = waiting.get(block.term.name)
            before = queue.pop() if queue else None
            if before is not None:
                n = before.block.calls
                if n > block.calls or not np.array_equal(before.block.x, block.x[:n]):
                    return None
            carried.append(before)
        return None if any(waiting.values()) else carried

    def _definition(self, block, params: slice, d) -> Definition:
        term, n_x = block.term, self.n_x
        n_in = term.nx - term.ng
        inputs, lifted = block.x[:, :n_in], block.x[:, n_in:] - n_x
        if inputs.max(initial=-1) >= n_x or lifted.min(initial=0) < 0:
            raise SolverBuildError(f"{term.name}: a virtual variable of real ones only")
        jr, jc = d.jac_pattern
        keep = np.flatnonzero(jc < n_in)
        hr, hc = d.hess_pattern["exact"]
        hess_keep = np.flatnonzero((hr < n_in) & (hc < n_in))
        exact = self.hessian == "exact" and len(hess_keep) > 0
        dense = block_pattern(hr[hess_keep], hc[hess_keep]) if self.project and exact else None
        kept_rows, kept_cols = (dense.rows, dense.cols) if dense else (hr[hess_keep], hc[hess_keep])
        a, b = inputs[:, kept_rows], inputs[:, kept_cols]
        return Definition(
            block,
            params,
            inputs,
            lifted,
            Mapped(d.val, block.calls),
            Mapped(d.jac, block.calls),
            Mapped(d.hess["exact"], block.calls) if exact else None,
            keep,
            np.stack([lifted[:, jr[keep]], inputs[:, jc[keep]]]),
            hess_keep,
            np.minimum(a, b),
            np.maximum(a, b),
            dense,
        )

    def _structure(self, previous: Oracles | None, defined: list) -> None:
        """P's pattern and the outputs' (over x): the same products on ones. ``previous``:
        oracles whose calls and definitions (``defined``: each definition's, or None) are
        these' first, so whose P is this P on its rows and whose H_z and H_x are within
        these: P and H_x are theirs and what the new calls add."""
        n_x, n_y = self.n_x, self.n_y
        # Each definition's entries of P, after those of its previous calls.
        new = [
            e.jac_at[:, before.block.calls if before else 0 :].reshape(2, -1)
            for e, before in zip(self._definitions, defined, strict=True)
        ]
        rows, cols = joined([n[0] for n in new]), joined([n[1] for n in new])
        if previous is None:
            self.P = Pattern(rows, cols, (n_y, n_x))
        else:
            self.P, moved = previous.P.extended(rows, cols, (n_y, n_x))
            owned = dict(zip(map(id, previous._definitions), previous._p_at(), strict=True))
            fresh = split_at(self.P.where, [n.shape[1] for n in new])
            self.P.where = joined(
                [
                    np.r_[moved[owned[id(before)]], next(fresh)] if before else next(fresh)
                    for before in defined
                ]
            )
        ones = self.P.matrix(np.ones(self.P.nnz))
        J_z = self.J_z.matrix(np.ones(self.J_z.nnz))
        self.J_x = structural(J_z[:, :n_x] + J_z[:, n_x:] @ ones if n_y else J_z)
        if previous is not None and np.array_equal(self.J_x._linear, previous.J_x._linear):
            self.J_x = previous.J_x  # and its CasADi sparsity, made once
        added = np.ones(self.H_z.nnz)
        if previous is not None:
            added[self._moved] = 0.0
        H_z = self.H_z.matrix(added)
        H_z.eliminate_zeros()
        H_x = self._chain_rule(H_z, ones)
        if previous is not None:
            H_x = H_x + previous.H_x.matrix(np.ones(previous.H_x.nnz))
        if self.hessian == "exact":
            rows, cols = (
                joined(
                    [
                        getattr(e, side)[before.block.calls if before else 0 :].ravel()
                        for e, before in zip(self._definitions, defined, strict=True)
                    ]
                )
                for side in ("hess_rows", "hess_cols")
            )
            H_x = H_x + sps.csc_matrix((np.ones(len(rows)), (rows, cols)), shape=(n_x, n_x))
        self.H_x = structural(H_x)

    def _p_at(self) -> list[np.ndarray]:
        """Each definition's entries' positions in P, in its calls' order."""
        return list(split_at(self.P.where, [e.jac_at[0].size for e in self._definitions]))

    def _chain_rule(self, H_z: sps.csc_matrix, P: sps.csc_matrix) -> sps.csc_matrix:
        """triu(H_x) from the upper triangle of H_z and P = dy/dx."""
        n_x = self.n_x
        if not self.n_y:
            return sps.triu(H_z, format="csc")
        full = (H_z + sps.triu(H_z, k=1, format="csc").T).tocsc()
        cross = full[:n_x, n_x:] @ P
        curvature = P.T @ (full[n_x:, n_x:] @ P)
        return sps.triu(full[:n_x, :n_x] + cross + cross.T + curvature, format="csc")

    # -- one point --------------------------------------------------------------------

    def _at(self, x: np.ndarray, p: np.ndarray) -> Point:
        """The shared evaluation at (x, p), kept for the next oracle at the same point."""
        point = self._point
        if point is not None and np.array_equal(point.x, x) and np.array_equal(point.p, p):
            return point
        point = Point(x, p)
        # The point's own copies: x and p may be views of CasADi's buffers, gone after
        # the call, and the point's inputs are slices of them.
        x, p = point.x, point.p
        z = np.zeros(self.n_x + self.n_y)
        z[: self.n_x] = x
        for e in self._definitions:
            n = e.block.calls
            xb = np.hstack([z[e.inputs], np.zeros((n, e.lifted.shape[1]))])
            pb = p[e.params].reshape(n, -1)
            g, _ = e.val(xb, pb)
            z[self.n_x + e.lifted.ravel()] = -g.ravel()
            point.definitions.append((xb, pb))
        g_parts, g_rows, f = [], [], 0.0
        for c in self._calls:
            n = c.block.calls
            xb, pb = z[c.block.x], p[c.params].reshape(n, -1)
            g, cost = c.val(xb, pb)
            cost = cost.ravel()
            f += float(np.sum(cost))
            point.inputs.append((xb, pb))
            one_sided = c.block.term.one_sided
            point.active.append(np.flatnonzero(cost >= NEGLIGIBLE_COST) if one_sided else None)
            if c.block.term.ng:
                g_parts.append(g.ravel())
                g_rows.append(c.block.rows.ravel())
        point.f = f
        point.g = np.bincount(joined(g_rows), joined(g_parts, float), minlength=self.n_g)
        self._point = point
        return point

    def _prolongation(self, point: Point) -> sps.csc_matrix:
        """P = dy/dx at the point: the derivatives' business only, so f and g at a trial
        point of IPOPT's line search do without it."""
        if point.P is None:
            values = []
            for e, (xb, pb) in zip(self._definitions, point.definitions, strict=True):
                _, jnz = e.jac(xb, pb)
                values.append(-jnz[:, e.jac_keep].ravel())
            # The rows of a definition are its own: every nonzero of P comes from one call.
            data = np.zeros(self.P.nnz)
            data[self.P.where] = joined(values, float)
            point.P = self.P.matrix(data)
            point.P.eliminate_zeros()
        return point.P

    def _gradient_z(self, point: Point) -> np.ndarray:
        if point.gradient is None:
            index, values = [], []
            for c, (xb, pb), active in zip(self._calls, point.inputs, point.active, strict=True):
                if active is None:
                    _, grad = c.grad(xb, pb)
                    index.append(c.block.x.ravel())
                elif len(active):
                    _, grad = c.grad.some(len(active), xb[active], pb[active])
                    index.append(c.block.x[active].ravel())
                else:
                    continue
                values.append(grad.ravel())
            n_z = self.n_x + self.n_y
            point.gradient = np.bincount(joined(index), joined(values, float), minlength=n_z)
        return point.gradient

    def _jacobian_z(self, point: Point) -> sps.csc_matrix:
        if point.jacobian is None:
            index, values = [], []
            for c, (xb, pb) in zip(self._calls, point.inputs, strict=True):
                if c.jac is None:
                    continue
                _, jnz = c.jac(xb, pb)
                index.append(c.jac_at.ravel())
                values.append(jnz.ravel())
            data = np.bincount(joined(index), joined(values, float), minlength=self.J_z.nnz)
            point.jacobian = self.J_z.matrix(data)
        return point.jacobian

    # -- the oracles ------------------------------------------------------------------

    def fg(self, x: np.ndarray, p: np.ndarray) -> tuple[float, np.ndarray]:
        point = self._at(x, p)
        return point.f, point.g

    def grad_f(self, x: np.ndarray, p: np.ndarray) -> tuple[float, np.ndarray]:
        point = self._at(x, p)
        grad = self._gradient_z(point)
        if self.n_y:
            return point.f, grad[: self.n_x] + self._prolongation(point).T @ grad[self.n_x :]
        return point.f, grad

    def jac_g(self, x: np.ndarray, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        point = self._at(x, p)
        J = self._jacobian_z(point)
        if self.n_y:
            J = J[:, : self.n_x] + J[:, self.n_x :] @ self._prolongation(point)
        return point.g, self.J_x.values(J)

    def hess_lag(self, x: np.ndarray, p: np.ndarray, lam_f: float, lam_g: np.ndarray) -> np.ndarray:
        point = self._at(x, p)
        index, values = [], []
        for c, (xb, pb), active in zip(self._calls, point.inputs, point.active, strict=True):
            if c.hess is None:
                continue
            calls = slice(None) if active is None else active
            count = c.block.calls if active is None else len(active)
            if not count:
                continue
            lam = lam_g[c.block.rows[calls]]
            sigma = np.full(count, lam_f)
            (hnz,) = c.hess.some(count, xb[calls], pb[calls], lam, sigma)
            if c.projected is not None:
                hnz = project_psd(hnz, c.projected)
            index.append(c.hess_at[calls].ravel())
            values.append(hnz.ravel())
        data = np.bincount(joined(index), joined(values, float), minlength=self.H_z.nnz)
        H_z = self.H_z.matrix(data)
        H_z.eliminate_zeros()
        H_x = self._chain_rule(H_z, self._prolongation(point))
        if self.hessian == "exact" and self.n_y:
            H_x = H_x + self._curvature(point, lam_f, lam_g)
        return self.H_x.values(H_x)

    def _curvature(self, point: Point, lam_f: float, lam_g: np.ndarray) -> sps.csc_matrix:
        """sum_i mu_i nabla^2 F_i(x) with mu = dL/dy, over the defining calls with mu != 0
        (a sphere whose every pair is far has none)."""
        n_x = self.n_x
        J_y = self._jacobian_z(point)[:, n_x:]
        mu = lam_f * self._gradient_z(point)[n_x:] + J_y.T @ lam_g
        rows, cols, values = [], [], []
        for e, (xb, pb) in zip(self._definitions, point.definitions, strict=True):
            if e.hess is None:
                continue
            lam = -mu[e.lifted]
            calls = np.flatnonzero(np.any(lam != 0.0, axis=1))
            if not len(calls):
                continue
            sigma = np.full(len(calls), lam_f)
            (hnz,) = e.hess.some(len(calls), xb[calls], pb[calls], lam[calls], sigma)
            curvature = hnz[:, e.hess_keep]
            if e.projected is not None:
                curvature = project_psd(curvature, e.projected)
            values.append(curvature.ravel())
            rows.append(e.hess_rows[calls].ravel())
            cols.append(e.hess_cols[calls].ravel())
        shape = (n_x, n_x)
        return sps.csc_matrix((joined(values, float), (joined(rows), joined(cols))), shape=shape)


def unavailable_jacobian(
    inputs: Sequence[tuple[str, ca.Sparsity]], outputs: Sequence[tuple[str, ca.Sparsity]]
) -> OracleCallback:
    """The Jacobian of a function whose derivatives IPOPT takes from the oracles instead:
    nlpsol builds the problem's gradient at set-up (for multipliers the TO does not ask
    for) and never calls it. Its pattern is empty; a call fails, naming what to use."""

    def refuse(*_):
        raise SolverBuildError(
            "the NLP's derivatives come from its oracles (jac_g, grad_f, hess_lag); its "
            "problem function has none of its own"
        )

    ins = [*inputs, *((f"out_{n}", sp) for n, sp in outputs)]
    outs = [
        (f"jac_{o}_{i}", ca.Sparsity(so.nnz(), si.nnz())) for o, so in outputs for i, si in inputs
    ]
    return OracleCallback("unavailable_jacobian", ins, outs, refuse)
