"""Benchmark of how robustly the G1 carries out each plan in MuJoCo: the execution from
perturbed starts.

Usage: python benchmarks/execute_robustness.py [--scenarios tiny ...] [--repeats 5]
       [--out benchmarks/results/execute_robustness.json]
Needs each scenario's scene and solve outputs (`dvc repro solve@tiny`).

Per scenario, ``--repeats`` executions at the parameters' ``execute`` settings: the first
from the plan's first node (the stage's run), the others with every joint angle of the
starting pose moved by a normal draw of standard deviation :data:`PERTURBATION_RAD` (seeds 1,
2, ...). One deterministic run says little: a balance that stands by luck falls at the next
millimetre. Reported: the fraction of the motion each run stayed up (1: throughout), its
median, the runs that stayed up, each run's lost grasps and its goal errors.
"""

from __future__ import annotations

import numpy as np
from common import run
from threadpoolctl import threadpool_limits

from locoman.artifacts import read_npz
from locoman.config import load_params
from locoman.execute import simulate
from locoman.execute.metrics import execution_metrics
from locoman.execute.pipeline import execution_setup
from locoman.stage import DATA_DIR
from locoman.to.io import TRAJECTORY, TRAJECTORY_FILE

PERTURBATION_RAD = 0.01


def perturbed_start(seed: int):
    """:func:`locoman.execute.simulate.initial_qpos` with the joints moved (seed 0: not)."""
    plain = simulate.initial_qpos

    def start(model, states, ref, objects):
        qpos = plain(model, states, ref, objects)
        if seed:
            rng = np.random.default_rng(seed)
            qpos[states.joint_qpos] += rng.normal(0.0, PERTURBATION_RAD, len(states.joint_qpos))
        return qpos

    return start


def _run(model, ref, traj, names, cfg, seed: int) -> dict:
    plain = simulate.initial_qpos
    simulate.initial_qpos = perturbed_start(seed)
    try:
        executed = simulate.execute(model, ref, names, cfg, float(traj["floor_friction"]))
    finally:
        simulate.initial_qpos = plain
    metrics = execution_metrics(model, executed, ref, traj, cfg)
    return {
        "seed": seed,
        "up_fraction": min(1.0, metrics["time_up_s"] / metrics["duration_s"]),
        "failed_checks": metrics["failed_checks"],
        "grasps_lost": metrics["grasps_lost"],
        "goal_error_m": {
            k.removesuffix("_goal_error_m"): v
            for k, v in metrics.items()
            if k.endswith("_goal_error_m")
        },
    }


def measure(scenario: str, repeats: int) -> dict:
    cfg = load_params().execute
    root = DATA_DIR / scenario
    traj = read_npz(root / "solve" / TRAJECTORY_FILE, TRAJECTORY)
    names = [str(name) for name in traj["object_names"]]
    ref, model = execution_setup(root / "scene", traj, cfg)
    # One BLAS thread, as the stages run (locoman.stage): seed 0 is the stage's execution.
    with threadpool_limits(limits=1):
        runs = [_run(model, ref, traj, names, cfg, seed) for seed in range(repeats)]
    up = [r["up_fraction"] for r in runs]
    return {
        "perturbation_rad": PERTURBATION_RAD,
        "up_fraction_median": float(np.median(up)),
        "up_throughout": sum(u >= 1.0 - 1e-9 for u in up),
        "successes": sum(not r["failed_checks"] for r in runs),
        "runs": runs,
    }


def summary(result: dict) -> str:
    runs = len(result["runs"])
    return (
        f"up {result['up_fraction_median']:.2f} of the motion (median), throughout in "
        f"{result['up_throughout']} of {runs}, succeeded in {result['successes']}"
    )


if __name__ == "__main__":
    run(__doc__, "benchmarks/results/execute_robustness.json", measure, summary)
