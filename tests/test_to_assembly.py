"""The NLP assembled from term calls against CasADi's own derivatives of the same NLP, on a
small random problem whose terms share constraint rows, skip variables and overlap: exact,
but for the residuals' Gauss-Newton Hessian where a flavour asks for it."""

from __future__ import annotations

import dataclasses
import logging
import re

import casadi as ca
import numpy as np
import pytest

from locoman.errors import SolverBuildError
from locoman.to.nlp.derivatives import load_derivatives
from locoman.to.nlp.ipopt import BlockNLP, parameter_vector, structure_key
from locoman.to.nlp.multipliers import WarmStart, carried_multipliers, row_owners
from locoman.to.terms.term import Block, RowSpace, Term

N_X = 9  # x[8] is in no term: its gradient is a zero IPOPT must see as such


def _terms() -> list[Term]:
    x, p = ca.SX.sym("x", 3), ca.SX.sym("p", 2)
    a = ca.Function(
        "a",
        [x, p],
        [
            ca.vertcat(x[1] - x[0] - ca.sin(x[2]) * p[0], x[2] * x[0] - p[1]),
            ca.sumsqr(x - p[0]) + x[0] * x[2] ** 2,
            ca.vertcat(ca.fmin(x[1] * x[2] - p[1], 0.0), ca.sin(x[0]) * p[0]),
        ],
    )
    y, q = ca.SX.sym("y", 2), ca.SX.sym("q", 1)
    share = ca.Function(
        "share", [y, q], [ca.vertcat(q * y[0] * y[1], ca.cos(y[1])), 0, ca.SX(0, 1)]
    )
    cost = ca.Function("cost", [y, q], [ca.SX(0, 1), ca.exp(q * y[0]) * y[1], ca.cos(y[1]) * y[0]])
    return [Term(a), Term(share), Term(cost, exact_residuals=False)]


def _blocks(rows: RowSpace) -> list[Block]:
    a, share, cost = _terms()
    rng = np.random.default_rng(1)
    own = rows.allocate(3, np.zeros(2), np.array([0.0, np.inf]))
    return [
        Block(a, np.array([[0, 1, 2], [3, 4, 5], [5, 6, 7]]), rng.normal(size=(3, 2)), own),
        # Adds onto a's rows of calls 0 and 2.
        Block(share, np.array([[2, 4], [6, 0]]), rng.normal(size=(2, 1)), own[[0, 2]]),
        Block(cost, np.array([[1, 7], [4, 3]]), rng.normal(size=(2, 1)), np.zeros((2, 0), int)),
    ]


def _reference(blocks: list[Block], n_g: int):
    """The same NLP written out call by call: constraints, smooth cost, residuals, and the
    residuals whose curvature the exact Hessian leaves out."""
    x = ca.SX.sym("x", N_X)
    g = [ca.SX(0)] * n_g
    f, r, r_gn = 0, [], []
    for block in blocks:
        for xs, ps, rows in zip(block.x, block.p, block.rows, strict=True):
            gk, lk, rk = block.term.function(x[xs.tolist()], ps)
            for i, row in enumerate(rows):
                g[row] += gk[i]
            f += lk
            (r if block.term.exact_residuals else r_gn).append(rk)
    return x, ca.vertcat(*g), f, ca.vertcat(*r), ca.vertcat(*r_gn)


