"""Build time of the TO when its libraries are cached: through the cache's index (what a grid
cell or a re-solve pays) and without it (each group differentiated and its C generated to
find its library, as every build did before the index).

Usage: python benchmarks/to_build.py [--scenarios tiny s1_basket] [--repeats 3]
       [--out benchmarks/results/to_build.json]

Reads ``data/<scenario>/`` and the libraries in ``solve.cache_dir`` (build them first:
``dvc repro solve@<scenario>``). Each build runs in a process of its own on a copy of the
cache (the libraries linked, the index copied or left out), and builds both NLPs: the
Gauss-Newton one and the exact-Hessian one that S1 and S2 switch to. Medians of
``--repeats``.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from locoman.artifacts import write_json_atomic
from locoman.config import load_params
from locoman.to.compile import CACHE_ENV, cache_dir
from locoman.to.pipeline import build_optimizer, load_inputs


def child(scenario: str) -> None:
    """One build (the cache from $LOCOMAN_CACHE_DIR); prints its times as JSON."""
    cfg = load_params().solve
    root = Path("data") / scenario
    inputs = load_inputs(root / "scene", root / "contacts", root / "retarget", cfg.contacts)
    tic = time.perf_counter()
    optimizer = build_optimizer(inputs, cfg)
    gauss_newton = time.perf_counter() - tic
    tic = time.perf_counter()
    if optimizer.switch_at is not None:
        optimizer.exact_nlp  # noqa: B018 (built on first use)
    print(json.dumps({"gauss_newton_s": gauss_newton, "exact_s": time.perf_counter() - tic}))


def build_in(scenario: str, cache: Path) -> dict[str, float]:
    """One build in a process of its own with ``cache`` as the TO's cache."""
    env = os.environ | {CACHE_ENV: str(cache)}
    command = [sys.executable, __file__, "--child", scenario]
    out = subprocess.run(command, env=env, check=True, capture_output=True, text=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def build_on_copy(scenario: str, source: Path, with_index: bool) -> dict[str, float]:
    """One build on a copy of ``source``: its libraries linked, its index copied or not."""
    with tempfile.TemporaryDirectory() as tmp:
        for path in source.glob("to_*"):
            (Path(tmp) / path.name).symlink_to(path.resolve())
        if with_index:
            for path in source.glob("index_*.json"):
                shutil.copy(path, tmp)
        return build_in(scenario, Path(tmp))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenarios", nargs="+", default=["tiny", "s1_basket"])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--out", default="benchmarks/results/to_build.json")
    parser.add_argument("--child", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        child(args.child)
        return
    source = cache_dir(load_params().solve.cache_dir)
    rows = []
    for scenario in args.scenarios:
        build_in(scenario, source)  # indexes (or compiles) what the cache lacks
        for with_index in (True, False):
            runs = [build_on_copy(scenario, source, with_index) for _ in range(args.repeats)]
            row = {"scenario": scenario, "index": with_index, "repeats": args.repeats}
            for key in ("gauss_newton_s", "exact_s"):
                row[f"{key.removesuffix('_s')}_median_s"] = statistics.median(r[key] for r in runs)
            rows.append(row)
            print(json.dumps(row), flush=True)
    write_json_atomic(Path(args.out), {"cpu_count": os.cpu_count(), "builds": rows})


if __name__ == "__main__":
    main()
