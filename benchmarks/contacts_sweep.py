"""Seed sweep of contact transfer: the error distribution, and which bad contacts are flagged.

Usage: python benchmarks/contacts_sweep.py [--seeds 20] [--first-seed 0] [--jobs 2]
    [--scenarios tiny s1_basket s2_trolley] [--out benchmarks/results/contacts_sweep.json]

Each seed redraws the object variant, the camera, the light and the person's placement, then
runs generate -> masks -> clouds -> contacts into a temporary folder, ``--jobs`` seeds at a
time. Needs the scene stages (`dvc repro scene`). Per scenario the JSON has the contact
errors' median, p90 and max for both methods, the registrations flagged as doubtful
(:mod:`locoman.contact.confidence`), the contacts more than 10 cm off and how many of those
were flagged (a *silent miss* is one that was not). About 9 s per subtask on one core.
"""

from __future__ import annotations

from locoman.kernels import pin_kernels

pin_kernels()  # first, as every stage: NumPy, OpenBLAS and OpenCV choose their kernels

import argparse
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context
from pathlib import Path
from typing import Any

import numpy as np
from common import write_benchmark

from locoman.config import load_params
from locoman.contact.pipeline import contacts_scenario
from locoman.errors import LocomanError
from locoman.perception.clouds import clouds_scenario
from locoman.perception.generate import generate_scenario
from locoman.perception.masks import masks_scenario
from locoman.stage import DATA_DIR

BAD_M = 0.10  # [m] a contact this far off is a failure that must not pass silently


def run_seed(scenario: str, seed: int) -> dict[str, Any]:
    """Per-subtask rows of the contacts metrics for one scenario and seed."""
    cfg = load_params()
    p = cfg.perception
    scene = DATA_DIR / scenario / "scene"
    with tempfile.TemporaryDirectory() as tmp:
        gen, msk, cld, con = (Path(tmp) / s for s in ("generate", "masks", "clouds", "contacts"))
        generate_scenario(scenario, scene, gen, p.generate, seed)
        masks_scenario(scenario, gen, msk, p.masks, seed)
        clouds_scenario(scenario, gen, msk, cld, p.clouds, p.depth_error, seed)
        return contacts_scenario(scenario, scene, gen, msk, cld, con, cfg.contacts, seed)


def contact_rows(scenario: str, seed: int) -> list[dict[str, Any]] | dict[str, Any]:
    """One row per contact of one scenario and seed, or the failure's record."""
    try:
        metrics = run_seed(scenario, seed)
    except LocomanError as err:  # a failed seed is recorded and the sweep goes on
        return {"scenario": scenario, "seed": seed, "error": str(err)}
    rows = []
    for row in metrics["per_subtask"]:
        for k, effector in enumerate(row["effectors"]):
            rows.append(
                {
                    "scenario": scenario,
                    "seed": seed,
                    "subtask": row["index"],
                    "effector": effector,
                    "error_m": row["contact_errors_m"][k],
                    "naive_error_m": row["naive_contact_errors_m"][k],
                    "rotation_error_deg": row["rotation_error_deg"],
                    "overlap": row["overlap"],
                    "margin": row["margin"],
                    "rival": row["rival"],
                    "silhouette_iou": row["silhouette_iou"],
                    "contact_gap_m": row["contact_gaps_m"][effector],
                    "doubtful": row["doubtful"],
                }
            )
    print(scenario, seed, metrics["contact_error_median_m"], flush=True)
    return rows


def _quantiles(values: list[float]) -> dict[str, float | None]:
    if not values:
        return {"median": None, "p25": None, "p75": None, "p90": None, "max": None}
    v = np.asarray(values)
    return {
        "median": float(np.median(v)),
        "p25": float(np.percentile(v, 25)),
        "p75": float(np.percentile(v, 75)),
        "p90": float(np.percentile(v, 90)),
        "max": float(v.max()),
    }


def scenario_summary(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Errors of both methods, the flags, and the bad contacts flagged or missed."""
    bad = [r for r in rows if r["error_m"] > BAD_M]
    registrations = {(r["seed"], r["subtask"]): r["doubtful"] for r in rows}
    return {
        "contacts": len(rows),
        "registration_m": _quantiles([r["error_m"] for r in rows]),
        "naive_m": _quantiles([r["naive_error_m"] for r in rows]),
        "registrations": len(registrations),
        "flagged_registrations": sum(registrations.values()),
        "bad_contacts": len(bad),
        "bad_contacts_flagged": sum(r["doubtful"] for r in bad),
        "silent_misses": sum(not r["doubtful"] for r in bad),
        "flagged_contacts_not_bad": sum(r["doubtful"] and r["error_m"] <= BAD_M for r in rows),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--first-seed", type=int, default=0)
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--scenarios", nargs="+", default=["tiny", "s1_basket", "s2_trolley"])
    parser.add_argument("--out", default="benchmarks/results/contacts_sweep.json")
    args = parser.parse_args()
    seeds = range(args.first_seed, args.first_seed + args.seeds)
    jobs = [(s, seed) for s in args.scenarios for seed in seeds]
    tic = time.perf_counter()
    with ProcessPoolExecutor(args.jobs, mp_context=get_context("spawn")) as pool:
        results = list(pool.map(contact_rows, *zip(*jobs, strict=True)))
    rows = [r for res in results if isinstance(res, list) for r in res]
    failures = [res for res in results if isinstance(res, dict)]
    result = {
        "seeds": list(seeds),
        "contacts": len(rows),
        "registration_m": _quantiles([r["error_m"] for r in rows]),
        "naive_m": _quantiles([r["naive_error_m"] for r in rows]),
        "by_scenario": {
            s: scenario_summary([r for r in rows if r["scenario"] == s]) for s in args.scenarios
        },
        "failures": failures,
        "seconds": time.perf_counter() - tic,
        "rows": rows,
    }
    write_benchmark(args.out, result)
    print({k: v for k, v in result.items() if k != "rows"})


if __name__ == "__main__":
    main()