@pytest.mark.parametrize("compiled", [False, True])
@pytest.mark.parametrize("hessian", ["gauss_newton", "exact"])
def test_assembled_derivatives_match_casadi(compiled: bool, hessian: str, tmp_path) -> None:
    rows = RowSpace()
    blocks = _blocks(rows)
    terms = [b.term for b in blocks]
    derivatives = load_derivatives(terms, tmp_path if compiled else None)
    if compiled:  # the second load takes the libraries and patterns from the cache's index
        assert len(list(tmp_path.glob("index_*.json"))) == len(terms)
        derivatives = load_derivatives(terms, tmp_path)
    nlp = BlockNLP(N_X, blocks, rows, derivatives, hessian, {"print_level": 0, "sb": "yes"})
    x, g, f_smooth, r, r_gn = _reference(blocks, rows.size)
    f = f_smooth + ca.sumsqr(r) + ca.sumsqr(r_gn)
    lam_f, lam_g = ca.SX.sym("lf"), ca.SX.sym("lg", rows.size)
    rng = np.random.default_rng(0)
    xv, pv = rng.normal(size=N_X), parameter_vector(blocks)
    lfv, lgv = 0.7, rng.normal(size=rows.size)
    jac_r, jac_gn = ca.jacobian(r, x), ca.jacobian(r_gn, x)
    if hessian == "exact":
        reference = ca.hessian(lam_f * (f_smooth + ca.sumsqr(r)) + ca.dot(lam_g, g), x)[0]
    else:
        reference = ca.hessian(lam_f * f_smooth, x)[0] + 2 * lam_f * (jac_r.T @ jac_r)
    reference += 2 * lam_f * (jac_gn.T @ jac_gn)
    ref_hess = ca.Function("h", [x, lam_f, lam_g], [reference])(xv, lfv, lgv)
    g_val, jac = nlp.oracles["jac_g"](xv, pv)
    f_val, grad = nlp.oracles["grad_f"](xv, pv)
    hess = nlp.oracles["hess_lag"](xv, pv, lfv, lgv)
    np.testing.assert_allclose(
        np.asarray(g_val).ravel(), np.asarray(ca.Function("g", [x], [g])(xv)).ravel(), atol=1e-12
    )
    assert float(f_val) == pytest.approx(float(ca.Function("f", [x], [f])(xv)), abs=1e-12)
    ref_jac = ca.Function("j", [x], [ca.jacobian(g, x)])(xv)
    np.testing.assert_allclose(
        np.asarray(ca.densify(jac)), np.asarray(ca.densify(ref_jac)), atol=1e-12
    )
    ref_grad = np.asarray(ca.Function("gr", [x], [ca.gradient(f, x)])(xv)).ravel()
    assert grad.is_dense()  # a variable in no term has a zero gradient, not a missing one
    np.testing.assert_allclose(np.asarray(grad).ravel(), ref_grad, atol=1e-12)
    np.testing.assert_allclose(
        np.asarray(ca.densify(hess)), np.triu(np.asarray(ca.densify(ref_hess))), atol=1e-12
    )


def test_the_structure_key_ignores_numbers_but_not_which_variables():
    rows = RowSpace()
    blocks = _blocks(rows)
    other = [Block(b.term, b.x, b.p + 1.0, b.rows) for b in blocks]
    assert structure_key(N_X, blocks) == structure_key(N_X, other)
    moved = [Block(blocks[0].term, blocks[0].x[:, ::-1], blocks[0].p, blocks[0].rows), *blocks[1:]]
    assert structure_key(N_X, blocks) != structure_key(N_X, moved)


def test_a_block_of_the_wrong_shape_is_refused():
    a = _terms()[0]
    with pytest.raises(SolverBuildError, match="x has shape"):
        Block(a, np.zeros((2, 2), int), np.zeros((2, 2)), np.zeros((2, 2), int))


