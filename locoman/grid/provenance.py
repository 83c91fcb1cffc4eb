"""Where a committed grid comes from, and whether today's code would give it again.

A figure's canonical folder (``benchmarks/results/<scenario>/<figure>/``) holds its summary,
figure and records, and ``provenance.json``: the commit the grid ran at, the command, and
the grid's *fingerprint*: the SHA-256 of every source file its cells' solve and evaluation
run (followed from their imports, :mod:`locoman.grid.sources`, as a cell's key is) and the
parameters they read (the scenario, ``solve``, ``evaluate``, the grid's time limit).

:func:`compare` sets that fingerprint against today's: a grid whose fingerprint matches is
*at main's code*; otherwise it names each source file and each parameter that differs, so
a reader sees at once whether a change touched what the grid measured. A change verified
not to move any output (a refactor whose every ``dvc repro`` output stayed bit-identical)
is recorded by stamping the folder again with ``--verified "<how>"``: the fingerprint moves
to today's and the note says why, the commit stays the one that ran the cells.

Usage::

    python -m locoman.grid.provenance stamp <folder> <scenario> <figure> [--command C]
        [--verified NOTE]
    python -m locoman.grid.provenance status [<folder> ...]
"""

from __future__ import annotations

import argparse
import datetime
import hashlib
import json
import subprocess
import sys
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import yaml

from locoman.artifacts import write_json_atomic, write_text_atomic
from locoman.errors import ArtifactError
from locoman.grid.sources import (
    CELL_FILE,
    EVALUATE_MODULES,
    PACKAGE,
    SOLVE_MODULES,
    imported_sources,
)

PROVENANCE_FILE = "provenance.json"
# Settings of the ``solve`` section that change where or how loudly a solve runs, never its
# result: a grid's fingerprint and a cell's key leave them out.
NOT_IN_RESULTS = ("cache_dir", "solver.print_level", "solver.progress_every")
RESULTS_DIR = Path("benchmarks/results")


def _sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def code_fingerprint(
    entries: Iterable[str], package: Path = PACKAGE, files: Iterable[str] = ()
) -> dict[str, str]:
    """``{path under the repository: SHA-256}`` of the sources ``entries`` import and of
    ``files`` (paths under the package), in the package at ``package`` (another checkout's
    ``locoman/`` for a past commit); an entry or file that is not there is left out."""
    present = [e for e in entries if _is_module(e, package)]
    paths = {*imported_sources(present, package), *(package / f for f in files)}
    return {
        f"locoman/{p.relative_to(package).as_posix()}": _sha256(p.read_bytes())
        for p in sorted(paths)
        if p.is_file()
    }


def _is_module(name: str, package: Path) -> bool:
    base = package.joinpath(*name.split(".")[1:])
    return base.with_suffix(".py").is_file() or (base / "__init__.py").is_file()


def results_settings(solve: Mapping[str, Any]) -> dict[str, Any]:
    """The ``solve`` section (as a dict) without :data:`NOT_IN_RESULTS`."""
    out = {k: dict(v) if isinstance(v, Mapping) else v for k, v in solve.items()}
    for path in NOT_IN_RESULTS:
        *parents, leaf = path.split(".")
        node = out
        for key in parents:
            node = node.get(key, {})
        node.pop(leaf, None)
    return out


def params_fingerprint(params: Mapping[str, Any], scenario: str) -> dict[str, Any]:
    """The parameters a grid's cells read, from a composed ``params.yaml``: the scenario's
    section, ``solve``, ``evaluate`` and the figures' time limit (a cell's box mass and yaw
    are its own)."""
    scenarios = params.get("scenarios", {})
    if scenario not in scenarios:
        raise ArtifactError(f"params.yaml has no scenario {scenario!r}")
    return {
        "scenario": scenarios[scenario],
        "solve": results_settings(params.get("solve", {})),
        "evaluate": params.get("evaluate", {}),
        "figures.time_limit_s": params.get("figures", {}).get("time_limit_s"),
    }


