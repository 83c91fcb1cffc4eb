"""The kmp_fit stage's work: GMM/GMR reference, KMP per adaptation case, and its figures."""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from locoman.config.skill_transfer import KmpCfg, ViaPointCfg
from locoman.kmp.demos import Demos, TaskPoints
from locoman.kmp.gmr import Reference, fit_gmm, gmr
from locoman.kmp.kmp import (
    N_OUT,
    ViaPoint,
    insert_via_points,
    kmp_covariance_fit,
    kmp_fit,
    kmp_predict,
    kmp_predict_covariance,
)

PREDICT_REPEATS = 5
COV_RATE_HZ = 10.0  # the covariance is drawn, not tracked: the reference's own rate


@dataclasses.dataclass(frozen=True)
class CaseResult:
    """One adapted reference, sampled at the controller's rate.

    Attributes:
        time_s: (T,) [s].
        outputs: (T, 9) wrist position [m], wrist velocity [m/s], pelvis (x, y, yaw).
        base: (T, 3) base command q_b,d in Sigma_B (x [m], y [m], yaw [rad]).
        via: The via points inserted.
        via_errors: Largest |prediction - via point| per output group: position [m],
            velocity [m/s], pelvis (mixed).
        fit_s: Time to insert the via points and solve the KMP [s].
        cov_time_s: (C,) inputs of the covariance prediction, at ``COV_RATE_HZ`` [s].
        cov: (C, 9, 9) KMP's predicted covariance there (units^2).
    """

    time_s: np.ndarray
    outputs: np.ndarray
    base: np.ndarray
    via: list[ViaPoint]
    via_errors: dict[str, float]
    fit_s: float
    cov_time_s: np.ndarray
    cov: np.ndarray


def pelvis_to_base(pelvis: np.ndarray, offset: float) -> np.ndarray:
    """Sigma_B (x, y, yaw) from the learned pelvis, which maps to Sigma_R ``offset`` m ahead."""
    yaw = pelvis[:, 2]
    return np.c_[pelvis[:, 0] - offset * np.cos(yaw), pelvis[:, 1] - offset * np.sin(yaw), yaw]


def via_points(
    points: list[ViaPointCfg], task: TaskPoints, default_variance: float
) -> list[ViaPoint]:
    """Config via points as :class:`ViaPoint`, ``at`` resolved to the scene's task points; an
    output group without its own variance gets ``default_variance``."""
    out = []
    for p in points:
        mean = np.full(N_OUT, np.nan)
        wrist = {"grasp": task.grasp, "place": task.place}.get(p.at or "", p.wrist_pos)
        if wrist is not None:
            mean[0:3] = wrist
        if p.wrist_vel is not None:
            mean[3:6] = p.wrist_vel
        if p.pelvis is not None:
            mean[6:9] = p.pelvis
        variance = np.repeat(
            [
                default_variance if v is None else v
                for v in (p.wrist_pos_variance, p.wrist_vel_variance, p.pelvis_variance)
            ],
            3,
        )
        out.append(ViaPoint.of(float(p.time_s), mean, variance))
    return out


def reference_of(demos: Demos, cfg: KmpCfg, seed: int) -> tuple[Reference, float]:
    """GMM/GMR reference over ``cfg.n_reference`` inputs spanning the demos; (ref, seconds)."""
    tic = time.perf_counter()
    m, n = demos.wrist_pos.shape[:2]
    gmm = fit_gmm(
        np.tile(demos.time_s, m),
        demos.outputs.reshape(m * n, N_OUT),
        cfg.gmm_components,
        seed,
        cfg.gmm_tolerance,
    )
    ref = gmr(gmm, np.linspace(demos.time_s[0], demos.time_s[-1], cfg.n_reference))
    return ref, time.perf_counter() - tic


def fit_case(ref: Reference, via: list[ViaPoint], cfg: KmpCfg, duration_s: float) -> CaseResult:
    """Insert the via points, fit the KMP and predict at ``cfg.rate_hz`` over the task."""
    tic = time.perf_counter()
    adapted = insert_via_points(ref, via, cfg.via_point_time_tol_s)
    model = kmp_fit(adapted, cfg.regularization, cfg.kernel_width_s)
    fit_s = time.perf_counter() - tic
    cov_model = kmp_covariance_fit(adapted, cfg.covariance_regularization, cfg.kernel_width_s)
    cov_time = np.linspace(0.0, duration_s, round(duration_s * COV_RATE_HZ) + 1)
    t = np.linspace(0.0, duration_s, round(duration_s * cfg.rate_hz) + 1)
    out = kmp_predict(model, t)
    errors = {"position_m": 0.0, "velocity_mps": 0.0, "pelvis": 0.0}
    for v in via:
        miss = np.abs(kmp_predict(model, np.array([v.s]))[0] - v.mean)
        for key, sl in zip(errors, (slice(0, 3), slice(3, 6), slice(6, 9)), strict=True):
            if np.any(~np.isnan(v.mean[sl])):
                errors[key] = max(errors[key], float(np.nanmax(miss[sl])))
    return CaseResult(
        t,
        out,
        pelvis_to_base(out[:, 6:9], cfg.pelvis_to_base_m),
        via,
        errors,
        fit_s,
        cov_time,
        kmp_predict_covariance(cov_model, cov_time),
    )


def predict_seconds(ref: Reference, cfg: KmpCfg, duration_s: float) -> float:
    """Median time [s] of predicting the whole task at ``cfg.rate_hz`` (several runs)."""
    model = kmp_fit(ref, cfg.regularization, cfg.kernel_width_s)
    t = np.linspace(0.0, duration_s, round(duration_s * cfg.rate_hz) + 1)
    runs = []
    for _ in range(PREDICT_REPEATS):
        tic = time.perf_counter()
        kmp_predict(model, t)
        runs.append(time.perf_counter() - tic)
    return float(np.median(runs))


def kmp_vs_gmr(ref: Reference, cfg: KmpCfg) -> dict[str, float]:
    """RMSE between the KMP without via points and the GMR mean, at the reference inputs."""
    pred = kmp_predict(kmp_fit(ref, cfg.regularization, cfg.kernel_width_s), ref.s)
    err = pred - ref.mean
    rms = np.sqrt(np.mean(err**2, axis=0))
    return {
        "position_m": float(np.sqrt(np.mean(rms[0:3] ** 2))),
        "velocity_mps": float(np.sqrt(np.mean(rms[3:6] ** 2))),
        "pelvis_xy_m": float(np.sqrt(np.mean(rms[6:8] ** 2))),
        "pelvis_yaw_rad": float(rms[8]),
    }
