"""A grid's records kept beside its committed summary, and put back to continue the grid.

Usage::

    python -m locoman.grid.archive export <scenario> <figure> <dir>
    python -m locoman.grid.archive restore <scenario> <dir>

A cell's record (``cell.json``, :mod:`locoman.grid.cell`) holds its numbers and the keys of
everything it read; its folder under ``data/<scenario>/grid/`` is not tracked (trajectories,
logs). ``export`` copies the records of every cell of ``figure`` that has one into
``<dir>/records/<figure>/<cell>.json``, small enough to commit next to the summary; only
the records whose key matches the checkout's parameters, upstream files and code (a grid
restarted after a change holds its older cells' records until they are solved again;
``--stale`` exports those too).
``restore`` copies them back where no record is: a grid launched afterwards skips each
restored cell whose key still matches (the same parameters, upstream files and code) and
solves the others, so a grid that takes longer than one sitting, or runs partly on a
cluster, is finished in several. A restored cell has no trajectory: re-scoring it
(``--rescore``) or drawing its Fig. 5 curve needs the solve again.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Collection
from pathlib import Path
from typing import Any

from locoman.artifacts import write_json_atomic
from locoman.config import RootCfg, load_params
from locoman.errors import ArtifactError
from locoman.grid.cell import (
    RECORD_FILE,
    CellCfg,
    cell_dir,
    cell_inputs,
    cell_key,
    read_record,
)

RECORDS = "records"


def _cell(record: dict[str, Any]) -> CellCfg:
    """The cell a record belongs to, from its own fields (not its file's name)."""
    try:
        return CellCfg(
            record["scenario"],
            record["figure"],
            record["run"],
            float(record["box_mass"]),
            float(record["initial_yaw"]),
        )
    except (KeyError, TypeError, ValueError) as exc:
        raise ArtifactError(f"not a cell record (no {exc}): {sorted(record)[:8]}") from exc


def current_key(cfg: RootCfg, cell: CellCfg, data_dir: Path) -> str:
    """The key a record of ``cell`` has when it is up to date with ``cfg``, the upstream
    files under ``data_dir`` and the code (what :func:`locoman.grid.cell.run_cell` skips).

    Raises:
        ArtifactError: The upstream artifacts are missing.
    """
    return cell_key(cell_inputs(cfg, cell, data_dir)[3], cfg.evaluate)


def export_records(
    data_dir: Path,
    scenario: str,
    figure: str,
    dest: Path,
    only: Collection[str] | None = None,
    current: RootCfg | None = None,
) -> list[Path]:
    """Copy each record of ``figure``'s cells under ``data_dir`` (``only``: of the cells of
    these names, :attr:`CellCfg.name`; ``current``: whose key is up to date with these
    parameters, :func:`current_key`) to ``dest/records/<figure>/<cell>.json``; return the
    files written, sorted.

    Raises:
        ArtifactError: The figure has no cell with a record (an up-to-date one).
    """
    grid = Path(data_dir) / scenario / "grid" / figure
    written = []
    for folder in sorted(grid.glob("*/")) if grid.is_dir() else []:
        record = read_record(folder)
        if record is None:
            continue
        cell = _cell(record)
        if only is not None and cell.name not in only:
            continue
        if current is not None and record.get("key") != current_key(current, cell, data_dir):
            continue
        out = Path(dest) / RECORDS / figure / f"{cell.name}.json"
        write_json_atomic(out, record)
        written.append(out)
    if not written:
        up_to_date = " up to date" if current is not None else ""
        raise ArtifactError(f"{grid} holds no{up_to_date} cell record: run the grid first")
    return sorted(written)


def restore_records(data_dir: Path, scenario: str, src: Path) -> tuple[list[str], list[str]]:
    """Copy the records in ``src/records/`` of ``scenario``'s cells into their folders under
    ``data_dir`` where a cell has no record; return (restored, kept) cell paths, a kept one
    holding a record already (a newer run's, never overwritten).

    Raises:
        ArtifactError: ``src`` has no records, or one belongs to another scenario or is not
            a record.
    """
    files = sorted((Path(src) / RECORDS).glob("*/*.json"))
    if not files:
        raise ArtifactError(f"{Path(src) / RECORDS} holds no <figure>/<cell>.json records")
    restored, kept = [], []
    for path in files:
        try:
            record = json.loads(path.read_text())
        except ValueError as exc:
            raise ArtifactError(f"{path} is not JSON: {exc}") from exc
        cell = _cell(record)
        if cell.scenario != scenario:
            raise ArtifactError(f"{path} is a record of {cell.scenario!r}, not {scenario!r}")
        folder = cell_dir(data_dir, cell)
        name = f"{cell.figure}/{cell.name}"
        if read_record(folder) is not None:
            kept.append(name)
            continue
        write_json_atomic(folder / RECORD_FILE, record)
        restored.append(name)
    return restored, kept


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    export = sub.add_parser("export", help="the figure's records into <dir>/records/")
    export.add_argument("scenario")
    export.add_argument("figure")
    export.add_argument("dir", type=Path)
    export.add_argument("--stale", action="store_true", help="also records not up to date")
    restore = sub.add_parser("restore", help="<dir>/records/ into data/ where none is")
    restore.add_argument("scenario")
    restore.add_argument("dir", type=Path)
    parser.add_argument("--data-dir", type=Path, default=Path("data"))
    args = parser.parse_args(argv)
    try:
        if args.command == "export":
            current = None if args.stale else load_params()
            files = export_records(
                args.data_dir, args.scenario, args.figure, args.dir, current=current
            )
            print(f"{len(files)} records in {args.dir / RECORDS / args.figure}")
        else:
            restored, kept = restore_records(args.data_dir, args.scenario, args.dir)
            print(f"{len(restored)} records restored, {len(kept)} cells kept their own")
    except ArtifactError as exc:
        print(f"locoman: ArtifactError: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