def fingerprint(root: Path, scenario: str) -> dict[str, Any]:
    """The fingerprint of the checkout at ``root`` (its ``locoman/`` and ``params.yaml``)."""
    params = yaml.safe_load((root / "params.yaml").read_text())
    package = root / "locoman"
    solve = code_fingerprint(SOLVE_MODULES, package, [CELL_FILE])
    evaluate = {
        k: v for k, v in code_fingerprint(EVALUATE_MODULES, package).items() if k not in solve
    }
    return {
        "solve_code": solve,
        "evaluate_code": evaluate,
        "params": params_fingerprint(params, scenario),
    }


def _flat(value: Any, prefix: str) -> dict[str, Any]:
    if isinstance(value, Mapping):
        out: dict[str, Any] = {}
        for key, item in value.items():
            out |= _flat(item, f"{prefix}.{key}" if prefix else str(key))
        return out
    return {prefix: value}


def _code_changes(kind: str, then: Mapping[str, str], now: Mapping[str, str]) -> list[str]:
    changed = sorted(p for p in then.keys() & now.keys() if then[p] != now[p])
    added = sorted(now.keys() - then.keys())
    removed = sorted(then.keys() - now.keys())
    out = [f"{kind}: {p} changed" for p in changed]
    out += [f"{kind}: {p} added" for p in added]
    out += [f"{kind}: {p} removed" for p in removed]
    return out


def compare(then: Mapping[str, Any], now: Mapping[str, Any]) -> list[str]:
    """Every difference between two fingerprints, one line each (empty: the same): a
    source file changed, added or removed, a parameter with its two values."""
    out = _code_changes("solve code", then["solve_code"], now["solve_code"])
    out += _code_changes("evaluation code", then["evaluate_code"], now["evaluate_code"])
    old, new = _flat(then["params"], ""), _flat(now["params"], "")
    for key in sorted(old.keys() | new.keys()):
        if old.get(key, "<none>") != new.get(key, "<none>"):
            out.append(f"parameter {key}: {old.get(key, '<none>')} -> {new.get(key, '<none>')}")
    return out


def head_commit(root: Path) -> str:
    """The checkout's commit (short), with ``+`` where ``locoman/`` or ``params.yaml`` has
    uncommitted changes; ``unknown`` outside git."""

    def git(*args: str) -> subprocess.CompletedProcess:
        return subprocess.run(
            ["git", "-C", str(root), *args], capture_output=True, text=True, check=False
        )

    commit = git("rev-parse", "--short", "HEAD").stdout.strip() or "unknown"
    dirty = git("status", "--porcelain", "--", "locoman", "params.yaml").stdout.strip()
    return f"{commit}+" if dirty else commit


def read_provenance(folder: Path) -> dict[str, Any]:
    """A folder's ``provenance.json``.

    Raises:
        ArtifactError: It has none, or it is not one.
    """
    path = Path(folder) / PROVENANCE_FILE
    try:
        record = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise ArtifactError(
            f"{path} is missing or unreadable ({exc}): stamp the grid with "
            f"`python -m locoman.grid.provenance stamp {folder} <scenario> <figure>`"
        ) from exc
    for key in ("scenario", "figure", "commit", "fingerprint"):
        if key not in record:
            raise ArtifactError(f"{path} has no {key!r}")
    return record


def stamp(
    folder: Path,
    scenario: str,
    figure: str,
    command: str,
    root: Path = Path("."),
    commit: str | None = None,
    verified: str | None = None,
    note: str | None = None,
    date: str | None = None,
) -> dict[str, Any]:
    """Write ``folder/provenance.json`` for the grid just drawn there from the checkout at
    ``root``. ``commit``: the commit the cells ran at (default: ``root``'s). ``verified``:
    restamp an existing folder at today's fingerprint, keeping its commit and command, with
    a note of how the change was shown to move no output. ``note``: anything else a reader
    of the grid needs (cells run at another commit, say); ``date``: the day the cells ran
    (ISO; default today)."""
    record: dict[str, Any]
    if verified is not None:
        record = read_provenance(folder)
        record["verified"] = [
            *record.get("verified", []),
            {"at": head_commit(root), "note": verified},
        ]
    else:
        record = {
            "scenario": scenario,
            "figure": figure,
            "commit": commit or head_commit(root),
            "date": date or datetime.date.today().isoformat(),
            "command": command,
        }
        if note:
            record["note"] = note
    record["fingerprint"] = fingerprint(root, scenario)
    write_json_atomic(Path(folder) / PROVENANCE_FILE, record)
    summary = Path(folder) / "summary.md"
    if summary.is_file():
        write_text_atomic(summary, with_header(summary.read_text(), record))
    return record


