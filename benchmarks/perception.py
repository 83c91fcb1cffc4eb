"""Benchmark of the perception front half: generate + masks + clouds per subtask.

Usage: python benchmarks/perception.py [--out benchmarks/results/perception.json]
Needs the scene stages (`dvc repro scene`). Runs every perception scenario at the default
resolution into a temporary folder, RUNS times, and quotes medians (these machines are noisy).
"""

from __future__ import annotations

import argparse
import platform
import resource
import tempfile
import time
from pathlib import Path

import numpy as np
from common import write_benchmark

from locoman.config import load_params
from locoman.perception.clouds import clouds_scenario
from locoman.perception.generate import generate_scenario
from locoman.perception.masks import masks_scenario
from locoman.stage import DATA_DIR

RUNS = 3


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="benchmarks/results/perception.json")
    args = parser.parse_args()
    cfg = load_params()
    p = cfg.perception
    per_stage: dict[str, list[float]] = {"generate": [], "masks": [], "clouds": []}
    subtasks = 0
    for _ in range(RUNS):
        subtasks = 0
        for scenario in p.scenarios:
            with tempfile.TemporaryDirectory() as tmp:
                gen, msk, cld = (Path(tmp) / s for s in ("generate", "masks", "clouds"))
                tic = time.perf_counter()
                n = generate_scenario(
                    scenario, DATA_DIR / scenario / "scene", gen, p.generate, cfg.seed
                )["subtasks"]
                per_stage["generate"].append((time.perf_counter() - tic) / n)
                tic = time.perf_counter()
                masks_scenario(scenario, gen, msk, p.masks, cfg.seed)
                per_stage["masks"].append((time.perf_counter() - tic) / n)
                tic = time.perf_counter()
                clouds_scenario(scenario, gen, msk, cld, p.clouds, p.depth_error, cfg.seed)
                per_stage["clouds"].append((time.perf_counter() - tic) / n)
                subtasks += n
    result = {
        "resolution_px": [p.generate.width, p.generate.height],
        "scenarios": list(p.scenarios),
        "subtasks": subtasks,
        "runs": RUNS,
        "seconds_per_subtask": {k: float(np.median(v)) for k, v in per_stage.items()},
        "seconds_per_subtask_total": float(sum(np.median(v) for v in per_stage.values())),
        "peak_rss_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
        "machine": platform.platform(),
        "notes": "generate includes the sim view and ground truth; masks scores grabcut too",
    }
    write_benchmark(args.out, result)
    print(result)


if __name__ == "__main__":
    main()
