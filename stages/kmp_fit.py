"""Stage `kmp_fit`: GMM/GMR reference of the demos, then KMP adapted to every case's via points.

Usage: python stages/kmp_fit.py   (reads params.yaml, data/<demos.scenario>/scene/ and demos/,
writes data/<demos.scenario>/kmp_fit/)
"""

from __future__ import annotations

from locoman.kernels import pin_kernels

pin_kernels()  # first: NumPy, OpenBLAS and OpenCV choose their CPU kernels when they load

import sys
from pathlib import Path

import numpy as np

from locoman.artifacts import read_npz, write_figure, write_metrics, write_npz
from locoman.artifacts.io import write_text_atomic
from locoman.config import load_params
from locoman.kmp.demos import Demos, task_points
from locoman.kmp.figures import reference_figure
from locoman.kmp.fit import fit_case, kmp_vs_gmr, predict_seconds, reference_of, via_points
from locoman.kmp.io import DEMOS, GMR, REFERENCE
from locoman.scene.io import load_objects, load_plan
from locoman.stage import DATA_DIR, StageOutputs, run_stage

PLOT_RATE_HZ = 20.0  # the dvc plots CSV: Vega inlines every row of every curve


def main(outputs: StageOutputs) -> Path:
    cfg = load_params()
    d, k = cfg.demos, cfg.kmp
    root = DATA_DIR / d.scenario
    _, task = task_points(load_objects(root / "scene"), load_plan(root / "scene"), d.grasp_height)
    raw = read_npz(root / "demos" / "demos.npz", DEMOS)
    demos = Demos(raw["time_s"], raw["wrist_pos"], raw["wrist_vel"], raw["pelvis"])
    demos = demos.subset(raw["selected"])
    duration = float(demos.time_s[-1])
    out = outputs.folder(d.scenario, "kmp_fit")

    ref, gmr_s = reference_of(demos, k, cfg.seed)
    write_npz(out / "gmr.npz", GMR, {"s": ref.s, "mean": ref.mean, "cov": ref.cov})
    metrics: dict = {"gmr_seconds": gmr_s, "cases": {}}
    for name, case_cfg in k.cases.items():
        via = via_points(case_cfg.via_points, task, k.via_point_variance)
        case = fit_case(ref, via, k, duration)
        write_npz(
            out / f"reference_{name}.npz",
            REFERENCE,
            {
                "time_s": case.time_s,
                "wrist_pos": case.outputs[:, 0:3],
                "wrist_vel": case.outputs[:, 3:6],
                "pelvis": case.outputs[:, 6:9],
                "base": case.base,
                "via_time_s": np.array([v.s for v in case.via], dtype=float),
                "via_mean": np.array([v.mean for v in case.via], dtype=float).reshape(-1, 9),
                "via_cov": np.array([v.cov for v in case.via], dtype=float).reshape(-1, 9, 9),
                "cov_time_s": case.cov_time_s,
                "cov": case.cov,
            },
        )
        write_figure(
            out / f"reference_{name}.png",
            reference_figure(demos, ref, case, f"Paper B, learned reference ({name})"),
        )
        step = max(1, round(k.rate_hz / PLOT_RATE_HZ))
        rows = np.c_[case.time_s, case.outputs, case.base][::step]
        header = "time_s,x,y,z,vx,vy,vz,pelvis_x,pelvis_y,pelvis_yaw,base_x,base_y,base_yaw"
        write_text_atomic(
            out / "plots" / f"reference_{name}.csv",
            header + "\n" + "\n".join(",".join(f"{v:.6g}" for v in r) for r in rows) + "\n",
        )
        metrics["cases"][name] = {"via_error": case.via_errors, "kmp_seconds": case.fit_s}
    fit_s = gmr_s + min(c["kmp_seconds"] for c in metrics["cases"].values())
    vs_gmr = kmp_vs_gmr(ref, k)
    failed = [
        f"{name}.via_point_error"
        for name, case in metrics["cases"].items()
        if case["via_error"]["position_m"] > k.via_point_error_max_m
    ]
    metrics |= {
        "success": not failed,
        "failed_checks": failed,
        "via_point_error_max": max(c["via_error"]["position_m"] for c in metrics["cases"].values()),
        "kmp_vs_gmr_rmse": vs_gmr["position_m"],
        "kmp_vs_gmr": vs_gmr,
        "fit_seconds": fit_s,
        "predict_seconds_26s_at_1khz": predict_seconds(ref, k, duration),
    }
    write_metrics(out, metrics)
    return out


if __name__ == "__main__":
    run_stage(main, sys.argv[1:])
