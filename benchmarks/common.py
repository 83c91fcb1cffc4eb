"""What the TO's benchmarks share: a wall and CPU clock, their command line, and their
results file with the commit and the machine they were measured at. Imported by the scripts
beside it (run as ``python benchmarks/<script>.py``, which puts this folder on the path)."""

from __future__ import annotations

import argparse
import datetime
import os
import platform
import time
from collections.abc import Callable
from pathlib import Path

from locoman.artifacts import write_json_atomic
from locoman.grid.provenance import head_commit


class Clock:
    """Wall and CPU seconds since the last reading."""

    def __init__(self) -> None:
        self._wall, self._cpu = time.perf_counter(), time.process_time()

    def lap(self) -> dict[str, float]:
        wall, cpu = time.perf_counter(), time.process_time()
        lap = {"wall_s": wall - self._wall, "cpu_s": cpu - self._cpu}
        self._wall, self._cpu = wall, cpu
        return lap


def stamped(record: dict) -> dict:
    """``record`` with the commit it ran at (``+``: with uncommitted changes to the library
    or the parameters), the date and the machine, which ``make results`` reports."""
    return {
        **record,
        "commit": head_commit(Path(".")),
        "date": datetime.date.today().isoformat(),
        "machine": f"{platform.machine()}, {os.cpu_count()} cores",
    }


def write_benchmark(out: str | Path, record: dict) -> None:
    """A benchmark's JSON, :func:`stamped`, written atomically."""
    write_json_atomic(out, stamped(record))


def write_results(out: Path, repeats: int, scenarios: dict) -> None:
    """``scenarios``' results to ``out`` (JSON, atomically, :func:`stamped`)."""
    write_benchmark(out, {"repeats": repeats, "scenarios": scenarios})


def run(
    doc: str,
    out: str,
    measure: Callable[[str, int], dict],
    summary: Callable[[dict], str],
) -> None:
    """A benchmark's command line (``--scenarios``, ``--repeats``, ``--out``, default
    ``out``): ``measure(scenario, repeats)`` for each scenario, its ``summary`` printed, the
    results written (:func:`write_results`)."""
    parser = argparse.ArgumentParser(description=doc.split("\n")[0])
    parser.add_argument("--scenarios", nargs="+", default=["tiny", "s1_basket", "s2_trolley"])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--out", type=Path, default=Path(out))
    args = parser.parse_args()
    name = Path(out).stem
    results = {}
    for scenario in args.scenarios:
        results[scenario] = measure(scenario, args.repeats)
        line = summary(results[scenario])
        print(f"[{name}] {scenario}: {line} (medians of {args.repeats})", flush=True)
    write_results(args.out, args.repeats, results)
