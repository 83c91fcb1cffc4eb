"""The TO's build without its solves: what ``build_time_s`` counts, piece by piece.

Usage: python benchmarks/to_build.py [--scenarios tiny s1_basket s2_trolley] [--repeats 3]
       [--out benchmarks/results/to_build.json]

Per scenario, ``--repeats`` runs of a solve's building at the defaults of ``params.yaml``:
the set-up (the terms loaded from ``.cache/casadi``: run a solve first), paper A's collision
pairs, the first transcription and its Gauss-Newton and exact assemblies; then one round per
round of the committed solve (``data/<scenario>/solve/metrics.json``), each a transcription
and an exact assembly with as many more pairs as that round added. The added pairs are
copies of the problem's own, every other one moved between its node and the next (fraction
0.5), as found pairs between nodes are: the real rounds add the pairs their checks find, so
this measures the build without the solves that find them. Wall and CPU seconds, medians
over the runs; CPU time is the steadier on a busy machine.
"""

from __future__ import annotations

from locoman.kernels import pin_kernels

pin_kernels()  # first, as every stage: NumPy and OpenBLAS choose their kernels when they load

import dataclasses
import json
import statistics
from pathlib import Path

import numpy as np
from common import Clock, run

from locoman.config import load_params
from locoman.config.to import scenario_solve
from locoman.to.pipeline import build_optimizer
from locoman.to.problem.loading import load_inputs

DATA = Path("data")


def round_sizes(scenario: str) -> list[int]:
    """The pairs each round of the committed solve added."""
    metrics = json.loads((DATA / scenario / "solve" / "metrics.json").read_text())
    return [r["pairs_added"] for r in metrics["collision_rounds"] if r["pairs_added"]]


def _copies(pairs: list, count: int, nodes: int, rng: np.random.Generator) -> list:
    """``count`` new pair objects like ``pairs``' own, every other one between nodes."""
    chosen = rng.choice(len(pairs), size=count, replace=False)
    out = []
    for i, j in enumerate(chosen):
        pair = pairs[j]
        between = i % 2 == 1 and pair.node < nodes - 1
        out.append(dataclasses.replace(pair, fraction=0.5 if between else pair.fraction))
    return out


def build_once(scenario: str, sizes: list[int], seed: int = 0) -> dict:
    """One run: each piece's wall and CPU seconds, and the optimizer's ``build_time_s``."""
    cfg = scenario_solve(load_params().solve, scenario)
    root = DATA / scenario
    inputs = load_inputs(root / "scene", root / "contacts", root / "retarget", cfg.contacts)
    clock = Clock()
    optimizer = build_optimizer(inputs, cfg)
    pieces = {"first problem, Gauss-Newton": clock.lap()}
    optimizer._nlp(optimizer.transcription, "exact")  # as the switch to the exact Hessian
    pieces["first problem, exact"] = clock.lap()
    rng = np.random.default_rng(seed)
    pairs = list(optimizer.transcription.pairs)
    for r, size in enumerate(sizes, 1):
        pairs = pairs + _copies(pairs, size, optimizer.schedule.nodes, rng)
        transcription = optimizer.transcribe(pairs=pairs)
        pieces[f"round {r}, transcription"] = clock.lap()
        optimizer._nlp(transcription, "exact")
        pieces[f"round {r}, assembly"] = clock.lap()
    total = {key: sum(p[key] for p in pieces.values()) for key in ("wall_s", "cpu_s")}
    return {"pieces": pieces, "total": total, "build_time_s": optimizer.build_time_s}


def _median(runs: list[dict]) -> dict:
    first = runs[0]
    return {
        "build_time_s": statistics.median(r["build_time_s"] for r in runs),
        "total": {k: statistics.median(r["total"][k] for r in runs) for k in first["total"]},
        "pieces": {
            name: {k: statistics.median(r["pieces"][name][k] for r in runs) for k in piece}
            for name, piece in first["pieces"].items()
        },
    }


def measure(scenario: str, repeats: int) -> dict:
    sizes = round_sizes(scenario)
    runs = [build_once(scenario, sizes) for _ in range(repeats)]
    return {"round_pairs": sizes, **_median(runs), "runs": runs}


def summary(result: dict) -> str:
    return f"build_time_s {result['build_time_s']:.2f} (CPU {result['total']['cpu_s']:.2f} s)"


if __name__ == "__main__":
    run(__doc__, "benchmarks/results/to_build.json", measure, summary)
