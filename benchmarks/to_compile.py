"""Compile time of the TO's generated C against the optimisation flags and the size of the
translation units, and the solve time each build gives, on ``tiny``.

Usage: python benchmarks/to_compile.py [--levels 0 1 2] [--splits group function]
       [--repeats 3] [--out benchmarks/results/to_compile.json]

A split of ``group`` compiles the four derivative functions of each stage group
(:mod:`locoman.to.nlp`) into one library, ``function`` each into its own (more, smaller
units, which two cores share out better). Every build starts from an empty cache and runs
as ``make run`` does, one compiler per core. The solve times are medians of ``--repeats``.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import statistics
import tempfile
import time
from pathlib import Path

from locoman.artifacts import write_json_atomic
from locoman.config import load_params
from locoman.to.compile import compile_units
from locoman.to.nlp import stage_derivatives
from locoman.to.pipeline import load_inputs
from locoman.to.trajopt import TrajectoryOptimizer

ROOT = Path("data/tiny")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--levels", nargs="+", default=["0", "1", "2"], help="gcc -O levels")
    parser.add_argument("--splits", nargs="+", default=["group", "function"])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--out", default="benchmarks/results/to_compile.json")
    args = parser.parse_args()
    cfg = load_params().solve
    inputs = load_inputs(ROOT / "scene", ROOT / "contacts", ROOT / "retarget")
    interpreted = dataclasses.replace(cfg.solver, compile=False, print_level=0)

    def optimizer(solver, cache: Path) -> TrajectoryOptimizer:
        return TrajectoryOptimizer(
            inputs, cfg.schedule, cfg.weights, cfg.contact, cfg.collision, solver, cache
        )

    groups = optimizer(interpreted, Path()).nlp.groups
    functions = [stage_derivatives(g, groups[0].function.size1_in(0))[0] for g in groups]
    rows = []
    for flags in (f"-O{level}" for level in args.levels):
        for split in args.splits:
            units = functions if split == "group" else [[f] for fns in functions for f in fns]
            with tempfile.TemporaryDirectory() as tmp:
                tic = time.perf_counter()
                compile_units(units, Path(tmp), [flags])
                compile_s = time.perf_counter() - tic
                size = sum(p.stat().st_size for p in Path(tmp).glob("*.so"))
                solver = dataclasses.replace(
                    cfg.solver, print_level=0, compile_flags=[flags], compile=True
                )
                # The solve loads the same C in one library per group: with the function
                # split only the compile is timed, the run is the group split's.
                solves = []
                if split == "group":
                    opt = optimizer(solver, Path(tmp))
                    solves = [
                        opt.solve((cfg.keyframe_base, cfg.keyframe_foot))
                        for _ in range(args.repeats)
                    ]
            row = {
                "flags": flags,
                "split": split,
                "units": len(units),
                "compile_wall_s": compile_s,
                "library_bytes": size,
                "jobs": os.cpu_count(),
            }
            if solves:
                row |= {
                    "iterations": [s.iterations for s in solves],
                    "solve_time_median_s": statistics.median(s.solve_time_s for s in solves),
                    "seconds_per_iteration": statistics.median(
                        s.solve_time_s / max(s.iterations, 1) for s in solves
                    ),
                }
            print(f"[bench] {row}", flush=True)
            rows.append(row)
    write_json_atomic(args.out, {"scenario": "tiny", "results": rows})


if __name__ == "__main__":
    main()
