"""Kernelized movement primitives (paper B, eq. (1)-(3); Huang et al., IJRR 2019).

Outputs per input s are xi = [x (3), xdot (3), p (3)]: wrist position, wrist velocity and
pelvis pose. Position and velocity are learned consistently with the KMP paper's kernel
extension: with xi(s) = Phi(s)^T w, the position rows use phi(s) and the velocity rows its
derivative phi'(s), so the kernel between two inputs is built from k and its derivatives,

    k_pp = k(s_i, s_j),        k_pv = dk/ds_j,
    k_vp = dk/ds_i,            k_vv = d^2 k / (ds_i ds_j),

each times I_3; the pelvis rows use k alone. With the RBF kernel
k = exp(-(s_i - s_j)^2 / (2 l^2)) and d = s_i - s_j these are exact:
dk/ds_i = -d / l^2 k, dk/ds_j = d / l^2 k, d^2k/(ds_i ds_j) = (1 / l^2 - d^2 / l^4) k
(the KMP paper's finite differences in the limit of a vanishing step).

The mean prediction (3) is E[xi(s*)] = k* (K + lambda Sigma)^{-1} mu, with (K + lambda Sigma)
factorised once by Cholesky.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import scipy.linalg

from locoman.errors import SolverError
from locoman.kmp.gmr import Reference

N_OUT = 9
POS, VEL, PELVIS = slice(0, 3), slice(3, 6), slice(6, 9)
_B_PP = np.zeros((N_OUT, N_OUT))
_B_PP[POS, POS] = np.eye(3)
_B_PP[PELVIS, PELVIS] = np.eye(3)
_B_PV = np.zeros((N_OUT, N_OUT))
_B_PV[POS, VEL] = np.eye(3)
_B_VP = _B_PV.T.copy()
_B_VV = np.zeros((N_OUT, N_OUT))
_B_VV[VEL, VEL] = np.eye(3)
_CHUNK = 512


@dataclasses.dataclass(frozen=True)
class Kmp:
    """A fitted KMP.

    Attributes:
        s: (N,) reference inputs [s].
        alpha: (N, 9) (K + lambda Sigma)^{-1} mu, one row per reference point.
        width: Kernel width l [s].
    """

    s: np.ndarray
    alpha: np.ndarray
    width: float


def rbf_blocks(a: np.ndarray, b: np.ndarray, width: float) -> tuple[np.ndarray, ...]:
    """k, dk/ds_i, dk/ds_j, d^2k/(ds_i ds_j) between inputs a (P,) and b (Q,), each (P, Q)."""
    d = a[:, None] - b[None, :]
    inv = 1.0 / width**2
    k = np.exp(-0.5 * d * d * inv)
    dk_di = -d * inv * k
    return k, dk_di, -dk_di, (inv - d * d * inv * inv) * k


def kernel_matrix(s: np.ndarray, width: float) -> np.ndarray:
    """K (9N, 9N), point-major: entry (9 i + o, 9 j + o') couples output o at s_i, o' at s_j."""
    k, dk_di, dk_dj, d2k = rbf_blocks(s, s, width)
    return np.kron(k, _B_PP) + np.kron(dk_dj, _B_PV) + np.kron(dk_di, _B_VP) + np.kron(d2k, _B_VV)


def kmp_fit(reference: Reference, regularization: float, width: float) -> Kmp:
    """Solve (K + lambda Sigma) alpha = mu by Cholesky (eq. (3)).

    Raises:
        SolverError: If K + lambda Sigma is not positive definite (e.g. two reference points
            at the same input with contradicting means and tiny covariances).
    """
    n = len(reference.s)
    sigma = scipy.linalg.block_diag(*reference.cov)
    c = kernel_matrix(reference.s, width) + regularization * sigma
    try:
        factor = scipy.linalg.cho_factor(c, lower=True, check_finite=False)
    except np.linalg.LinAlgError:
        raise SolverError(
            f"KMP: K + lambda Sigma ({9 * n}x{9 * n}) is not positive definite; check for "
            "duplicate via points or raise kmp.via_point_variance"
        ) from None
    alpha = scipy.linalg.cho_solve(factor, reference.mean.reshape(-1), check_finite=False)
    return Kmp(reference.s.copy(), alpha.reshape(n, N_OUT), width)


def kmp_predict(model: Kmp, s_star: np.ndarray) -> np.ndarray:
    """Mean outputs (M, 9) at inputs s_star (M,): eq. (3).

    With u = (s* - s_j) / l the kernel blocks are k = exp(-u^2 / 2), dk/ds_j = (u k) / l and
    d^2k / (ds_i ds_j) = (k - u^2 k) / l^2; the 1 / l factors go into the weights, so each
    chunk of inputs costs one exponential, a few in-place passes and three products:
    [x | p] = k [a_x | a_p] + (u k) a_v / l and xdot = -(u k) a_x / l + (k - u^2 k) a_v / l^2.
    """
    s_star = np.asarray(s_star, dtype=float) / model.width
    s_ref = model.s / model.width
    out = np.empty((len(s_star), N_OUT))
    a = model.alpha
    a_xp = np.ascontiguousarray(a[:, np.r_[0:3, 6:9]])
    a_v_negx = np.ascontiguousarray(np.c_[a[:, VEL], -a[:, POS]]) / model.width
    a_v = np.ascontiguousarray(a[:, VEL]) / model.width**2
    for lo in range(0, len(s_star), _CHUNK):
        u = s_star[lo : lo + _CHUNK, None] - s_ref[None, :]
        k = np.multiply(u, u)
        np.multiply(k, -0.5, out=k)
        np.exp(k, out=k)
        uk = np.multiply(u, k, out=u)
        rows = slice(lo, lo + len(k))
        xp = k @ a_xp
        mixed = uk @ a_v_negx
        out[rows, POS] = xp[:, :3] + mixed[:, :3]
        out[rows, PELVIS] = xp[:, 3:]
        # k - u^2 k = k - u (u k); u is gone, so recover u^2 k from uk^2 / k where k > 0.
        np.subtract(k, np.multiply(uk, s_star[lo : lo + _CHUNK, None] - s_ref[None, :]), out=k)
        out[rows, VEL] = mixed[:, 3:] + k @ a_v
    return out


@dataclasses.dataclass(frozen=True)
class ViaPoint:
    """A desired point {s_bar, mu_bar, Sigma_bar}; NaN entries of ``mean`` are unconstrained."""

    s: float
    mean: np.ndarray


def insert_via_points(reference: Reference, via: list[ViaPoint], variance: float) -> Reference:
    """Replace the nearest reference point of every via point by it (KMP paper, Sec. IV).

    Constrained outputs get mean mu_bar and variance ``variance`` with no correlation to the
    others; an unconstrained output keeps the replaced point's mean and marginal covariance.

    Raises:
        SolverError: If two via points fall on the same reference point.
    """
    s, mean, cov = reference.s.copy(), reference.mean.copy(), reference.cov.copy()
    used: dict[int, float] = {}
    for v in via:
        n = int(np.argmin(np.abs(s - v.s)))
        if n in used:
            raise SolverError(
                f"via points at {used[n]} s and {v.s} s replace the same reference point; "
                "space them further apart than the reference spacing"
            )
        used[n] = v.s
        fixed = ~np.isnan(v.mean)
        s[n] = v.s
        mean[n, fixed] = v.mean[fixed]
        cov[n][fixed, :] = 0.0
        cov[n][:, fixed] = 0.0
        cov[n][fixed, fixed] = variance
    return Reference(s, mean, cov)
