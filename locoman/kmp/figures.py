"""The learned reference as a picture: demonstrations, GMR and KMP with their covariance bands."""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

from locoman.kmp.demos import Demos
from locoman.kmp.fit import CaseResult
from locoman.kmp.gmr import Reference

#: Bands span mean +- BAND_SIGMAS standard deviations.
BAND_SIGMAS = 2.0
OUTPUT_LABELS = (
    "wrist x [m]",
    "wrist y [m]",
    "wrist z [m]",
    "wrist vx [m/s]",
    "wrist vy [m/s]",
    "wrist vz [m/s]",
    "pelvis x [m]",
    "pelvis y [m]",
    "pelvis yaw [rad]",
)


def _std(cov: np.ndarray) -> np.ndarray:
    return np.sqrt(np.clip(np.diagonal(cov, axis1=1, axis2=2), 0.0, None))


def reference_figure(demos: Demos, ref: Reference, case: CaseResult, title: str) -> Figure:
    """3 x 3 panels, one per output: the demonstrations (grey), the GMR mean and its band
    (blue), the KMP mean and its predictive band (orange), the via points (black)."""
    fig = Figure(figsize=(13, 8.5), layout="constrained")
    axes = fig.subplots(3, 3, sharex=True)
    gmr_std, kmp_std = _std(ref.cov), _std(case.cov)
    kmp_at_cov = np.array([np.interp(case.cov_time_s, case.time_s, y) for y in case.outputs.T]).T
    for o, ax in enumerate(axes.ravel()):
        for demo in demos.outputs:
            ax.plot(demos.time_s, demo[:, o], color="0.7", lw=0.6)
        ax.fill_between(
            ref.s,
            ref.mean[:, o] - BAND_SIGMAS * gmr_std[:, o],
            ref.mean[:, o] + BAND_SIGMAS * gmr_std[:, o],
            color="tab:blue",
            alpha=0.2,
            lw=0,
        )
        ax.plot(ref.s, ref.mean[:, o], color="tab:blue", lw=1.0, label="GMR")
        ax.fill_between(
            case.cov_time_s,
            kmp_at_cov[:, o] - BAND_SIGMAS * kmp_std[:, o],
            kmp_at_cov[:, o] + BAND_SIGMAS * kmp_std[:, o],
            color="tab:orange",
            alpha=0.3,
            lw=0,
        )
        ax.plot(case.time_s, case.outputs[:, o], color="tab:orange", lw=1.2, label="KMP")
        for v in case.via:
            if np.isfinite(v.mean[o]):
                ax.plot(v.s, v.mean[o], "kx", ms=7, mew=1.5)
        ax.set_ylabel(OUTPUT_LABELS[o])
        ax.grid(alpha=0.3)
    for ax in axes[-1]:
        ax.set_xlabel("time [s]")
    axes[0, 0].legend(loc="best", fontsize=8)
    fig.suptitle(
        f"{title}: demonstrations (grey), GMR and KMP means with +-{BAND_SIGMAS:g} sigma bands, "
        "via points (x)"
    )
    return fig
