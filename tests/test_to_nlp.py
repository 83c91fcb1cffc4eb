"""The stage NLP's assembled derivatives against CasADi's own, on a small random problem:
exact, but for the residuals' Gauss-Newton Hessian."""

from __future__ import annotations

import dataclasses
import shutil

import casadi as ca
import numpy as np
import pytest

from locoman.to.nlp import SolverBuildError, StageGroup, StageNLP

WIDTH, NODES, PARAMS, THETA = 3, 6, 2, 2


def _groups() -> list[StageGroup]:
    z, z1 = ca.SX.sym("z", WIDTH), ca.SX.sym("z1", WIDTH)
    p, p1 = ca.SX.sym("p", PARAMS), ca.SX.sym("p1", PARAMS)
    theta = ca.SX.sym("theta", THETA)
    g_a = ca.vertcat(
        z1[0] - z[0] - ca.sin(z[1]) * p[0], z1[2] * z[2] - p[1] * theta[0], z[0] ** 2 + z1[1]
    )
    l_a = ca.sumsqr(z - p[0]) + z[0] * z1[2] ** 2
    g_b = ca.vertcat(z1[0] - z[0] * z[2], ca.cos(z1[1]) + z[1])
    l_b = ca.sumsqr(z1) * p1[1] + ca.exp(theta[1] * z[2])
    r_a = ca.vertcat(ca.fmin(z[1] * z1[2] - p[1], 0.0), ca.sin(z[0]) * p1[0])
    fa = ca.Function("stage_a", [z, z1, p, p1, theta], [g_a, l_a, r_a])
    fb = ca.Function("stage_b", [z, z1, p, p1, theta], [g_b, l_b, ca.SX(0, 1)])
    g_n = ca.vertcat(z[0] * ca.sin(z[2]) - p[0], z[1] ** 3)
    r_n = ca.cos(z[2]) * z[1]
    l_n = ca.exp(z[0] * p[1]) + z[1] * z[2] * theta[0]
    fn = ca.Function("node", [z, p, theta], [g_n, l_n, r_n])
    return [
        StageGroup(fa, np.array([0, 2, 3]), np.zeros(3), np.array([0.0, 0.0, np.inf])),
        StageGroup(fb, np.array([1, 4]), np.zeros(2), np.zeros(2)),
        StageGroup(fn, np.arange(NODES), np.zeros(2), np.full(2, np.inf)),
    ]


def _reference(groups: list[StageGroup]):
    """The same NLP written out stage by stage: constraints, smooth cost, residuals."""
    x, p = ca.SX.sym("x", WIDTH * NODES), ca.SX.sym("p", PARAMS * NODES + THETA)
    Z, P = ca.reshape(x, WIDTH, NODES), ca.reshape(p[: PARAMS * NODES], PARAMS, NODES)
    theta = p[PARAMS * NODES :]
    g, f, r = [], 0, []
    for group in groups:
        for k in group.stages:
            cols = range(k, k + group.span)
            gk, lk, rk = group.function(*[Z[:, c] for c in cols], *[P[:, c] for c in cols], theta)
            g.append(gk)
            f += lk
            r.append(rk)
    return x, p, ca.vertcat(*g), f, ca.vertcat(*r)


@pytest.mark.parametrize(
    ("compiled", "curvature", "residuals"),
    [
        (False, True, False),
        (True, True, False),
        (False, False, False),
        (False, True, True),
        (True, True, True),
    ],
)
def test_assembled_derivatives_match_casadi(
    compiled: bool, curvature: bool, residuals: bool, tmp_path
) -> None:
    """Without ``curvature`` (the TO's Gauss-Newton default) the Hessian leaves out the
    constraints' second derivatives lambda' nabla^2 g; without ``residuals`` the penalties'
    r nabla^2 r; with both (the exact phase) it is the Lagrangian's exact Hessian."""
    if compiled and shutil.which("gcc") is None:
        pytest.skip("no C compiler")
    groups = [
        dataclasses.replace(g, constraint_curvature=curvature, residual_curvature=residuals)
        for g in _groups()
    ]
    cache = tmp_path if compiled else None
    nlp = StageNLP(WIDTH, NODES, PARAMS, THETA, groups, {"print_level": 0, "sb": "yes"}, cache)
    if compiled:  # the second build loads the libraries and sparsities from the cache's index
        assert len(list(tmp_path.glob("index_*.json"))) == len(groups)
        nlp = StageNLP(WIDTH, NODES, PARAMS, THETA, groups, {"print_level": 0, "sb": "yes"}, cache)
    x, p, g, f_smooth, r = _reference(groups)
    f = f_smooth + ca.sumsqr(r)
    lam_f, lam_g = ca.SX.sym("lf"), ca.SX.sym("lg", g.numel())
    rng = np.random.default_rng(0)
    xv, pv = rng.normal(size=x.numel()), rng.normal(size=p.numel())
    lfv, lgv = 0.7, rng.normal(size=g.numel())
    ref_jac = ca.Function("j", [x, p], [ca.jacobian(g, x)])(xv, pv)
    ref_grad = ca.Function("gr", [x, p], [ca.gradient(f, x)])(xv, pv)
    jac_r = ca.jacobian(r, x)
    constraints = ca.dot(lam_g, g) if curvature else 0.0
    gauss_newton = ca.hessian(lam_f * f_smooth + constraints, x)[0] + 2 * lam_f * (jac_r.T @ jac_r)
    exact = ca.hessian(lam_f * f + constraints, x)[0]
    reference = exact if residuals else gauss_newton
    ref_hess = ca.Function("h", [x, p, lam_f, lam_g], [reference])(xv, pv, lfv, lgv)
    g_val, jac = nlp.oracles["jac_g"](xv, pv)
    f_val, grad = nlp.oracles["grad_f"](xv, pv)
    hess = nlp.oracles["hess_lag"](xv, pv, lfv, lgv)
    np.testing.assert_allclose(
        np.asarray(g_val).ravel(),
        np.asarray(ca.Function("g", [x, p], [g])(xv, pv)).ravel(),
        atol=1e-12,
    )
    np.testing.assert_allclose(
        float(f_val), float(ca.Function("f", [x, p], [f])(xv, pv)), atol=1e-12
    )
    np.testing.assert_allclose(
        np.asarray(ca.densify(jac)), np.asarray(ca.densify(ref_jac)), atol=1e-12
    )
    np.testing.assert_allclose(np.asarray(grad).ravel(), np.asarray(ref_grad).ravel(), atol=1e-12)
    np.testing.assert_allclose(
        np.asarray(ca.densify(hess)), np.triu(np.asarray(ca.densify(ref_hess))), atol=1e-12
    )


def test_uncovered_stage_is_refused() -> None:
    groups = _groups()[:1] + _groups()[2:]
    with pytest.raises(SolverBuildError, match="every stage"):
        StageNLP(WIDTH, NODES, PARAMS, THETA, groups, {"print_level": 0})
