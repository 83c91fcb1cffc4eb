"""The TO's solver settings side by side on a scenario, as the node count grows.

Usage: python benchmarks/to_solvers.py [--scenario tiny] [--scales 1 2 4] [--repeats 3]
       [--configs ipopt_mumps:gauss_newton ipopt_mumps:exact] [--spral-iterations 20]
       [--out benchmarks/results/to_solvers.json]

S2's solve time: ``--scenario s2_trolley --scales 1 --configs ipopt_mumps:gauss_newton
--spral-iterations 0 --out benchmarks/results/to_solvers_s2_trolley.json``.

Each scale multiplies every phase's node count of ``solve.schedule`` (params.yaml); the
scene, contacts and keyframes are the current ``data/<scenario>`` artifacts (``dvc repro
retarget@<scenario>`` first). The compiled derivatives do not depend on the node count, so only a
fresh cache compiles, once. For every backend and scale: the median of ``--repeats`` runs of
the solve time, the iterations, the time per iteration, the final cost, and whether the
evaluation's checks (``evaluate`` stage: dynamics, friction, slip, penetration, goal) pass.
A config is ``backend:hessian`` (``solve.solver.backend``, ``solve.solver.hessian``). One
run of the script measures every config, so their ratios are comparable; ``growth`` is the
exponent b of solve time ~ nodes^b fitted over the scales. IPOPT with SPRAL takes seconds
per iteration here, so it is probed at the default node count for ``--spral-iterations``
iterations (0: not at all) instead of solved.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import platform
import statistics
import tempfile
from pathlib import Path

import numpy as np

from locoman.artifacts import write_json_atomic
from locoman.config import load_params
from locoman.sim.pipeline import evaluate_scenario
from locoman.to.pipeline import build_optimizer, load_inputs, write_solution
from locoman.to.trajopt import BACKENDS


def _scaled(schedule, scale: float):
    counts = {
        f.name: max(1, round(getattr(schedule, f.name) * scale))
        for f in dataclasses.fields(schedule)
        if f.name.endswith("_nodes")
    }
    return dataclasses.replace(schedule, **counts)


def _run(optimizer, inputs, cfg, evaluate_cfg, root: Path) -> dict:
    traj = optimizer.solve((cfg.keyframe_base, cfg.keyframe_foot))
    with tempfile.TemporaryDirectory() as tmp:
        solve_dir, eval_dir = Path(tmp) / "solve", Path(tmp) / "evaluate"
        write_solution(solve_dir, traj, inputs, optimizer, cfg, root / "scene")
        metrics = evaluate_scenario(root / "scene", solve_dir, eval_dir, evaluate_cfg)
    return {
        "status": traj.status,
        "iterations": traj.iterations,
        "exact_hessian_iterations": traj.exact_iterations,
        "solve_time_s": traj.solve_time_s,
        "cost": traj.cost,
        "evaluation_success": metrics["success"],
        "avg_penetration_m": metrics["avg_penetration_m"],
        "dynamics_residual_max": metrics["dynamics_residual_max"],
    }


def _growth(rows: list[dict]) -> float | None:
    """Least-squares slope of log(median solve time) against log(nodes)."""
    if len(rows) < 2:
        return None
    x = np.log([r["nodes"] for r in rows])
    y = np.log([r["solve_time_median_s"] for r in rows])
    return float(np.polyfit(x, y, 1)[0])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", default="tiny")
    parser.add_argument("--scales", type=float, nargs="+", default=[1.0, 2.0, 4.0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument(
        "--configs", nargs="+", default=["ipopt_mumps:gauss_newton", "ipopt_mumps:exact"]
    )
    parser.add_argument("--spral-iterations", type=int, default=20)
    parser.add_argument("--out", default="benchmarks/results/to_solvers.json")
    args = parser.parse_args()
    params = load_params()
    cfg = params.solve
    root = Path("data") / args.scenario
    inputs = load_inputs(root / "scene", root / "contacts", root / "retarget")
    rows = []
    for config in args.configs:
        backend, hessian = config.split(":")
        if backend not in BACKENDS:
            parser.error(f"unknown backend {backend!r}; one of {sorted(BACKENDS)}")
        solver = dataclasses.replace(cfg.solver, print_level=0, backend=backend, hessian=hessian)
        for scale in args.scales:
            run_cfg = dataclasses.replace(cfg, solver=solver, schedule=_scaled(cfg.schedule, scale))
            optimizer = build_optimizer(inputs, run_cfg)
            runs = [
                _run(optimizer, inputs, run_cfg, params.evaluate, root) for _ in range(args.repeats)
            ]
            times = [r["solve_time_s"] for r in runs]
            row = {
                "config": config,
                "backend": backend,
                "hessian": hessian,
                "scale": scale,
                "nodes": optimizer.schedule.nodes,
                "n_variables": optimizer.nlp.n_x,
                "n_constraints": optimizer.nlp.n_g,
                "build_time_s": optimizer.build_time_s,
                "runs": runs,
                "solve_time_median_s": statistics.median(times),
                "iterations_median": statistics.median(r["iterations"] for r in runs),
                "seconds_per_iteration": statistics.median(
                    r["solve_time_s"] / max(r["iterations"], 1) for r in runs
                ),
                "cost_median": statistics.median(r["cost"] for r in runs),
                "evaluation_success": all(r["evaluation_success"] for r in runs),
            }
            print(
                f"[bench] {config} x{scale:g}: {row['nodes']} nodes, "
                f"{row['iterations_median']:g} iterations, {row['solve_time_median_s']:.1f} s, "
                f"checks {'pass' if row['evaluation_success'] else 'FAIL'}",
                flush=True,
            )
            rows.append(row)
    growth = {c: _growth([r for r in rows if r["config"] == c]) for c in args.configs}
    out = {
        "scenario": args.scenario,
        "machine": {"cpus": os.cpu_count(), "platform": platform.platform()},
        "repeats": args.repeats,
        "growth_exponent": growth,
        "results": rows,
    }
    if args.spral_iterations:
        solver = dataclasses.replace(
            cfg.solver, print_level=0, backend="ipopt_spral", max_iterations=args.spral_iterations
        )
        optimizer = build_optimizer(inputs, dataclasses.replace(cfg, solver=solver))
        traj = optimizer.solve((cfg.keyframe_base, cfg.keyframe_foot))
        out["spral_probe"] = {
            "nodes": optimizer.schedule.nodes,
            "hessian": solver.hessian,
            "iterations": traj.iterations,
            "status": traj.status,
            "seconds_per_iteration": traj.solve_time_s / max(traj.iterations, 1),
        }
        print(f"[bench] spral probe: {out['spral_probe']}", flush=True)
    write_json_atomic(args.out, out)


if __name__ == "__main__":
    main()
