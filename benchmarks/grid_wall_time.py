"""Wall time of a figure's grid per (box mass, initial yaw) panel, from its cells' records.

Usage: python benchmarks/grid_wall_time.py <scenario> <figure> <out.json> [--data DIR]
       [--note TEXT]

A panel's wall time [s] is how long at least one of its cells was running: the union of the
cells' intervals [end - wall_time_s, end], with ``end`` the time ``cell.json`` was written.
A grid that was stopped and relaunched so counts the time it computed and
not the gaps between launches. Panels with fewer records than runs are marked
``"whole": false``. Cells that errored count too: they took the time. A cell last evaluated
again on its kept solve counts that evaluation (``evaluate_wall_time_s``): its solve ran in
an earlier grid.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import defaultdict
from pathlib import Path

from locoman.artifacts import write_json_atomic
from locoman.grid.cell import RECORD_FILE, read_record
from locoman.grid.runs import FIGURE_RUNS


def union_length(intervals: list[tuple[float, float]]) -> float:
    """Total length [s] of the union of ``(start, end)`` intervals."""
    total, reach = 0.0, float("-inf")
    for start, end in sorted(intervals):
        if end > reach:
            total += end - max(start, reach)
            reach = end
    return total


def panels(folder: Path, figure: str) -> list[dict]:
    """One entry per (box mass, initial yaw) with records under ``folder``, sorted."""
    intervals: dict[tuple[float, float], list[tuple[float, float]]] = defaultdict(list)
    for cell in sorted(folder.iterdir()):
        record = None if cell.name.startswith(".") else read_record(cell)
        if record is None:
            continue  # a cell running (its staging folder) or killed: no record yet
        end = (cell / RECORD_FILE).stat().st_mtime
        panel = (float(record["box_mass"]), float(record["initial_yaw"]))
        seconds = record.get("evaluate_wall_time_s", record["wall_time_s"])
        intervals[panel].append((end - float(seconds), end))
    runs = len(FIGURE_RUNS[figure])
    return [
        {
            "box_mass": mass,
            "initial_yaw": yaw,
            "runs": len(spans),
            "whole": len(spans) == runs,
            "wall_time_s": round(union_length(spans)),
        }
        for (mass, yaw), spans in sorted(intervals.items())
    ]


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenario")
    parser.add_argument("figure", choices=sorted(FIGURE_RUNS))
    parser.add_argument("out", type=Path)
    parser.add_argument("--data", type=Path, default=Path("data"))
    parser.add_argument("--note", default="")
    args = parser.parse_args(argv)
    folder = args.data / args.scenario / "grid" / args.figure
    if not folder.is_dir():
        print(
            f"{folder} does not exist: run `python -m locoman.grid {args.scenario} "
            f"{args.figure}` first",
            file=sys.stderr,
        )
        return 2
    rows = panels(folder, args.figure)
    result = {
        "note": args.note,
        "cells": rows,
        "runs": sum(r["runs"] for r in rows),
        "wall_time_s": sum(r["wall_time_s"] for r in rows),
    }
    write_json_atomic(args.out, result)
    print(json.dumps({k: v for k, v in result.items() if k != "cells"}))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
