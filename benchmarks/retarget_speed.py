"""Speed of the placo retargeter: keyframes per second, on the artifacts of `dvc repro`.

Usage: python benchmarks/retarget_speed.py [--repeats 5] [--scenarios tiny s1_basket s2_trolley]
    [--out benchmarks/results/retarget_speed.json]

Loads each scenario's contacts and pose artifacts once, then solves every keyframe
``--repeats`` times with one Retargeter (the model is loaded once, as in the stage). Reports
the median time per keyframe, split into keyframes whose contacts are all met and those
with an unreachable hand (which run to the iteration cap), and the model load time.
"""

from __future__ import annotations

import argparse
import time
from typing import Any

import numpy as np
from common import write_benchmark

from locoman.artifacts import read_npz
from locoman.config import load_params
from locoman.contact.io import CONTACTS
from locoman.contact.io import subtask_file as contact_file
from locoman.perception.io import POSE
from locoman.perception.io import SUBTASKS_DIR as PERCEPTION_SUBTASKS
from locoman.retarget.ik import Retargeter
from locoman.retarget.pipeline import feet_left_standing
from locoman.retarget.problem import body_scale, build_problem, g1_stance_half_width
from locoman.stage import DATA_DIR


def problems(scenario: str) -> list[Any]:
    """The IK problems of a scenario's subtasks, from its contacts and pose artifacts."""
    root = DATA_DIR / scenario
    half_width, scale = g1_stance_half_width(), body_scale()
    standing: dict[str, np.ndarray] = {}
    out = []
    i = 0
    while contact_file(root / "contacts", i).is_file():
        contacts = read_npz(contact_file(root / "contacts", i), CONTACTS)
        pose = read_npz(root / "masks" / PERCEPTION_SUBTASKS / f"pose_{i}.npz", POSE)
        out.append(build_problem(contacts, pose, half_width, scale, standing))
        standing = feet_left_standing(contacts, standing)
        i += 1
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--scenarios", nargs="+", default=["tiny", "s1_basket", "s2_trolley"])
    parser.add_argument("--out", default="benchmarks/results/retarget_speed.json")
    args = parser.parse_args()
    cfg = load_params().retarget
    tic = time.perf_counter()
    retargeter = Retargeter(cfg)
    load_s = time.perf_counter() - tic
    met, missed, per_scenario = [], [], {}
    for scenario in args.scenarios:
        times = []
        for problem in problems(scenario):
            for _ in range(args.repeats):
                t0 = time.perf_counter()
                result = retargeter.solve(problem)
                dt = time.perf_counter() - t0
                times.append(dt)
                (missed if result.unreachable else met).append(dt)
        per_scenario[scenario] = {
            "keyframes_per_second": 1.0 / float(np.median(times)),
            "seconds_per_keyframe_median": float(np.median(times)),
        }
        print(scenario, per_scenario[scenario], flush=True)
    result = {
        "repeats": args.repeats,
        "model_load_s": load_s,
        "keyframes_per_second_all_met": 1.0 / float(np.median(met)) if met else None,
        "keyframes_per_second_unreachable": 1.0 / float(np.median(missed)) if missed else None,
        "keyframes_met": len(met) // args.repeats,
        "keyframes_unreachable": len(missed) // args.repeats,
        "iterations_cap": cfg.iterations,
        "by_scenario": per_scenario,
        "reference": "a mink-based G1 retargeter: 60-70 frames per second (issue 5)",
    }
    write_benchmark(args.out, result)
    print(result)


if __name__ == "__main__":
    main()
