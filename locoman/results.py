"""One compact table of the headline numbers per scenario, from the stages' metrics.

Usage: ``python -m locoman.results [--data data]`` (``make results``). A stage that has not
run shows ``-``. The full figures stay in each stage's ``metrics.json`` (and per subtask in
``details.json``).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

HUMANOID_COLUMNS = (
    ("contact err", "contacts", "contact_error_median_m", "{:.1f} cm", 100.0),
    ("hand miss", "retarget", "hand_contact_residual_max_m", "{:.1f} mm", 1000.0),
    ("unreachable", "retarget", "unreachable_contacts", "{:d}", None),
    ("TO", "solve", "status", "{}", None),
    ("iters", "solve", "iterations", "{:d}", None),
    ("penetr. avg", "evaluate", "avg_penetration_m", "{:.2f} mm", 1000.0),
    ("penetr. max", "evaluate", "max_penetration_m", "{:.1f} mm", 1000.0),
    ("dyn. resid.", "evaluate", "dynamics_residual_max", "{:.0e}", None),
    ("goal err", "evaluate", "object_goal_error_m", "{:.1f} cm", 100.0),
    ("success", "evaluate", "success", "{}", None),
)


def _read(path: Path) -> dict[str, Any] | None:
    try:
        return json.loads(path.read_text())
    except (OSError, json.JSONDecodeError):
        return None


def _cell(metrics: dict[str, Any] | None, key: str, fmt: str, scale: float | None) -> str:
    if metrics is None or metrics.get(key) is None:
        return "-"
    value = metrics[key]
    return fmt.format(value * scale if scale is not None else value)


def humanoid_rows(data: Path) -> list[list[str]]:
    """A row per humanoid scenario (a folder of ``data`` with a ``contacts`` stage)."""
    rows = []
    for folder in sorted(p for p in data.iterdir() if (p / "contacts").is_dir()):
        metrics = {
            stage: _read(folder / stage / "metrics.json") for _, stage, *_ in HUMANOID_COLUMNS
        }
        cells = [
            _cell(metrics[stage], key, fmt, scale) for _, stage, key, fmt, scale in HUMANOID_COLUMNS
        ]
        failed = (metrics["evaluate"] or {}).get("failed_checks")
        rows.append([folder.name, *cells, ", ".join(failed) if failed else ""])
    return rows


def mobile_rows(data: Path) -> list[list[str]]:
    """A row per replay case of each scenario with an ``hqp_replay`` stage."""
    rows = []
    for folder in sorted(p for p in data.iterdir() if (p / "hqp_replay").is_dir()):
        metrics = _read(folder / "hqp_replay" / "metrics.json") or {}
        for case, m in sorted(metrics.items()):
            pos = ", ".join(f"{100 * v:.2f}" for v in m["rmse_ee_pos_m"])
            vel = ", ".join(f"{100 * v:.2f}" for v in m["rmse_ee_vel_mps"])
            rows.append(
                [
                    f"{folder.name}/{case}",
                    pos,
                    vel,
                    f"{1000 * m['bottle_final_error_m']:.1f}",
                    str(m["success"]),
                ]
            )
    return rows


def table(header: list[str], rows: list[list[str]]) -> str:
    """Fixed-width text table."""
    widths = [max(len(r[i]) for r in [header, *rows]) for i in range(len(header))]
    lines = [
        "  ".join(c.ljust(w) for c, w in zip(row, widths, strict=True)).rstrip()
        for row in [header, *rows]
    ]
    lines.insert(1, "  ".join("-" * w for w in widths))
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=Path("data"))
    args = parser.parse_args(argv)
    if not args.data.is_dir():
        print(f"locoman: no {args.data}/ folder; run `make run` first", file=sys.stderr)
        return 2
    header = ["scenario", *(c[0] for c in HUMANOID_COLUMNS), "failed checks"]
    print("Paper A (humanoid): per scenario\n")
    print(table(header, humanoid_rows(args.data)))
    print("\nPaper B (mobile manipulator): per replay\n")
    header = [
        "replay",
        "EE pos RMSE x,y,z [cm]",
        "EE vel RMSE [cm/s]",
        "bottle err [mm]",
        "success",
    ]
    print(table(header, mobile_rows(args.data)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