def _virtual_problem():
    """x (4 variables) and y = F(x) (4 virtual: two calls of a lifting term), with a
    constraint and a cost with residuals on y and x together."""
    u, c = ca.SX.sym("u", 2), ca.SX.sym("c", 2)
    F = ca.vertcat(ca.sin(u[0]) * u[1], u[0] ** 2 + ca.cos(u[1]))
    lift = Term(
        ca.Function("lift", [ca.vertcat(u, c), ca.SX(0, 1)], [c - F, 0, ca.SX(0, 1)]), lifts=True
    )
    w, q = ca.SX.sym("w", 3), ca.SX.sym("q", 1)
    use = Term(
        ca.Function(
            "use",
            [w, q],
            [
                w[0] * w[1] - q,
                ca.exp(0.3 * w[2]) * w[0],
                ca.vertcat(ca.fmin(w[1] - q, 0.0), w[2] * w[0]),
            ],
        )
    )
    rows = RowSpace()
    own = rows.allocate(2, np.zeros(1), np.array([np.inf]))
    blocks = [
        Block(
            lift,
            np.array([[0, 1, 4, 5], [2, 3, 6, 7]]),
            np.zeros((2, 0)),
            np.zeros((2, 0), int),
            defines=True,
        ),
        Block(use, np.array([[4, 7, 1], [6, 0, 5]]), np.array([[0.2], [-0.4]]), own),
    ]
    return blocks, rows


@pytest.mark.parametrize("compiled", [False, True])
@pytest.mark.parametrize("hessian", ["gauss_newton", "exact"])
def test_virtual_variables_reach_x_by_the_chain_rule(compiled: bool, hessian: str, tmp_path):
    """Terms on virtual y = F(x) (a robot sphere's centre from q): J, the gradient and the
    exact Hessian are those of the NLP with F substituted; the Gauss-Newton Hessian is
    P' H_z P, P = [I; dF/dx], without F's curvature (as without the constraints')."""
    blocks, rows = _virtual_problem()
    derivatives = load_derivatives([b.term for b in blocks], tmp_path if compiled else None)
    nlp = BlockNLP(4, blocks, rows, derivatives, hessian, {"print_level": 0, "sb": "yes"}, n_y=4)
    x = ca.SX.sym("x", 4)
    y = ca.SX.sym("y", 4)
    lift, use = blocks[0].term.function, blocks[1].term.function

    def F(u):
        return -lift(ca.vertcat(u, ca.SX.zeros(2)), ca.SX(0, 1))[0]

    Fx = ca.vertcat(F(x[0:2]), F(x[2:4]))
    z = ca.vertcat(x, y)
    g, f, r = [], 0, []
    for xs, ps in zip(blocks[1].x, blocks[1].p, strict=True):
        gk, lk, rk = use(z[xs.tolist()], ps)
        g.append(gk)
        f += lk
        r.append(rk)
    g, r = ca.vertcat(*g), ca.vertcat(*r)
    lam_f, lam_g = ca.SX.sym("lf"), ca.SX.sym("lg", 2)
    substitute = ca.Function("s", [x, y], [g, f + ca.sumsqr(r)])
    g_x, f_x = substitute(x, Fx)
    if hessian == "exact":
        reference = ca.hessian(lam_f * f_x + ca.dot(lam_g, g_x), x)[0]
    else:
        jac_r = ca.jacobian(r, z)
        H_z = ca.hessian(lam_f * f, z)[0] + 2 * lam_f * (jac_r.T @ jac_r)
        P = ca.vertcat(ca.SX.eye(4), ca.jacobian(Fx, x))
        H_z = ca.substitute(H_z, y, Fx)
        reference = P.T @ H_z @ P
    rng = np.random.default_rng(3)
    xv, lgv = rng.normal(size=4), rng.normal(size=2)
    pv = parameter_vector(blocks)
    g_val, jac = nlp.oracles["jac_g"](xv, pv)
    f_val, grad = nlp.oracles["grad_f"](xv, pv)
    hess = nlp.oracles["hess_lag"](xv, pv, 0.7, lgv)
    np.testing.assert_allclose(
        np.asarray(g_val).ravel(), np.asarray(ca.Function("g", [x], [g_x])(xv)).ravel(), atol=1e-12
    )
    assert float(f_val) == pytest.approx(float(ca.Function("f", [x], [f_x])(xv)), abs=1e-12)
    ref_jac = np.asarray(ca.Function("j", [x], [ca.jacobian(g_x, x)])(xv))
    np.testing.assert_allclose(np.asarray(ca.densify(jac)), ref_jac, atol=1e-12)
    ref_grad = np.asarray(ca.Function("gr", [x], [ca.gradient(f_x, x)])(xv)).ravel()
    np.testing.assert_allclose(np.asarray(grad).ravel(), ref_grad, atol=1e-12)
    ref_hess = np.asarray(ca.Function("h", [x, lam_f, lam_g], [reference])(xv, 0.7, lgv))
    np.testing.assert_allclose(np.asarray(ca.densify(hess)), np.triu(ref_hess), atol=1e-12)


