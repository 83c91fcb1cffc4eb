"""Paper B's Fig. 5 (replica) and Fig. 6 (generalisation) drawn from a replay."""

from __future__ import annotations

import dataclasses

import numpy as np
from matplotlib.figure import Figure

AXES = ("x", "y", "z")
BASE_AXES = ("x [m]", "y [m]", "yaw [rad]")


@dataclasses.dataclass(frozen=True)
class ReplaySeries:
    """A replay at the export rate, in the quantities the paper plots.

    Attributes:
        time_s: (T,) [s].
        ee_pos_desired, ee_pos: (T, 3) EE desired and actual position, world [m].
        ee_pos_arm: (T, 3) EE actual position in the arm base frame Sigma_R [m].
        base_learned, base_optimal, base_actual: (T, 3) base x [m], y [m], yaw [rad].
        ee_vel_desired, ee_vel: (T, 3) EE desired and actual velocity, world [m/s].
        grasp_time_s: The grasp instant [s].
        grasp_velocity: (3,) desired EE velocity at the grasp [m/s].
    """

    time_s: np.ndarray
    ee_pos_desired: np.ndarray
    ee_pos: np.ndarray
    ee_pos_arm: np.ndarray
    base_learned: np.ndarray
    base_optimal: np.ndarray
    base_actual: np.ndarray
    ee_vel_desired: np.ndarray
    ee_vel: np.ndarray
    grasp_time_s: float
    grasp_velocity: np.ndarray


def replay_figure(series: ReplaySeries, title: str) -> Figure:
    """Four rows as in the paper: EE desired vs actual position (world); EE actual position in
    the arm base frame; base learned, HQP optimal and actual pose; EE desired vs actual
    velocity. As in the paper, magenta circles mark the desired initial point and red ones
    the desired grasp point; the grasp instant is a dotted line and its desired velocity a
    black dot."""
    r = series
    fig = Figure(figsize=(13, 11), layout="constrained")
    axes = fig.subplots(4, 3, sharex=True)
    for i in range(3):
        a = axes[0, i]
        a.plot(r.time_s, r.ee_pos_desired[:, i], "--", label="desired")
        a.plot(r.time_s, r.ee_pos[:, i], label="actual")
        a.plot(r.time_s[0], r.ee_pos_desired[0, i], "o", mfc="none", mec="m", ms=9)
        k = int(np.searchsorted(r.time_s, r.grasp_time_s))
        a.plot(r.time_s[k], r.ee_pos_desired[k, i], "o", mfc="none", mec="r", ms=9)
        a.set_ylabel(f"EE {AXES[i]} world [m]")
        axes[1, i].plot(r.time_s, r.ee_pos_arm[:, i], color="tab:green")
        axes[1, i].set_ylabel(f"EE {AXES[i]} arm base [m]")
        a = axes[2, i]
        a.plot(r.time_s, r.base_learned[:, i], "--", label="learned")
        a.plot(r.time_s, r.base_optimal[:, i], label="HQP optimal")
        a.plot(r.time_s, r.base_actual[:, i], ":", label="actual")
        a.set_ylabel(f"base {BASE_AXES[i]}")
        a = axes[3, i]
        a.plot(r.time_s, r.ee_vel_desired[:, i], "--", label="desired")
        a.plot(r.time_s, r.ee_vel[:, i], label="actual")
        a.plot(r.grasp_time_s, r.grasp_velocity[i], "ko", label="grasp velocity")
        a.set_ylabel(f"EE v{AXES[i]} [m/s]")
    for a in axes.ravel():
        a.axvline(r.grasp_time_s, color="0.4", ls=":", lw=1)
        a.grid(alpha=0.3)
    for a in axes[-1]:
        a.set_xlabel("time [s]")
    for row in (0, 2, 3):
        axes[row, 0].legend(fontsize=8, loc="best")
    fig.suptitle(f"{title} (dotted line: grasp)")
    return fig


#: Paper B, Sec. IV-C: the RMSEs it reports, per case (Fig. 5 replica, Fig. 6 generalisation).
PAPER_RMSE = {
    "replica": {
        "rmse_ee_pos_m": [0.1428, 0.0505, 0.0250],
        "rmse_ee_vel_mps": [0.0415, 0.0353, 0.0241],
        "rmse_base_learned_vs_optimal": [0.1912, 0.2297, 0.3132],
        "rmse_base_optimal_vs_actual": [0.1875, 0.1149, 0.1735],
    },
    "generalisation": {
        "rmse_ee_pos_m": [0.1600, 0.0867, 0.0366],
        "rmse_ee_vel_mps": [0.0496, 0.0410, 0.0264],
        "rmse_base_learned_vs_optimal": [0.5102, 0.2682, 0.3652],
        "rmse_base_optimal_vs_actual": [0.4732, 0.1882, 0.2587],
    },
}
RMSE_LABELS = {
    "rmse_ee_pos_m": "EE position x, y, z [m]",
    "rmse_ee_vel_mps": "EE velocity x, y, z [m/s]",
    "rmse_base_learned_vs_optimal": "base learned vs optimal x [m], y [m], yaw [rad]",
    "rmse_base_optimal_vs_actual": "base optimal vs actual x [m], y [m], yaw [rad]",
}


def results_table(metrics: dict[str, dict]) -> str:
    """Markdown: our RMSEs per case next to the paper's (a case the paper has no figure
    for gets a dash)."""
    lines = ["| case | RMSE | paper B | ours |", "|---|---|---|---|"]
    for case, ours in metrics.items():
        for key, label in RMSE_LABELS.items():
            paper = PAPER_RMSE.get(case, {}).get(key)
            paper_s = "-" if paper is None else ", ".join(f"{v:.4f}" for v in paper)
            ours_s = ", ".join(f"{v:.4f}" for v in ours[key])
            lines.append(f"| {case} | {label} | {paper_s} | {ours_s} |")
    return "\n".join(lines) + "\n"
