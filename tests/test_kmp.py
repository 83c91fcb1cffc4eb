"""GMM/GMR and KMP: reproduce the reference, pass through via points, consistent velocities."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from locoman.errors import ConfigError
from locoman.kmp.gmr import Reference, fit_gmm, gmr
from locoman.kmp.kmp import (
    ViaPoint,
    insert_via_points,
    kernel_matrix,
    kmp_covariance_fit,
    kmp_fit,
    kmp_predict,
    kmp_predict_covariance,
    rbf_blocks,
)

NAN3 = np.full(3, np.nan)
TOL_S = 1e-3


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
    mean = np.r_[pos, vel, NAN3]
    ref = insert_via_points(smooth_reference(), [ViaPoint.of(s, mean, 1e-10)], TOL_S)
    out = kmp_predict(kmp_fit(ref, 10.0, 0.5), np.array([s]))[0]
    assert np.abs(out[:3] - pos).max() < 1e-3
    assert np.abs(out[3:6] - vel).max() < 1e-3


def line_reference(s: np.ndarray) -> Reference:
    """x = s along every position axis (velocity 1), pelvis 0, small uncorrelated noise."""
    n = len(s)
    mean = np.c_[np.tile(s[:, None], 3), np.ones((n, 3)), np.zeros((n, 3))]
    return Reference(s, mean, np.tile(1e-4 * np.eye(9), (n, 1, 1)))


def test_a_via_point_past_the_reference_is_added_and_keeps_its_end_point():
    ref = line_reference(np.array([0.0, 0.5, 1.0, 1.5, 2.0]))
    via = ViaPoint.of(3.0, np.r_[3.0, 3.0, 3.0, NAN3, NAN3], 1e-10)
    adapted = insert_via_points(ref, [via], TOL_S)
    np.testing.assert_array_equal(adapted.s, [0.0, 0.5, 1.0, 1.5, 2.0, 3.0])
    # Substituting the end point instead moved the prediction at 2 s to 1.964.
    plain = kmp_predict(kmp_fit(ref, 1.0, 1.0), np.array([2.0]))[0]
    with_via = kmp_predict(kmp_fit(adapted, 1.0, 1.0), np.array([2.0, 3.0]))
    assert abs(plain[0] - 2.0) < 5e-3 and abs(with_via[0, 0] - 2.0) < 5e-3, with_via[0, 0]
    assert abs(with_via[1, 0] - 3.0) < 1e-6


def test_a_via_point_between_reference_points_keeps_the_learned_shape():
    ref = smooth_reference(n=80, duration=8.0)
    s_via = 0.5 * (ref.s[40] + ref.s[41])
    truth = np.r_[np.sin(s_via), 0.5 * np.sin(0.5 * s_via), 0.1 * s_via]
    adapted = insert_via_points(ref, [ViaPoint.of(s_via, np.r_[truth, NAN3, NAN3], 1e-10)], TOL_S)
    assert len(adapted.s) == 81 and set(ref.s) <= set(adapted.s)
    t = np.linspace(ref.s[38], ref.s[43], 51)
    vel = np.c_[np.cos(t), 0.25 * np.cos(0.5 * t), np.full(len(t), 0.1)]
    pred = kmp_predict(kmp_fit(adapted, 10.0, 0.5), t)[:, 3:6]
    assert np.abs(pred - vel).max() / np.abs(vel).max() < 5e-3


def test_a_via_point_on_a_reference_input_replaces_that_point():
    ref = smooth_reference()
    via = ViaPoint.of(ref.s[10] + 0.5 * TOL_S, np.r_[1.0, 2.0, 3.0, NAN3, NAN3], 1e-10)
    adapted = insert_via_points(ref, [via], TOL_S)
    assert len(adapted.s) == len(ref.s)
    np.testing.assert_array_equal(adapted.mean[10, :3], [1.0, 2.0, 3.0])
    np.testing.assert_array_equal(adapted.mean[10, 3:], ref.mean[10, 3:])
    assert np.all(adapted.cov[10][:3, 3:] == 0.0)


def test_two_via_points_closer_than_the_reference_spacing_both_count():
    ref = smooth_reference()  # spacing 0.1 s
    a = ViaPoint.of(2.03, np.r_[0.50, 0.2, 0.3, NAN3, NAN3], 1e-10)
    b = ViaPoint.of(2.05, np.r_[0.51, 0.2, 0.3, NAN3, NAN3], 1e-10)
    adapted = insert_via_points(ref, [a, b], TOL_S)
    assert len(adapted.s) == len(ref.s) + 2
    out = kmp_predict(kmp_fit(adapted, 10.0, 0.5), np.array([2.03, 2.05]))
    np.testing.assert_allclose(out[:, :3], [a.mean[:3], b.mean[:3]], atol=5e-4)


def test_a_large_variance_leaves_an_output_to_the_demonstrations():
    ref = smooth_reference()
    s_via = 4.05
    pos = np.r_[np.sin(s_via), 0.5 * np.sin(0.5 * s_via), 0.1 * s_via]
    demo_vel = np.r_[np.cos(s_via), 0.25 * np.cos(0.5 * s_via), 0.1]
    wanted_vel = demo_vel + 1.0
    mean = np.r_[pos, wanted_vel, NAN3]
    variances = {
        "pinned": np.r_[np.full(6, 1e-10), np.ones(3)],
        "free": np.r_[1e-10 * np.ones(3), 1e2 * np.ones(6)],
    }
    out = {}
    for name, var in variances.items():
        adapted = insert_via_points(ref, [ViaPoint.of(s_via, mean, var)], TOL_S)
        out[name] = kmp_predict(kmp_fit(adapted, 10.0, 0.5), np.array([s_via]))[0]
    np.testing.assert_allclose(out["pinned"][3:6], wanted_vel, atol=1e-3)
    np.testing.assert_allclose(out["free"][:3], pos, atol=1e-3)
    assert np.abs(out["free"][3:6] - demo_vel).max() < 0.05
    assert np.abs(out["free"][3:6] - wanted_vel).min() > 0.9


@pytest.mark.parametrize(
    ("mean", "cov", "message"),
    [
        (np.zeros(8), np.eye(9), "must be"),
        (np.zeros(9), np.eye(8), "must be"),
        (np.full(9, np.nan), np.eye(9), "every output is NaN"),
        (np.zeros(9), -np.eye(9), "not positive definite"),
        (np.zeros(9), np.triu(np.ones((9, 9))), "symmetric"),
        (np.zeros(9), np.full((9, 9), np.nan), "finite"),
        (np.r_[np.inf, np.zeros(8)], np.eye(9), "finite"),
    ],
)
def test_a_bad_via_point_is_refused_with_a_message(mean, cov, message):
    with pytest.raises(ConfigError, match=message):
        ViaPoint(1.0, mean, cov)


def test_a_free_output_ignores_its_covariance_entries():
    cov = np.eye(9)
    cov[3:, 3:] = np.nan  # free outputs: not read
    ViaPoint(1.0, np.r_[0.0, 0.0, 0.0, NAN3, NAN3], cov)


def dense_kernel(a: np.ndarray, b: np.ndarray, width: float) -> np.ndarray:
    """The KMP kernel block by block, written out from its definition (not the production
    code): position and pelvis use k, position-velocity dk/ds_j, velocity-position dk/ds_i,
    velocity-velocity d2k/(ds_i ds_j)."""
    out = np.zeros((9 * len(a), 9 * len(b)))
    eye = np.eye(3)
    for i, si in enumerate(a):
        for j, sj in enumerate(b):
            d = si - sj
            k = np.exp(-(d**2) / (2 * width**2))
            block = np.zeros((9, 9))
            block[0:3, 0:3] = k * eye
            block[6:9, 6:9] = k * eye
            block[0:3, 3:6] = d / width**2 * k * eye
            block[3:6, 0:3] = -d / width**2 * k * eye
            block[3:6, 3:6] = (1 / width**2 - d**2 / width**4) * k * eye
            out[9 * i : 9 * i + 9, 9 * j : 9 * j + 9] = block
    return out


def worked_example() -> tuple[Reference, list[ViaPoint]]:
    s = np.array([0.0, 0.4, 0.8, 1.2])
    rng = np.random.default_rng(3)
    mean = rng.normal(size=(4, 9))
    a = rng.normal(size=(4, 9, 9))
    cov = 0.01 * (a @ np.swapaxes(a, 1, 2) + np.eye(9))
    via = [
        ViaPoint.of(0.6, np.r_[0.3, -0.2, 0.5, NAN3, NAN3], 1e-6),
        ViaPoint.of(0.8, np.r_[NAN3, 0.1, 0.0, -0.1, NAN3], 1e-4),
    ]
    return Reference(s, mean, cov), via


def test_kmp_matches_a_dense_solve_written_out():
    ref, via = worked_example()
    lam, width = 2.0, 0.5
    # By hand: the via point at 0.6 s is a fifth point observing the position only; the
    # one at 0.8 s replaces the third point's velocity and its correlations.
    s = np.array([0.0, 0.4, 0.6, 0.8, 1.2])
    mu = np.vstack(
        [ref.mean[0], ref.mean[1], np.r_[0.3, -0.2, 0.5, np.zeros(6)], ref.mean[2], ref.mean[3]]
    )
    mu[3, 3:6] = [0.1, 0.0, -0.1]
    sig = [
        ref.cov[0],
        ref.cov[1],
        np.diag(np.r_[np.full(3, 1e-6), np.zeros(6)]),
        ref.cov[2].copy(),
        ref.cov[3],
    ]
    sig[3][3:6, :] = 0.0
    sig[3][:, 3:6] = 0.0
    sig[3][3:6, 3:6] = 1e-4 * np.eye(3)
    keep = np.ones(45, bool)
    keep[9 * 2 + 3 : 9 * 3] = False  # the added point's velocity and pelvis are unobserved
    big_k = dense_kernel(s, s, width)[np.ix_(keep, keep)]
    big_sigma = np.zeros((45, 45))
    for i in range(5):
        big_sigma[9 * i : 9 * i + 9, 9 * i : 9 * i + 9] = sig[i]
    big_sigma = big_sigma[np.ix_(keep, keep)]
    s_star = np.array([0.1, 0.6, 0.8, 1.5])
    k_star = dense_kernel(s_star, s, width)[:, keep]
    expected_mean = k_star @ np.linalg.solve(big_k + lam * big_sigma, mu.reshape(-1)[keep])
    lam_c = 7.0
    c_inv_kt = np.linalg.solve(big_k + lam_c * big_sigma, k_star.T)
    k_ss = dense_kernel(np.zeros(1), np.zeros(1), width)
    expected_cov = np.stack(
        [
            5 / lam_c * (k_ss - k_star[9 * m : 9 * m + 9] @ c_inv_kt[:, 9 * m : 9 * m + 9])
            for m in range(4)
        ]
    )

    adapted = insert_via_points(ref, via, TOL_S)
    np.testing.assert_array_equal(adapted.s, s)
    mean = kmp_predict(kmp_fit(adapted, lam, width), s_star)
    np.testing.assert_allclose(mean.reshape(-1), expected_mean, rtol=1e-8, atol=1e-10)
    cov = kmp_predict_covariance(kmp_covariance_fit(adapted, lam_c, width), s_star)
    np.testing.assert_allclose(cov, expected_cov, rtol=1e-7, atol=1e-10)


def test_predicted_covariance_shrinks_at_a_via_point_with_its_variance():
    # With one via point dominating, N / lambda_c (k - k^2 / (k + lambda_c sigma)) tends to
    # N sigma: the prediction is as certain as the via point, scaled by N.
    ref = smooth_reference()
    s_via, n = 4.05, len(ref.s) + 1
    plain = kmp_predict_covariance(kmp_covariance_fit(ref, n, 0.5), np.array([s_via]))[0]
    pos_var = {}
    for variance in (1e-6, 1e-8):
        via = ViaPoint.of(s_via, np.r_[0.1, 0.2, 0.3, NAN3, NAN3], variance)
        adapted = insert_via_points(ref, [via], TOL_S)
        cov = kmp_predict_covariance(kmp_covariance_fit(adapted, n, 0.5), np.array([s_via]))[0]
        pos_var[variance] = np.diag(cov)[:3]
        assert np.all(pos_var[variance] <= n * variance), (pos_var[variance], n * variance)
        assert np.all(np.linalg.eigvalsh(cov) > -1e-12)
    assert np.all(pos_var[1e-6] < 0.5 * np.diag(plain)[:3])
    ratio = pos_var[1e-8] / pos_var[1e-6]
    assert np.all((ratio > 0.005) & (ratio < 0.02)), ratio


def test_gmr_recovers_a_linear_trend():
    rng = np.random.default_rng(0)
    s = np.tile(np.linspace(0.0, 10.0, 500), 4)
    xi = np.c_[0.3 * s + 1.0, -0.1 * s] + rng.normal(0.0, 0.01, (len(s), 2))
    ref = gmr(fit_gmm(s, xi, 4, seed=0), np.linspace(1.0, 9.0, 9))
    np.testing.assert_allclose(ref.mean[:, 0], 0.3 * ref.s + 1.0, atol=0.02)
    np.testing.assert_allclose(ref.mean[:, 1], -0.1 * ref.s, atol=0.02)
    assert np.all(np.linalg.eigvalsh(ref.cov) > 0.0)