def test_a_problem_with_more_rows_keeps_the_multipliers_of_the_calls_it_shares():
    """A round of hard pairs adds calls (and rows) to a kind and a kind of its own: the
    shared calls' rows keep their multipliers wherever they moved, the new rows start at 0,
    and a call whose numbers changed starts afresh."""
    a, share, _ = _terms()
    rng = np.random.default_rng(2)
    p = rng.normal(size=(3, 2))
    old_rows = RowSpace()
    own = old_rows.allocate(2, np.zeros(2), np.zeros(2))
    old = [Block(a, np.array([[0, 1, 2], [3, 4, 5]]), p[:2], own)]
    warm = WarmStart(np.zeros(N_X), np.zeros(N_X), np.array([1.0, 2.0, 3.0, 4.0]), row_owners(old))
    # The new problem: share's rows first (a new kind), then a with a third call.
    rows = RowSpace()
    first = rows.allocate(1, np.zeros(2), np.zeros(2))
    moved = rows.allocate(3, np.zeros(2), np.zeros(2))
    new = [
        Block(share, np.array([[2, 4]]), rng.normal(size=(1, 1)), first),
        Block(a, np.array([[0, 1, 2], [3, 4, 5], [5, 6, 7]]), p, moved),
    ]
    carried = carried_multipliers(warm, new, rows.size)
    assert carried is not None
    np.testing.assert_array_equal(carried.lam_g, [0, 0, 1, 2, 3, 4, 0, 0])
    changed = [new[0], dataclasses.replace(new[1], p=np.r_[p[:1], p[:1] + 1.0, p[2:]])]
    again = carried_multipliers(warm, changed, rows.size)
    np.testing.assert_array_equal(again.lam_g, [0, 0, 1, 2, 0, 0, 0, 0])
    assert carried_multipliers(dataclasses.replace(warm, rows=None), new, rows.size) is None


def test_a_solve_logs_its_progress_every_few_iterations(caplog) -> None:
    """With ``progress_every`` the solve logs the iteration, the objective and the largest
    constraint violation under its label, the first line at the start point; the iterates
    are those of a solve without it."""
    rows = RowSpace()
    blocks = _blocks(rows)
    derivatives = load_derivatives([b.term for b in blocks], None)
    options = {"print_level": 0, "sb": "yes", "max_iter": 7}
    quiet = BlockNLP(N_X, blocks, rows, derivatives, "exact", options)
    logged = BlockNLP(N_X, blocks, rows, derivatives, "exact", options, progress_every=3)
    args = (np.full(N_X, 0.3), np.full(N_X, -5.0), np.full(N_X, 5.0), parameter_vector(blocks))
    with caplog.at_level(logging.INFO, logger="locoman.to.nlp.progress"):
        result = logged.solve(*args, label="round 2")
    lines = [r.getMessage() for r in caplog.records if r.name == "locoman.to.nlp.progress"]
    iterations = [int(re.search(r"iteration (\d+),", line).group(1)) for line in lines]
    assert iterations == list(range(0, result.iterations + 1, 3))
    assert all(line.startswith("round 2: iteration ") for line in lines)
    g0 = np.asarray(logged.oracles["jac_g"](args[0], args[3])[0]).ravel()
    violation = max(np.max(logged.lbg - g0, initial=0.0), np.max(g0 - logged.ubg, initial=0.0))
    assert f"constraint violation {violation:.1e}" in lines[0]
    np.testing.assert_array_equal(result.x, quiet.solve(*args).x)
