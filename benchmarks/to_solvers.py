"""The TO's build and solve times on tiny, S1 and S2, for each compiler configuration.

Usage: python benchmarks/to_solvers.py [--scenarios tiny s1_basket s2_trolley] [--repeats 3]
       [--configs gcc:-O1 tcc:-O0@tiny] [--out benchmarks/results/to_solvers.json]

Per configuration (``compiler:flags``): the time to build the G1's compiled set of terms from
an empty cache (once: a build is deterministic), then per scenario the median of
``--repeats`` runs of the ``solve`` stage's work (the first solve and the rounds that add the
collision pairs it needs) at the defaults of ``params.yaml``: solve time, iterations,
the time per iteration split into the NLP's function evaluations and the rest (IPOPT's
linear algebra, mostly), the build time of a solve whose terms are cached (transcription and
assembly), the problem's size and collision pairs, and whether the ``evaluate`` stage's
checks pass on the solution. The scenes, contacts and keyframes are the current
``data/<scenario>`` artifacts (``dvc repro retarget`` first). One run of the script measures
every configuration, so their ratios are comparable. A configuration ``compiler:flags@a,b``
runs on scenarios ``a`` and ``b`` alone (the default runs tcc on ``tiny`` alone: its build
time is the point, and S1's and S2's solves at its slower code would add half an hour).
"""

from __future__ import annotations

from locoman.kernels import pin_kernels

pin_kernels()  # first, as every stage: NumPy and OpenBLAS choose their kernels when they load

import argparse
import dataclasses
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from common import write_benchmark

from locoman.config import load_params
from locoman.sim.pipeline import evaluate_scenario
from locoman.to.nlp.compile import CACHE_ENV
from locoman.to.pipeline import solve_scenario


def _build_set(cache: Path, compiler: str, flags: list[str]) -> float:
    """Seconds to build the G1's terms into an empty ``cache``, in a fresh process."""
    script = (
        "from pathlib import Path; import sys;"
        "from locoman.to.terms.library import all_kinds, g1_terms;"
        "from locoman.to.nlp.derivatives import load_derivatives;"
        "load_derivatives([k.term for k in all_kinds(g1_terms())], Path(sys.argv[1]), sys.argv[2:])"
    )
    env = dict(os.environ, CC=compiler)
    tic = time.perf_counter()
    subprocess.run([sys.executable, "-c", script, str(cache), *flags], check=True, env=env)
    return time.perf_counter() - tic


def _solve(scenario: str, cfg, evaluate_cfg) -> dict:
    """One run of the ``solve`` stage's work (the first solve and the rounds that add the
    collision pairs it needs), then the ``evaluate`` stage's checks on it."""
    root = Path("data") / scenario
    with tempfile.TemporaryDirectory() as tmp:
        solve_dir, eval_dir = Path(tmp) / "solve", Path(tmp) / "evaluate"
        solve_dir.mkdir()
        tic = time.perf_counter()
        traj = solve_scenario(root / "scene", root / "contacts", root / "retarget", solve_dir, cfg)
        wall = time.perf_counter() - tic
        solved = json.loads((solve_dir / "metrics.json").read_text())
        metrics = evaluate_scenario(root / "scene", solve_dir, eval_dir, evaluate_cfg)
    return {
        "status": traj.status,
        "iterations": traj.iterations,
        "exact_hessian_iterations": traj.exact_iterations,
        "solve_time_s": traj.solve_time_s,
        "function_time_s": traj.function_time_s,
        "other_time_s": traj.solve_time_s - traj.function_time_s,
        "build_time_s": traj.build_time_s,
        "stage_wall_time_s": wall,
        "cost": traj.cost,
        "nodes": solved["nodes"],
        "n_variables": solved["n_variables"],
        "n_constraints": solved["n_constraints"],
        "collision_rounds": len(solved["collision_rounds"]),
        "pairs_found": solved["pairs_found"],
        "evaluation_success": metrics["success"],
        "failed_checks": metrics.get("failed_checks", []),
        "max_penetration_m": metrics["max_penetration_m"],
    }


def _median(runs: list[dict], key: str) -> float:
    return statistics.median(r[key] for r in runs)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenarios", nargs="+", default=["tiny", "s1_basket", "s2_trolley"])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--configs", nargs="+", default=["gcc:-O1", "tcc:-O0@tiny"])
    parser.add_argument("--out", default="benchmarks/results/to_solvers.json")
    args = parser.parse_args()
    # As a stage (locoman.stage.run_stage): one BLAS thread, the same iterates on any machine.
    os.environ["OPENBLAS_NUM_THREADS"] = os.environ["OMP_NUM_THREADS"] = "1"
    params = load_params()
    results = []
    for spec in args.configs:
        config, _, only = spec.partition("@")
        scenarios = [s for s in args.scenarios if not only or s in only.split(",")]
        compiler, _, flags = config.partition(":")
        flag_list = flags.split() if flags else []
        with tempfile.TemporaryDirectory() as cache:
            build = _build_set(Path(cache), compiler, flag_list)
            print(f"[bench] {config}: the G1's terms built in {build:.1f} s", flush=True)
            os.environ[CACHE_ENV], os.environ["CC"] = cache, compiler
            solver = dataclasses.replace(
                params.solve.solver, print_level=0, compile_flags=flag_list
            )
            cfg = dataclasses.replace(params.solve, solver=solver)
            for scenario in scenarios:
                runs = [_solve(scenario, cfg, params.evaluate) for _ in range(args.repeats)]
                iterations = _median(runs, "iterations")
                row = {
                    "config": config,
                    "scenario": scenario,
                    "terms_build_time_s": build,
                    "runs": runs,
                    "solve_time_median_s": _median(runs, "solve_time_s"),
                    "iterations_median": iterations,
                    "function_time_median_s": _median(runs, "function_time_s"),
                    "other_time_median_s": _median(runs, "other_time_s"),
                    "seconds_per_iteration": _median(runs, "solve_time_s") / max(iterations, 1),
                    "function_seconds_per_iteration": _median(runs, "function_time_s")
                    / max(iterations, 1),
                    "build_time_cached_median_s": _median(runs, "build_time_s"),
                    "stage_wall_time_median_s": _median(runs, "stage_wall_time_s"),
                    "collision_rounds": [r["collision_rounds"] for r in runs],
                    "max_penetration_m": [r["max_penetration_m"] for r in runs],
                    "evaluation_success": all(r["evaluation_success"] for r in runs),
                }
                print(
                    f"[bench] {config} {scenario}: {iterations:g} iterations, "
                    f"{row['solve_time_median_s']:.1f} s "
                    f"({row['function_time_median_s']:.1f} s in functions), "
                    f"checks {'pass' if row['evaluation_success'] else 'FAIL'}",
                    flush=True,
                )
                results.append(row)
    out = {
        "machine": {"cpus": os.cpu_count(), "platform": platform.platform()},
        "repeats": args.repeats,
        "results": results,
    }
    write_benchmark(args.out, out)


if __name__ == "__main__":
    main()
