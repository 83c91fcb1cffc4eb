"""The numeric oracles (:mod:`locoman.to.nlp.oracles`): a one-sided penalty's far calls are
skipped without changing the derivatives beyond rounding, a subset of calls evaluates as
the same calls of the whole map, and the problem function's own Jacobian is refused."""

from __future__ import annotations

import dataclasses

import casadi as ca
import numpy as np
import pytest

from locoman.errors import SolverBuildError
from locoman.to.nlp.derivatives import load_derivatives
from locoman.to.nlp.ipopt import BlockNLP, parameter_vector
from locoman.to.nlp.oracles import Oracles
from locoman.to.nlp.sparsity import Mapped
from locoman.to.terms.collisions import penetration_residual
from locoman.to.terms.term import Block, RowSpace, Term

SOFTNESS = 0.005  # [m]


def _penalty(one_sided: bool) -> Term:
    """A point (x) kept 0.1 m from a fixed point (p): (12) on a sphere pair."""
    x, p = ca.SX.sym("x", 3), ca.SX.sym("p", 3)
    clearance = ca.norm_2(x - p) - 0.1
    residual = 10.0 * penetration_residual(clearance, SOFTNESS)
    fn = ca.Function("near", [x, p], [ca.SX(0, 1), 0, residual])
    return Term(fn, one_sided=one_sided)


def _track() -> Term:
    """A cost that keeps every point near the origin, so the problem has curvature
    everywhere."""
    x = ca.SX.sym("x", 3)
    return Term(ca.Function("track", [x, ca.SX(0, 1)], [ca.SX(0, 1), 0, 0.1 * x]))