HEADER = "> Ran at "


def with_header(summary: str, record: Mapping[str, Any]) -> str:
    """``summary`` (a grid's summary.md) with the provenance quote under its title: the
    commit, the date, the command, each verified change; an older quote is replaced."""
    lines = summary.split("\n")
    body = [ln for ln in lines[1:] if not ln.startswith(">")]
    while body and not body[0].strip():
        body.pop(0)
    quote = [
        f"{HEADER}`{record['commit']}` ({record.get('date', '?')})"
        + (f": `{record['command']}`" if record.get("command") else "")
        + ".",
        *([f"> {record['note']}"] if record.get("note") else []),
        *(f"> Verified unchanged at `{v['at']}`: {v['note']}" for v in record.get("verified", [])),
        "> Whether today's code and parameters would give it again: `make results`; what it "
        "read: `provenance.json`.",
    ]
    return "\n".join([lines[0], "", *quote, "", *body])


def status(folder: Path, root: Path = Path(".")) -> list[str]:
    """What differs between the grid in ``folder`` and the checkout at ``root`` (empty: the
    grid is at main's code)."""
    record = read_provenance(folder)
    return compare(record["fingerprint"], fingerprint(root, record["scenario"]))


def status_line(folder: Path, root: Path = Path(".")) -> str:
    """One line: ``at main's code`` or what changed since the grid's commit."""
    record = read_provenance(folder)
    changes = status(folder, root)
    if not changes:
        return f"at main's code (ran at {record['commit']})"
    files = sum(c.startswith(("solve code", "evaluation code")) for c in changes)
    keys = len(changes) - files
    return (
        f"ran at {record['commit']}; since then {files} source file(s) and {keys} "
        "parameter(s) it reads changed"
    )


def canonical_folders(results: Path = RESULTS_DIR) -> list[Path]:
    """Every ``<scenario>/<figure>/`` folder under ``results`` with a provenance record."""
    return sorted(p.parent for p in Path(results).glob(f"*/*/{PROVENANCE_FILE}"))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="action", required=True)
    stamp_cmd = sub.add_parser("stamp", help="write a folder's provenance.json")
    stamp_cmd.add_argument("folder", type=Path)
    stamp_cmd.add_argument("scenario")
    stamp_cmd.add_argument("figure")
    stamp_cmd.add_argument("--command", default="", help="how the grid was run")
    stamp_cmd.add_argument("--commit", help="the commit the cells ran at (default: HEAD)")
    stamp_cmd.add_argument("--root", type=Path, default=Path("."), help="the checkout")
    stamp_cmd.add_argument("--verified", help="restamp at today's code, saying how")
    stamp_cmd.add_argument("--note", help="what else a reader of the grid needs to know")
    stamp_cmd.add_argument("--date", help="the day the cells ran, YYYY-MM-DD (default: today)")
    status_cmd = sub.add_parser("status", help="which grids are at main's code")
    status_cmd.add_argument("folders", nargs="*", type=Path)
    args = parser.parse_args(argv)
    try:
        if args.action == "stamp":
            stamp(
                args.folder,
                args.scenario,
                args.figure,
                args.command,
                args.root,
                args.commit,
                args.verified,
                args.note,
                args.date,
            )
            return 0
        for folder in args.folders or canonical_folders():
            print(f"{folder}: {status_line(folder)}")
            for change in status(folder):
                print(f"    {change}")
    except ArtifactError as exc:
        print(f"locoman: ArtifactError: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
