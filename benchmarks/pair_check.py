"""One check of a solution by the collision rounds (:mod:`locoman.to.rounds.search`), timed.

Usage: python benchmarks/pair_check.py [--scenarios tiny s1_basket s2_trolley] [--repeats 3]
       [--out benchmarks/results/pair_check.json]

Per scenario, the committed solution (``data/<scenario>/solve/``: run the solves first)
checked against the problem's starting pairs, as a first round checks the first solve:
MuJoCo's close pairs along it (:func:`locoman.sim.audit.close_pairs`), then the pairs that
answer them (:func:`locoman.to.rounds.found_pairs.round_pairs`, found and promoted) and the close
pairs left unmodelled (:func:`locoman.to.rounds.found_pairs.unmodelled`), the starting pairs'
identities made in it as in a first round. Wall and CPU seconds, medians over ``--repeats``
runs.
"""

from __future__ import annotations

from locoman.kernels import pin_kernels

pin_kernels()  # first, as every stage: NumPy and OpenBLAS choose their kernels when they load

import dataclasses
import statistics
from pathlib import Path

import numpy as np
from common import Clock, run

from locoman.artifacts import read_npz
from locoman.config import load_params
from locoman.config.to import scenario_solve
from locoman.scene.io import load_scene_model
from locoman.sim.audit import close_pairs
from locoman.to.io import TRAJECTORY, TRAJECTORY_FILE
from locoman.to.pipeline import build_optimizer
from locoman.to.problem.loading import load_inputs
from locoman.to.rounds.found_pairs import Check, SolutionScene, round_pairs, unmodelled
from locoman.to.rounds.search import solution_scene
from locoman.to.solve.trajectory import Trajectory

DATA = Path("data")


def committed_solution(scenario: str) -> Trajectory:
    """The committed solve's trajectory; the fields its file does not hold (counts,
    timings) empty."""
    arrays = read_npz(DATA / scenario / "solve" / TRAJECTORY_FILE, TRAJECTORY)
    empty = {"str": "", "bool": False, "int": 0, "float": 0.0}
    fields = {f.name: empty.get(f.type, np.zeros(0)) for f in dataclasses.fields(Trajectory)}
    return Trajectory(**fields | {k: v for k, v in arrays.items() if k in fields})


def check_once(optimizer, model, scene: SolutionScene, cfg) -> dict:
    """One check: its pieces' wall and CPU seconds and what it found."""
    # Fresh pair objects, as a first round meets them: their identities not made yet.
    pairs = [dataclasses.replace(p) for p in optimizer.transcription.pairs]
    clock = Clock()
    close = close_pairs(model, scene.schedule, cfg.audit_margin_m, cfg.audit_substeps)
    audit = clock.lap()
    check = Check(close, scene)
    new = round_pairs(check, pairs, cfg)
    missing = unmodelled(check, pairs)
    mapping = clock.lap()
    counts = {"close_pairs": len(close), "pairs_added": len(new), "unmodelled": len(missing)}
    return {"audit": audit, "mapping": mapping, **counts}


def measure(scenario: str, repeats: int) -> dict:
    cfg = scenario_solve(load_params().solve, scenario)
    root = DATA / scenario
    inputs = load_inputs(root / "scene", root / "contacts", root / "retarget", cfg.contacts)
    optimizer = build_optimizer(inputs, cfg)
    traj = committed_solution(scenario)
    scene = solution_scene(optimizer, traj, cfg.collision)
    model = load_scene_model(root / "scene")
    runs = [check_once(optimizer, model, scene, cfg.collision) for _ in range(repeats)]
    medians = {
        piece: {k: statistics.median(r[piece][k] for r in runs) for k in ("wall_s", "cpu_s")}
        for piece in ("audit", "mapping")
    }
    counts = {k: runs[0][k] for k in ("close_pairs", "pairs_added", "unmodelled")}
    return {**counts, **medians, "runs": runs}


def summary(result: dict) -> str:
    return (
        f"{result['close_pairs']} close pairs -> {result['pairs_added']} pairs; audit "
        f"{result['audit']['wall_s']:.2f} s, mapping {result['mapping']['wall_s']:.2f} s"
    )


if __name__ == "__main__":
    run(__doc__, "benchmarks/results/pair_check.json", measure, summary)