def _oracles(one_sided: bool, calls: int = 200) -> tuple[Oracles, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(5)
    n_points = 40
    points = rng.integers(0, n_points, size=calls)
    x = (3 * points[:, None] + np.arange(3)).astype(int)
    obstacles = rng.uniform(-1.0, 1.0, size=(calls, 3))
    blocks = [
        Block(_penalty(one_sided), x, obstacles, np.zeros((calls, 0), int)),
        Block(
            _track(),
            np.arange(3 * n_points).reshape(n_points, 3),
            np.zeros((n_points, 0)),
            np.zeros((n_points, 0), int),
        ),
    ]
    derivatives = load_derivatives([b.term for b in blocks], None)
    oracles = Oracles(3 * n_points, blocks, 0, derivatives, "exact", 0)
    return oracles, rng.uniform(-1.0, 1.0, size=3 * n_points), parameter_vector(blocks)


def test_far_penalty_calls_are_skipped_and_change_nothing_beyond_rounding():
    skipping, x, p = _oracles(one_sided=True)
    every, _, _ = _oracles(one_sided=False)
    f, grad = skipping.grad_f(x, p)
    f_all, grad_all = every.grad_f(x, p)
    assert f == f_all  # the cost sums every call
    np.testing.assert_allclose(grad, grad_all, rtol=0, atol=1e-14)
    hess = skipping.hess_lag(x, p, 1.0, np.zeros(0))
    np.testing.assert_allclose(hess, every.hess_lag(x, p, 1.0, np.zeros(0)), rtol=0, atol=1e-12)
    active = skipping._point.active[0]
    assert 0 < len(active) < 200  # some near, most far: the test sees both
    assert every._point.active[0] is None


def test_a_subset_of_calls_is_the_same_calls_of_the_whole_map():
    term = _penalty(one_sided=True)
    derivatives = load_derivatives([term], None)["near"]
    rng = np.random.default_rng(2)
    x, p = rng.normal(size=(50, 3)), rng.normal(size=(50, 3))
    whole = Mapped(derivatives.grad, 50)
    cost, grad = whole(x, p)
    chosen = np.array([3, 17, 18, 41, 49])
    part_cost, part_grad = whole.some(len(chosen), x[chosen], p[chosen])  # padded to 16
    np.testing.assert_array_equal(part_cost, cost[chosen])
    np.testing.assert_array_equal(part_grad, grad[chosen])
    assert np.all(cost >= 0.0)


def test_the_problem_function_has_no_jacobian_of_its_own():
    term = _track()
    derivatives = load_derivatives([term], None)
    rows = RowSpace()
    block = Block(term, np.array([[0, 1, 2]]), np.zeros((1, 0)), np.zeros((1, 0), int))
    nlp = BlockNLP(3, [block], rows, derivatives, "gauss_newton", {"print_level": 0, "sb": "yes"})
    _, jacobian = nlp._callbacks
    # The TO's own refusal (SolverBuildError), raised through CasADi.
    with pytest.raises(RuntimeError, match="come from its oracles"):
        jacobian(*[np.zeros(sp.nnz()) for sp in map(jacobian.sparsity_in, range(4))])
    solution = nlp.solve(np.ones(3), -np.inf * np.ones(3), np.inf * np.ones(3), np.zeros(0))
    assert solution.success
    np.testing.assert_allclose(solution.x, 0.0, atol=1e-8)


def test_a_virtual_variable_defined_twice_or_from_another_is_refused():
    u, c = ca.SX.sym("u", 1), ca.SX.sym("c", 1)
    lift = Term(ca.Function("lift", [ca.vertcat(u, c), ca.SX(0, 1)], [c - u**2, 0, ca.SX(0, 1)]))
    lift = dataclasses.replace(lift, lifts=True)
    derivatives = load_derivatives([lift], None)

    def oracles(x: list[list[int]]) -> Oracles:
        block = Block(lift, np.array(x), np.zeros((2, 0)), np.zeros((2, 0), int), defines=True)
        return Oracles(2, [block], 0, derivatives, "gauss_newton", 2)

    oracles([[0, 2], [1, 3]])  # y0 = x0^2, y1 = x1^2
    with pytest.raises(SolverBuildError, match="exactly once"):
        oracles([[0, 2], [1, 2]])
    with pytest.raises(SolverBuildError, match="real ones only"):
        oracles([[0, 2], [2, 3]])


def _lift() -> Term:
    """y = (sin(u0) u1, u0 u1^2): a virtual point of a real one, curved."""
    u, c = ca.SX.sym("u", 2), ca.SX.sym("c", 2)
    lifted = ca.vertcat(ca.sin(u[0]) * u[1], u[0] * u[1] ** 2)
    return dataclasses.replace(
        Term(ca.Function("lift", [ca.vertcat(u, c), ca.SX(0, 1)], [c - lifted, 0, ca.SX(0, 1)])),
        lifts=True,
    )


def _pair() -> Term:
    """A cost on two virtual points, coupling all four coordinates."""
    a, b = ca.SX.sym("a", 2), ca.SX.sym("b", 2)
    residual = ca.dot(a - b, a + b) + 0.3 * a[0] * b[1]
    return Term(ca.Function("pair", [ca.vertcat(a, b), ca.SX(0, 1)], [ca.SX(0, 1), 0, residual]))


def _ring() -> Term:
    """A constraint row on one virtual point."""
    a = ca.SX.sym("a", 2)
    return Term(ca.Function("ring", [a, ca.SX(0, 1)], [ca.sumsqr(a), 0, ca.SX(0, 1)]))


REAL_POINTS = 5


def _blocks(lifted: int, pairs: np.ndarray, ring: bool, rows: RowSpace) -> list[Block]:
    """Five real points (2 each), ``lifted`` of them lifted in two definition blocks, the
    second from point 3 on, of real points 1 and 2 (as a round's spheres between nodes come
    after every node's, of the nodes' configurations); a cost on the real ones that a round
    leaves as it is; the pair cost on ``pairs`` of virtual points; with ``ring``, a
    constraint on the last lifted one."""
    n_x = 2 * REAL_POINTS

    def lift(chosen: range, source: int = 0) -> Block:
        """Virtual points ``chosen`` of the real points ``source`` on."""
        x = np.array(
            [[2 * j, 2 * j + 1, n_x + 2 * i, n_x + 2 * i + 1] for j, i in enumerate(chosen, source)]
        )
        return Block(_lift(), x, np.zeros((len(x), 0)), np.zeros((len(x), 0), int), defines=True)

    def at(i: np.ndarray) -> np.ndarray:
        return n_x + 2 * i[:, None] + np.arange(2)

    x = np.hstack([at(pairs[:, 0]), at(pairs[:, 1])])
    none = np.zeros((len(x), 0))
    track = Block(_track(), np.array([[0, 1, 2]]), np.zeros((1, 0)), np.zeros((1, 0), int))
    blocks = [lift(range(min(lifted, 3))), track, Block(_pair(), x, none, none.astype(int))]
    if lifted > 3:
        blocks.append(lift(range(3, lifted), source=1))  # among the first ones' entries of P
    if ring:
        row = rows.allocate(1, np.array([1.0]), np.array([2.0]))
        blocks.append(Block(_ring(), at(np.array([lifted - 1])), np.zeros((1, 0)), row))
    return blocks


@pytest.mark.parametrize("hessian", ["exact", "gauss_newton", "projected"])
def test_a_rounds_oracles_extend_the_previous_patterns_into_the_same_problem(hessian):
    """Oracles built on the previous round's (whose calls are their first calls) extend
    its patterns by the new calls: new pairs on old and on new virtual points, a new
    definition block and a new constraint. The patterns, each call's place in them and the
    derivatives are those of oracles built from scratch; oracles of other first calls or
    of another Hessian are built from scratch."""
    rng = np.random.default_rng(11)
    old_pairs = np.array([[0, 1], [1, 2]])
    # (0, 2) adds entries among the old ones (they move), the others after them.
    new_pairs = np.r_[old_pairs, [[0, 2], [2, 4], [1, 3], [3, 4]]]
    derivatives = load_derivatives([_lift(), _track(), _pair(), _ring()], None)

    def oracles(lifted, pairs, ring, previous=None, flavour=hessian) -> Oracles:
        rows = RowSpace()
        blocks = _blocks(lifted, pairs, ring, rows)
        n_x = 2 * REAL_POINTS
        return Oracles(n_x, blocks, rows.size, derivatives, flavour, 2 * lifted, previous)

    first = oracles(3, old_pairs, ring=False)
    extended = oracles(5, new_pairs, ring=True, previous=first)
    scratch = oracles(5, new_pairs, ring=True)
    assert extended._moved is not None and scratch._moved is None
    for name in ("J_z", "H_z", "P", "J_x", "H_x"):
        a, b = getattr(extended, name), getattr(scratch, name)
        assert a.shape == b.shape and np.array_equal(a._linear, b._linear), name
    for a, b in zip(extended._calls, scratch._calls, strict=True):
        np.testing.assert_array_equal(a.hess_at, b.hess_at)
        np.testing.assert_array_equal(a.jac_at, b.jac_at)
    x, p, lam = rng.normal(size=10), np.zeros(0), rng.normal(size=1)
    np.testing.assert_array_equal(
        extended.hess_lag(x, p, 0.7, lam), scratch.hess_lag(x, p, 0.7, lam)
    )
    np.testing.assert_array_equal(extended.jac_g(x, p)[1], scratch.jac_g(x, p)[1])
    assert len(np.unique(scratch.H_x._linear)) > len(first.H_x._linear)  # the test adds some
    reordered = oracles(5, new_pairs[::-1], ring=True, previous=first)
    other = "gauss_newton" if hessian == "exact" else "exact"
    flavoured = oracles(5, new_pairs, ring=True, previous=first, flavour=other)
    assert reordered._moved is None and flavoured._moved is None
