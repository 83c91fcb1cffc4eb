"""GMM/GMR and KMP: reproduce the reference, pass through via points, consistent velocities."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from locoman.errors import SolverError
from locoman.kmp.gmr import Reference, fit_gmm, gmr
from locoman.kmp.kmp import (
    ViaPoint,
    insert_via_points,
    kernel_matrix,
    kmp_fit,
    kmp_predict,
    rbf_blocks,
)


def smooth_reference(n: int = 80, duration: float = 8.0) -> Reference:
    """Outputs of a known smooth motion: x = sin, xdot = its derivative, pelvis = cos."""
    s = np.linspace(0.0, duration, n)
    pos = np.c_[np.sin(s), 0.5 * np.sin(0.5 * s), 0.1 * s]
    vel = np.c_[np.cos(s), 0.25 * np.cos(0.5 * s), np.full(n, 0.1)]
    pel = np.c_[np.cos(s), 0.2 * s, 0.1 * np.sin(s)]
    cov = np.tile(1e-4 * np.eye(9), (n, 1, 1))
    return Reference(s, np.c_[pos, vel, pel], cov)


def test_rbf_derivatives_match_finite_differences():
    a, b, h = np.array([0.3, 1.1]), np.array([0.0, 0.7, 2.0]), 1e-6
    _k, dk_di, dk_dj, d2k = rbf_blocks(a, b, 0.8)
    fd_i = (rbf_blocks(a + h, b, 0.8)[0] - rbf_blocks(a - h, b, 0.8)[0]) / (2 * h)
    fd_j = (rbf_blocks(a, b + h, 0.8)[0] - rbf_blocks(a, b - h, 0.8)[0]) / (2 * h)
    fd_ij = (rbf_blocks(a, b + h, 0.8)[1] - rbf_blocks(a, b - h, 0.8)[1]) / (2 * h)
    np.testing.assert_allclose(dk_di, fd_i, atol=1e-8)
    np.testing.assert_allclose(dk_dj, fd_j, atol=1e-8)
    np.testing.assert_allclose(d2k, fd_ij, atol=1e-6)


def test_kernel_matrix_is_symmetric_positive_semidefinite():
    big_k = kernel_matrix(np.linspace(0.0, 3.0, 12), 0.5)
    np.testing.assert_allclose(big_k, big_k.T, atol=1e-12)
    assert np.linalg.eigvalsh(big_k).min() > -1e-9


def test_kmp_reproduces_the_reference_mean_without_via_points():
    ref = smooth_reference()
    pred = kmp_predict(kmp_fit(ref, 10.0, 0.5), ref.s)
    rmse = np.sqrt(np.mean((pred - ref.mean) ** 2, axis=0))
    assert rmse.max() < 5e-3, rmse


def test_predicted_velocity_is_the_derivative_of_the_predicted_position():
    model = kmp_fit(smooth_reference(), 10.0, 0.5)
    t = np.linspace(1.0, 7.0, 6001)
    out = kmp_predict(model, t)
    fd = np.gradient(out[:, 0:3], t, axis=0)
    assert np.abs(fd[5:-5] - out[5:-5, 3:6]).max() < 1e-4


@settings(max_examples=15, deadline=None)
@given(
    s=st.floats(0.5, 7.5),
    pos=st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3),
    vel=st.lists(st.floats(-0.5, 0.5), min_size=3, max_size=3),
)
def test_kmp_passes_through_via_points(s, pos, vel):
    mean = np.r_[pos, vel, np.full(3, np.nan)]
    ref = insert_via_points(smooth_reference(), [ViaPoint(s, mean)], 1e-10)
    out = kmp_predict(kmp_fit(ref, 10.0, 0.5), np.array([s]))[0]
    assert np.abs(out[:3] - pos).max() < 1e-3
    assert np.abs(out[3:6] - vel).max() < 1e-3


def test_via_points_on_the_same_reference_point_are_refused():
    nan3 = np.full(3, np.nan)
    via = [ViaPoint(1.0, np.r_[0, 0, 0, nan3, nan3]), ViaPoint(1.01, np.r_[1, 1, 1, nan3, nan3])]
    with pytest.raises(SolverError, match="same reference point"):
        insert_via_points(smooth_reference(), via, 1e-10)


def test_gmr_recovers_a_linear_trend():
    rng = np.random.default_rng(0)
    s = np.tile(np.linspace(0.0, 10.0, 500), 4)
    xi = np.c_[0.3 * s + 1.0, -0.1 * s] + rng.normal(0.0, 0.01, (len(s), 2))
    ref = gmr(fit_gmm(s, xi, 4, seed=0), np.linspace(1.0, 9.0, 9))
    np.testing.assert_allclose(ref.mean[:, 0], 0.3 * ref.s + 1.0, atol=0.02)
    np.testing.assert_allclose(ref.mean[:, 1], -0.1 * ref.s, atol=0.02)
    assert np.all(np.linalg.eigvalsh(ref.cov) > 0.0)
