"""The projected Hessian: each term call's curvature projected onto the positive
semidefinite cone (:mod:`locoman.to.nlp.convexify`), against NumPy's eigendecomposition, and
assembled against the same NLP's Hessians computed call by call."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from test_to_assembly import N_X, RowSpace, _blocks, _virtual_problem

from locoman.to.nlp.convexify import block_pattern, project_psd
from locoman.to.nlp.derivatives import load_derivatives
from locoman.to.nlp.ipopt import BlockNLP, parameter_vector


def _psd(H: np.ndarray) -> np.ndarray:
    w, V = np.linalg.eigh(H)
    return V @ np.diag(np.maximum(w, 0.0)) @ V.T


def _symmetric(values: np.ndarray, m: int) -> np.ndarray:
    H = np.zeros((m, m))
    H[np.triu_indices(m)] = values
    return H + np.triu(H, 1).T


@settings(max_examples=50, deadline=None)
@given(arrays(np.float64, (3, 10), elements=st.floats(-1e3, 1e3)))
def test_each_call_is_projected_onto_the_psd_cone(values: np.ndarray) -> None:
    """Three 4 x 4 calls given as their upper triangles: each projection is the nearest
    positive semidefinite matrix, V max(Lambda, 0) V'."""
    rows, cols = np.triu_indices(4)
    projected = project_psd(values, block_pattern(rows, cols))
    for given_, got in zip(values, projected, strict=True):
        H = _symmetric(given_, 4)
        P = _symmetric(got, 4)
        np.testing.assert_allclose(P, _psd(H), atol=1e-9 * max(1.0, np.abs(H).max()))
        assert np.linalg.eigvalsh(P).min() >= -1e-9 * max(1.0, np.abs(H).max())


def test_uncoupled_inputs_are_projected_as_blocks_of_their_own():
    """A pattern coupling inputs 1 and 4, with 6 on its own: the blocks {6} and {1, 4}
    (dense), each projected alone; a positive semidefinite call comes back unchanged."""
    rows, cols = np.array([1, 1, 4, 6]), np.array([1, 4, 4, 6])
    blocks = block_pattern(rows, cols)
    assert list(zip(blocks.rows, blocks.cols, strict=True)) == [(6, 6), (1, 1), (1, 4), (4, 4)]
    calls = np.array([[2.0, 1.0, 3.0, 5.0], [1.0, 2.0, 1.0, -3.0]])
    out = project_psd(calls, blocks)
    np.testing.assert_allclose(out[0], [5.0, 2.0, 1.0, 3.0], atol=1e-12)
    # [[1, 2], [2, 1]]: eigenvalues 3 and -1, its projection 1.5 [[1, 1], [1, 1]].
    np.testing.assert_allclose(out[1], [0.0, 1.5, 1.5, 1.5], atol=1e-12)


def _call_hessian(term, xs, ps, lam, lam_f) -> np.ndarray:
    """One call's Hessian over its own inputs, as the projected flavour takes it: the exact
    one (Gauss-Newton for residuals without exact curvature), projected."""
    x = ca.SX.sym("x", term.nx)
    g, smooth, r = term.function(x, ps)
    jac_r = ca.jacobian(r, x)
    if term.exact_residuals:
        L = lam_f * (smooth + ca.sumsqr(r)) + ca.dot(ca.DM(lam), g)
        H = ca.hessian(L, x)[0]
    else:
        H = ca.hessian(lam_f * smooth + ca.dot(ca.DM(lam), g), x)[0] + 2 * lam_f * (jac_r.T @ jac_r)
    H = np.asarray(ca.Function("h", [x], [H])(np.zeros(term.nx) + xs))
    return _psd(H)


