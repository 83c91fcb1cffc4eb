"""Solve time and iterations of the TO on ``tiny`` as the number of nodes grows.

Usage: python benchmarks/to_tiny.py [--scales 0.75 1.0 1.25] [--repeats 1]
       [--out benchmarks/results/to_tiny.json]

Each scale multiplies every phase's node count of ``solve.schedule`` (params.yaml); the
scene, contacts and keyframes are the current ``data/tiny`` artifacts. The compiled
derivatives do not depend on N, so only the first build compiles.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import statistics
from pathlib import Path

from locoman.artifacts import write_json_atomic
from locoman.config import load_params
from locoman.to.pipeline import load_inputs
from locoman.to.trajopt import TrajectoryOptimizer


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scales", type=float, nargs="+", default=[0.75, 1.0, 1.25])
    parser.add_argument("--repeats", type=int, default=1)
    parser.add_argument("--out", default="benchmarks/results/to_tiny.json")
    args = parser.parse_args()
    cfg = load_params().solve
    root = Path("data/tiny")
    inputs = load_inputs(root / "scene", root / "contacts", root / "retarget")
    solver = dataclasses.replace(cfg.solver, print_level=0)
    rows = []
    for scale in args.scales:
        counts = {
            f.name: max(1, round(getattr(cfg.schedule, f.name) * scale))
            for f in dataclasses.fields(cfg.schedule)
            if f.name.endswith("_nodes")
        }
        schedule = dataclasses.replace(cfg.schedule, **counts)
        optimizer = TrajectoryOptimizer(
            inputs, schedule, cfg.weights, cfg.contact, cfg.collision, solver, Path(cfg.cache_dir)
        )
        runs = [
            optimizer.solve((cfg.keyframe_base, cfg.keyframe_foot)) for _ in range(args.repeats)
        ]
        row = {
            "scale": scale,
            "nodes": optimizer.schedule.nodes,
            "n_variables": optimizer.nlp.n_x,
            "n_constraints": optimizer.nlp.n_g,
            "build_time_s": optimizer.nlp.build_time_s,
            "status": [r.status for r in runs],
            "iterations": [r.iterations for r in runs],
            "solve_time_s": [r.solve_time_s for r in runs],
            "solve_time_median_s": statistics.median(r.solve_time_s for r in runs),
            "seconds_per_iteration": statistics.median(
                r.solve_time_s / max(r.iterations, 1) for r in runs
            ),
        }
        print(json.dumps(row), flush=True)
        rows.append(row)
    write_json_atomic(args.out, {"scenario": "tiny", "runs": rows})


if __name__ == "__main__":
    main()
