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
factorised once by Cholesky; the covariance prediction (KMP paper, Huang et al. IJRR 2019,
Sec. 3) is D[xi(s*)] = N / lambda_c (k(s*, s*) - k* (K + lambda_c Sigma)^{-1} k*^T), with
its own regularisation lambda_c. A NaN in a reference mean is an unobserved output (a via
point's free output): its rows and columns leave K, Sigma and mu, which is the limit of an
infinite variance.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import scipy.linalg

from locoman.errors import ConfigError, SolverError
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


def kernel_blocks(a: np.ndarray, b: np.ndarray, width: float) -> np.ndarray:
    """k(a_i, b_j) as (9P, 9Q), point-major: entry (9 i + o, 9 j + o') couples output o at
    a_i with output o' at b_j."""
    k, dk_di, dk_dj, d2k = rbf_blocks(a, b, width)
    return np.kron(k, _B_PP) + np.kron(dk_dj, _B_PV) + np.kron(dk_di, _B_VP) + np.kron(d2k, _B_VV)


def kernel_matrix(s: np.ndarray, width: float) -> np.ndarray:
    """K (9N, 9N) of the reference inputs s (N,)."""
    return kernel_blocks(s, s, width)


def _factor(reference: Reference, regularization: float, width: float):
    """Cholesky factor of (K + lambda Sigma) over the observed outputs, and their mask."""
    observed = np.isfinite(reference.mean).reshape(-1)
    n = int(observed.sum())
    sigma = scipy.linalg.block_diag(*reference.cov)[np.ix_(observed, observed)]
    c = kernel_matrix(reference.s, width)[np.ix_(observed, observed)] + regularization * sigma
    try:
        return scipy.linalg.cho_factor(c, lower=True, check_finite=False), observed
    except np.linalg.LinAlgError:
        raise SolverError(
            f"KMP: K + lambda Sigma ({n}x{n}) is not positive definite; check for via points "
            "that contradict each other at one input with tiny variances, or raise their "
            "variance"
        ) from None


def kmp_fit(reference: Reference, regularization: float, width: float) -> Kmp:
    """Solve (K + lambda Sigma) alpha = mu by Cholesky (eq. (3)); unobserved outputs (NaN
    means) get alpha = 0.

    Raises:
        SolverError: If K + lambda Sigma is not positive definite (e.g. two reference points
            at the same input with contradicting means and tiny covariances).
    """
    factor, observed = _factor(reference, regularization, width)
    alpha = np.zeros(observed.size)
    alpha[observed] = scipy.linalg.cho_solve(
        factor, reference.mean.reshape(-1)[observed], check_finite=False
    )
    return Kmp(reference.s.copy(), alpha.reshape(-1, N_OUT), width)


@dataclasses.dataclass(frozen=True)
class KmpCovariance:
    """A fitted KMP covariance prediction.

    Attributes:
        s: (N,) reference inputs [s].
        observed: (9N,) which reference outputs enter K and Sigma.
        factor: Cholesky factor of (K + lambda_c Sigma) over the observed outputs.
        scale: N / lambda_c.
        width: Kernel width l [s].
    """

    s: np.ndarray
    observed: np.ndarray
    factor: tuple
    scale: float
    width: float


def kmp_covariance_fit(reference: Reference, regularization: float, width: float) -> KmpCovariance:
    """Factorise (K + lambda_c Sigma) for the covariance prediction (``regularization`` is
    lambda_c).

    Raises:
        SolverError: If K + lambda_c Sigma is not positive definite.
    """
    factor, observed = _factor(reference, regularization, width)
    return KmpCovariance(
        reference.s.copy(), observed, factor, len(reference.s) / regularization, width
    )


def kmp_predict_covariance(model: KmpCovariance, s_star: np.ndarray) -> np.ndarray:
    """Predicted covariances (M, 9, 9) at inputs s_star (M,):
    N / lambda_c (k(s*, s*) - k* (K + lambda_c Sigma)^{-1} k*^T).

    Costs one triangular solve with 9M right-hand sides: predict on a plotting grid, not at
    the controller's rate.
    """
    s_star = np.asarray(s_star, dtype=float)
    k_star = kernel_blocks(s_star, model.s, model.width)[:, model.observed]
    w = scipy.linalg.solve_triangular(model.factor[0], k_star.T, lower=True, check_finite=False)
    k_ss = kernel_blocks(np.zeros(1), np.zeros(1), model.width)
    m = len(s_star)
    explained = np.einsum("ima,imb->mab", w.reshape(-1, m, N_OUT), w.reshape(-1, m, N_OUT))
    return model.scale * (k_ss[None] - explained)


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
    """A desired point {s_bar, mu_bar, Sigma_bar} (KMP paper, Sec. IV).

    Attributes:
        s: Input (time) [s].
        mean: (9,) desired outputs; NaN leaves an output free (to the demonstrations).
        cov: (9, 9) covariance of the desired outputs (units^2): a tiny variance pins an
            output, a large one lets the demonstrations pull it. Rows and columns of free
            outputs are ignored; the constrained block must be symmetric positive definite.

    Raises:
        ConfigError: On a wrong shape, a non-finite input or covariance, no constrained
            output, or a constrained covariance block that is not symmetric positive definite.
    """

    s: float
    mean: np.ndarray
    cov: np.ndarray

    def __post_init__(self) -> None:
        where = f"via point at s = {self.s}"
        if not np.isfinite(self.s):
            raise ConfigError(f"{where}: its input must be finite")
        if np.shape(self.mean) != (N_OUT,) or np.shape(self.cov) != (N_OUT, N_OUT):
            raise ConfigError(
                f"{where}: mean must be ({N_OUT},) and cov ({N_OUT}, {N_OUT}), got "
                f"{np.shape(self.mean)} and {np.shape(self.cov)}"
            )
        fixed = self.constrained
        if not fixed.any():
            raise ConfigError(f"{where}: every output is NaN (free); constrain at least one")
        block = self.cov[np.ix_(fixed, fixed)]
        if not np.all(np.isfinite(block)) or np.any(np.isinf(self.mean)):
            raise ConfigError(f"{where}: mean and covariance must be finite (NaN = free output)")
        if not np.allclose(block, block.T, rtol=1e-9, atol=0.0):
            raise ConfigError(f"{where}: the covariance must be symmetric")
        try:
            np.linalg.cholesky(block)
        except np.linalg.LinAlgError:
            raise ConfigError(
                f"{where}: the covariance of the constrained outputs is not positive "
                "definite; give every constrained output a variance > 0"
            ) from None

    @property
    def constrained(self) -> np.ndarray:
        """(9,) which outputs the point constrains."""
        return ~np.isnan(self.mean)

    @classmethod
    def of(cls, s: float, mean: np.ndarray, variance: float | np.ndarray) -> ViaPoint:
        """A via point with uncorrelated outputs: ``variance`` is one value for every output
        or (9,) per output (units^2)."""
        var = np.broadcast_to(np.asarray(variance, dtype=float), (N_OUT,))
        return cls(float(s), np.asarray(mean, dtype=float), np.diag(var))


def insert_via_points(reference: Reference, via: list[ViaPoint], time_tol_s: float) -> Reference:
    """Insert the via points into the reference (paper B, Sec. III-A.2: N + M points).

    A via point within ``time_tol_s`` of a reference point's input replaces that point's
    constrained outputs (mean mu_bar, covariance Sigma_bar, no correlation with the point's
    free outputs, which keep their mean and marginal covariance). Any other via point is
    added as a point of its own, its free outputs unobserved (NaN). The reference keeps all
    its points; via points close to each other all count. The result is sorted by input.
    """
    s, mean, cov = reference.s.copy(), reference.mean.copy(), reference.cov.copy()
    extra_s, extra_mean, extra_cov = [], [], []
    replaced: set[int] = set()
    for v in via:
        fixed = v.constrained
        n = int(np.argmin(np.abs(reference.s - v.s)))
        if abs(reference.s[n] - v.s) <= time_tol_s and n not in replaced:
            replaced.add(n)
            s[n] = v.s
            mean[n, fixed] = v.mean[fixed]
            cov[n][fixed, :] = 0.0
            cov[n][:, fixed] = 0.0
            cov[n][np.ix_(fixed, fixed)] = v.cov[np.ix_(fixed, fixed)]
        else:
            c = np.zeros((N_OUT, N_OUT))
            c[np.ix_(fixed, fixed)] = v.cov[np.ix_(fixed, fixed)]
            extra_s.append(v.s)
            extra_mean.append(v.mean)
            extra_cov.append(c)
    if extra_s:
        s = np.r_[s, extra_s]
        mean = np.r_[mean, np.array(extra_mean)]
        cov = np.r_[cov, np.array(extra_cov)]
    order = np.argsort(s, kind="stable")
    return Reference(s[order], mean[order], cov[order])
