"""Benchmark of the mobile-manipulator branch: KMP prediction and the 1 kHz HQP step.

Usage: python benchmarks/mm_branch.py [--out benchmarks/results/mm_branch.json]
Needs `dvc repro kmp_fit` first (reads data/<demos.scenario>/kmp_fit/ and scene/).
Quotes medians over several runs; these machines are noisy.
"""

from __future__ import annotations

import argparse
import platform
import time

import numpy as np
from common import write_benchmark

from locoman.artifacts import read_npz
from locoman.config import load_params
from locoman.hqp.replay import ReplayTask, replay
from locoman.kmp.gmr import Reference
from locoman.kmp.io import GMR
from locoman.kmp.kmp import kmp_fit, kmp_predict
from locoman.scene.io import load_scene_model, load_state
from locoman.stage import DATA_DIR

RUNS = 5
REPLAY_S = 5.0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="benchmarks/results/mm_branch.json")
    args = parser.parse_args()
    cfg = load_params()
    root = DATA_DIR / cfg.demos.scenario
    g = read_npz(root / "kmp_fit" / "gmr.npz", GMR)
    ref = Reference(g["s"], g["mean"], g["cov"])
    t = np.linspace(0.0, cfg.demos.duration_s, round(cfg.demos.duration_s * cfg.kmp.rate_hz) + 1)
    fit, predict = [], []
    for _ in range(RUNS):
        tic = time.perf_counter()
        model = kmp_fit(ref, cfg.kmp.regularization, cfg.kmp.kernel_width_s)
        fit.append(time.perf_counter() - tic)
        tic = time.perf_counter()
        out = kmp_predict(model, t)
        predict.append(time.perf_counter() - tic)
    n = round(REPLAY_S / cfg.hqp.dt) + 1
    pel = out[:n, 6:9]
    off = cfg.kmp.pelvis_to_base_m
    base = np.c_[
        pel[:, 0] - off * np.cos(pel[:, 2]), pel[:, 1] - off * np.sin(pel[:, 2]), pel[:, 2]
    ]
    task = ReplayTask(
        t[:n],
        out[:n, :3],
        out[:n, 3:6],
        base,
        np.asarray(cfg.demos.grasp_velocity),
        1e9,
        2e9,
        "bottle",
        np.zeros(3),
    )
    home = load_state(root / "scene")["qpos"]
    medians, p99s, rtf = [], [], []
    for _ in range(RUNS):
        log = replay(load_scene_model(root / "scene"), home, task, cfg.hqp)
        medians.append(np.median(log.hqp_step_s))
        p99s.append(np.percentile(log.hqp_step_s, 99))
        rtf.append(REPLAY_S / log.wall_s)
    write_benchmark(
        args.out,
        {
            "machine": platform.processor() or platform.machine(),
            "runs": RUNS,
            "kmp_fit_seconds_median": float(np.median(fit)),
            "kmp_predict_26s_at_1khz_seconds_median": float(np.median(predict)),
            "hqp_step_median_s": float(np.median(medians)),
            "hqp_step_p99_s_median": float(np.median(p99s)),
            "replay_realtime_factor_median": float(np.median(rtf)),
        },
    )


if __name__ == "__main__":
    main()