@pytest.mark.parametrize("compiled", [False, True])
def test_the_assembled_hessian_projects_each_call_before_the_sum(compiled: bool, tmp_path):
    """The projected flavour's Hessian is the sum of each call's projected Hessian, and
    positive semidefinite; the exact flavour's at the same point is not (else the test
    would not tell them apart)."""
    rows = RowSpace()
    blocks = _blocks(rows)
    derivatives = load_derivatives([b.term for b in blocks], tmp_path if compiled else None)
    opts = {"print_level": 0, "sb": "yes"}
    projected = BlockNLP(N_X, blocks, rows, derivatives, "projected", opts)
    exact = BlockNLP(N_X, blocks, rows, derivatives, "exact", opts)
    rng = np.random.default_rng(0)
    xv, pv = rng.normal(size=N_X), parameter_vector(blocks)
    lfv, lgv = 0.7, 3.0 * rng.normal(size=rows.size)
    reference = np.zeros((N_X, N_X))
    for block in blocks:
        for xs, ps, rws in zip(block.x, block.p, block.rows, strict=True):
            H = _call_hessian(block.term, xv[xs], ps, lgv[rws], lfv)
            reference[np.ix_(xs, xs)] += H
    got = np.asarray(ca.densify(projected.oracles["hess_lag"](xv, pv, lfv, lgv)))
    np.testing.assert_allclose(got, np.triu(reference), atol=1e-10)
    assert np.linalg.eigvalsh(reference).min() >= -1e-10
    H_exact = np.asarray(ca.densify(exact.oracles["hess_lag"](xv, pv, lfv, lgv)))
    assert np.linalg.eigvalsh(H_exact + np.triu(H_exact, 1).T).min() < -1e-3


def test_virtual_variables_curvature_is_projected_per_definition():
    """y = F(x) by two calls of a lifting term: H_x = P' H_z+ P + sum_j (sum_i mu_i
    nabla^2 F_i(x_j))+, mu = dL/dy, each call's and each definition's part projected on
    its own."""
    blocks, rows = _virtual_problem()
    lift, use = blocks
    derivatives = load_derivatives([b.term for b in blocks], None)
    nlp = BlockNLP(4, blocks, rows, derivatives, "projected", {"print_level": 0}, n_y=4)
    rng = np.random.default_rng(3)
    xv, lgv, lfv = rng.normal(size=4), 2.0 * rng.normal(size=2), 0.7
    u = ca.SX.sym("u", 2)
    F = -lift.term.function(ca.vertcat(u, ca.SX.zeros(2)), ca.SX(0, 1))[0]
    F_num = ca.Function("F", [u], [F, ca.jacobian(F, u)])
    z, P = np.zeros(8), np.zeros((8, 4))
    z[:4], P[:4] = xv, np.eye(4)
    for inputs in lift.x:
        y, J = F_num(xv[inputs[:2]])
        z[inputs[2:]], P[np.ix_(inputs[2:], inputs[:2])] = np.ravel(y), J
    # The using term's calls over z, and mu = dL/dy (its cost's gradient and its rows'
    # multipliers, on y).
    w, q, lam = (ca.SX.sym(n, k) for n, k in (("w", 3), ("q", 1), ("l", 1)))
    g, smooth, r = use.term.function(w, q)
    dL = ca.Function("dL", [w, q, lam], [ca.gradient(lfv * (smooth + ca.sumsqr(r)) + lam * g, w)])
    H_z, dL_dz = np.zeros((8, 8)), np.zeros(8)
    for xs, ps, rws in zip(use.x, use.p, use.rows, strict=True):
        H_z[np.ix_(xs, xs)] += _call_hessian(use.term, z[xs], ps, lgv[rws], lfv)
        dL_dz[xs] += np.ravel(dL(z[xs], ps, lgv[rws]))
    reference = P.T @ H_z @ P
    mu = ca.SX.sym("mu", 2)
    curvature = ca.Function("c", [u, mu], [ca.hessian(ca.dot(mu, F), u)[0]])
    for inputs in lift.x:
        C = np.asarray(curvature(xv[inputs[:2]], dL_dz[inputs[2:]]))
        reference[np.ix_(inputs[:2], inputs[:2])] += _psd(C)
    pv = parameter_vector(blocks)
    got = np.asarray(ca.densify(nlp.oracles["hess_lag"](xv, pv, lfv, lgv)))
    np.testing.assert_allclose(got, np.triu(reference), atol=1e-10)
    assert np.linalg.eigvalsh(reference).min() >= -1e-10
