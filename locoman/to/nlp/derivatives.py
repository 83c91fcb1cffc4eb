"""The derivatives each term kind is compiled with: its Jacobian, gradient and Hessians
(Gauss-Newton and exact), built once per kind from its CasADi function, compiled to C and
kept in the cache by a key of their expressions (:mod:`locoman.to.nlp.compile`)."""

from __future__ import annotations

import dataclasses
import hashlib
import inspect
from collections.abc import Sequence
from pathlib import Path

import casadi as ca
import numpy as np

from locoman.errors import SolverBuildError
from locoman.to.nlp.compile import Recipe, load_or_compile
from locoman.to.terms.term import Term


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
    """The compiled derivatives of ``term`` as a cache recipe (:mod:`locoman.to.nlp.compile`)."""
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
