"""Reference distribution of the demonstrations by GMM/GMR (paper B, Sec. III-A.2).

A Gaussian mixture is fitted to the joint samples (s, xi) with scikit-learn; Gaussian mixture
regression then gives, at each reference input s_n, the conditional mean mu_n and covariance
Sigma_n of xi, i.e. the reference trajectory {s_n, mu_n, Sigma_n} that KMP imitates.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from sklearn.mixture import GaussianMixture

from locoman.errors import SolverError


@dataclasses.dataclass(frozen=True)
class Gmm:
    """A Gaussian mixture over (s, xi): weights (K,), means (K, D), covariances (K, D, D)."""

    weights: np.ndarray
    means: np.ndarray
    covariances: np.ndarray


@dataclasses.dataclass(frozen=True)
class Reference:
    """The reference trajectory {s_n, mu_n, Sigma_n}.

    Attributes:
        s: (N,) inputs (time [s]).
        mean: (N, O) means of the outputs; NaN marks an output not observed at that input
            (a via point's free output), which KMP leaves out.
        cov: (N, O, O) covariances of the outputs.
    """

    s: np.ndarray
    mean: np.ndarray
    cov: np.ndarray


def fit_gmm(s: np.ndarray, xi: np.ndarray, n_components: int, seed: int, tol: float = 1e-2) -> Gmm:
    """Fit a GMM to samples (s (S,), xi (S, O)), initialised with equal slices of time.

    Time-sliced initial means make the fit deterministic and put one Gaussian on every phase
    of the task, as the usual time-based initialisation of GMM/GMR does.

    Raises:
        SolverError: If EM does not converge.
    """
    data = np.c_[s, xi]
    edges = np.linspace(s.min(), s.max(), n_components + 1)
    slot = np.clip(np.searchsorted(edges, s, side="right") - 1, 0, n_components - 1)
    means = np.stack([data[slot == k].mean(axis=0) for k in range(n_components)])
    gmm = GaussianMixture(
        n_components=n_components,
        covariance_type="full",
        reg_covar=1e-6,
        max_iter=500,
        tol=tol,
        means_init=means,
        random_state=seed,
    ).fit(data)
    if not gmm.converged_:
        raise SolverError(
            f"GMM with {n_components} components did not converge in 500 EM iterations; "
            "lower kmp.gmm_components or add demonstrations"
        )
    return Gmm(gmm.weights_, gmm.means_, gmm.covariances_)


def gmr(gmm: Gmm, s: np.ndarray) -> Reference:
    """Condition the GMM on the input: mean and covariance of xi given s, at every s (N,).

    With h_k(s) the responsibility of component k for s,
    mu(s) = sum_k h_k (mu_k^xi + Sigma_k^{xi s} / Sigma_k^{ss} (s - mu_k^s)) and
    Sigma(s) = sum_k h_k (Sigma_k^{xi|s} + m_k m_k^T) - mu(s) mu(s)^T.
    """
    mu_s = gmm.means[:, 0]
    var_s = gmm.covariances[:, 0, 0]
    mu_x = gmm.means[:, 1:]
    cov_xs = gmm.covariances[:, 1:, 0]
    cov_xx = gmm.covariances[:, 1:, 1:]
    d = s[:, None] - mu_s[None, :]
    log_h = np.log(gmm.weights)[None] - 0.5 * (d**2 / var_s + np.log(2.0 * np.pi * var_s))
    log_h -= log_h.max(axis=1, keepdims=True)
    h = np.exp(log_h)
    h /= h.sum(axis=1, keepdims=True)
    m = mu_x[None] + (d / var_s)[..., None] * cov_xs[None]
    mean = np.einsum("nk,nko->no", h, m)
    cond = cov_xx - np.einsum("ko,kp->kop", cov_xs, cov_xs) / var_s[:, None, None]
    second = np.einsum("nk,kop->nop", h, cond) + np.einsum("nk,nko,nkp->nop", h, m, m)
    cov = second - np.einsum("no,np->nop", mean, mean)
    return Reference(s, mean, 0.5 * (cov + np.swapaxes(cov, 1, 2)))
