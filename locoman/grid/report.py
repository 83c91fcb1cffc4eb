"""Stage ``figures`` for one scenario: run both grids, then draw and summarise them.

Outputs under ``data/<scenario>/figures/``::

    fig5.png, fig6.png        paper A's Fig. 5 and Fig. 6
    vb.png                    V-B over Fig. 6's cells: ours against geometry-unaware, per cell
    fig5/<run>.csv            Fig. 5's curves (node, time_s, penetration_m), for dvc plots
    summary.csv               one row per run of both figures (figures.SUMMARY_COLUMNS)
    summary.md                the same as two tables, and where the paper's claims stand
    metrics.json              per-run numbers of Fig. 5, per-setting rates of Fig. 6, claims,
                              and each grid's penetration by class per run
"""

from __future__ import annotations

import csv
import dataclasses
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from locoman.artifacts import write_json_atomic, write_metrics, write_text_atomic
from locoman.artifacts.io import write_figure
from locoman.config.schema import RootCfg
from locoman.errors import ArtifactError, ConfigError
from locoman.grid.cell import cell_dir, read_record
from locoman.grid.claims import (
    Claim,
    claims_markdown,
    fig5_claims,
    fig6_claims,
    fig6_comparison,
    vb_claims,
    vb_comparison,
)
from locoman.grid.figures import (
    fig5,
    fig6,
    markdown_table,
    setting_table,
    summary_csv,
    vb_figure,
)
from locoman.grid.launch import cells, launch_figures
from locoman.grid.runs import KEYFRAME_RUNS
from locoman.sim.penetration import CLASSES


def collect(
    cfg: RootCfg,
    scenario: str,
    figure: str,
    data_dir: Path,
    runs: Sequence[str] | None = None,
) -> list[dict[str, Any]]:
    """The records of every cell of the figure (``runs``: of these of its runs), in its
    order.

    Raises:
        ArtifactError: A cell has no record (the grid did not finish it).
    """
    records = []
    for cell in cells(cfg, scenario, figure, runs):
        record = read_record(cell_dir(data_dir, cell))
        if record is None:
            raise ArtifactError(
                f"{cell_dir(data_dir, cell)} has no record: run `python -m locoman.grid "
                f"{scenario} {figure}` to finish the grid"
            )
        records.append(record)
    return records


# A Fig. 5 curve's columns: paper A's penetration, then each class's (locoman.sim.penetration).
CURVE_COLUMNS = ("time_s", "penetration_m", *(f"{kind}_m" for kind in CLASSES))


def penetration_curve(folder: Path) -> np.ndarray | None:
    """(N, 2 + classes) time [s], paper A's penetration and each class's [m] per node
    (:data:`CURVE_COLUMNS`) from a cell's evaluation, if it ran."""
    path = folder / "evaluate" / "plots" / "penetration.csv"
    if not path.is_file():
        return None
    with path.open() as f:
        rows = list(csv.DictReader(f))
    return np.array([[float(r[c]) for c in CURVE_COLUMNS] for r in rows])


def _curve_csv(curve: np.ndarray) -> str:
    lines = [",".join(("node", *CURVE_COLUMNS))]
    lines += [
        ",".join([str(k), f"{row[0]:.6f}", *(f"{v:.9f}" for v in row[1:])])
        for k, row in enumerate(curve)
    ]
    return "\n".join(lines) + "\n"


def penetration_by_class(records: Sequence[dict[str, Any]]) -> dict[str, dict[str, Any]]:
    """Each run's penetration by class (:data:`locoman.sim.penetration.CLASSES`) over its
    converged cells whose evaluation ran, for a grid's ``metrics.json``.

    Per run and class: ``cells``, how many cells count; ``max_m``, the deepest node over
    them [m]; ``avg_m``, the mean over them of each cell's average per node [m];
    ``nodes_penetrating``, summed over them; ``deepest_pair``, the deepest geom pair over
    them with its cell's ``box_mass`` [kg] and ``initial_yaw`` [rad]. A run with no such
    cell maps to ``{}``. Failed solves are left out: their trajectories are not solutions,
    and the checks they fail are in their records.
    """
    counted: dict[str, list[dict[str, Any]]] = {r["run"]: [] for r in records}
    for record in records:
        if record["status"] == "converged" and record.get("penetration_by_class"):
            counted[record["run"]].append(record)
    result: dict[str, dict[str, Any]] = {}
    for run, cells_of_run in counted.items():
        result[run] = {}
        for kind in CLASSES if cells_of_run else ():
            per_cell = [(r, r["penetration_by_class"][kind]) for r in cells_of_run]
            pairs = [(c["deepest_pair"], r) for r, c in per_cell if c["deepest_pair"]]
            pair, cell = max(pairs, key=lambda pr: pr[0]["depth_m"], default=(None, None))
            result[run][kind] = {
                "cells": len(per_cell),
                "max_m": max(c["max_m"] for _, c in per_cell),
                "avg_m": float(np.mean([c["avg_m"] for _, c in per_cell])),
                "nodes_penetrating": sum(c["nodes_penetrating"] for _, c in per_cell),
                "deepest_pair": None
                if pair is None
                else pair | {"box_mass": cell["box_mass"], "initial_yaw": cell["initial_yaw"]},
            }
    return result


@dataclasses.dataclass(frozen=True)
class FigureReport:
    """What one figure adds to the scenario's outputs (its PNG is already written)."""

    name: str
    """Its name, e.g. "Fig. 5"."""
    heading: str
    """Its section's heading in the summary, e.g. "Fig. 5 (5 kg, 0 rad)"."""
    table: str
    """Its Markdown table, one row per run."""
    claims: list[Claim]
    """Where the paper's claims that rest on it stand."""
    metrics: dict[str, Any]
    """Its part of ``metrics.json``."""


# A figure's report: (configuration, scenario, its cells' records, out_dir, data_dir).
ReportFunction = Callable[[RootCfg, str, list[dict[str, Any]], Path, Path], FigureReport]


def report_fig5(
    cfg: RootCfg, scenario: str, records: list[dict[str, Any]], out_dir: Path, data_dir: Path
) -> FigureReport:
    """Fig. 5: penetration per node of the four runs (PNG and one CSV curve per run)."""
    runs = {r["run"]: r for r in records}
    curves = {}
    for cell in cells(cfg, scenario, "fig5"):
        curve = penetration_curve(cell_dir(data_dir, cell))
        if curve is not None:
            curves[cell.run] = curve
            write_text_atomic(out_dir / "fig5" / f"{cell.run}.csv", _curve_csv(curve))
    mass, yaw = cfg.scenario.box_mass, cfg.scenario.initial_yaw
    title = f"Paper A, Fig. 5: {scenario} ({mass:g} kg, {yaw:g} rad)"
    write_figure(out_dir / "fig5.png", fig5(runs, curves, title))
    return FigureReport(
        name="Fig. 5",
        heading=f"Fig. 5 ({mass:g} kg, {yaw:g} rad)",
        table=markdown_table(records),
        claims=fig5_claims(runs, cfg.evaluate),
        metrics={
            r["run"]: {
                "status": r["status"],
                "avg_penetration_m": r.get("avg_penetration_m"),
                "max_penetration_m": r.get("max_penetration_m"),
                "penetration_by_class": r.get("penetration_by_class"),
            }
            for r in records
        },
    )


def _keyframe_report(figure: str, name: str, setting: str) -> ReportFunction:
    """The report of a keyframe ablation grid ``figure`` (Fig. 6, in the product's or in
    paper A's settings): its bars (``<figure>.png``) and its convergence rate per setting."""

    def report(
        cfg: RootCfg, scenario: str, records: list[dict[str, Any]], out_dir: Path, data_dir: Path
    ) -> FigureReport:
        bound = cfg.figures.grids[scenario].axis_bound_m
        title = f"Paper A, Fig. 6: {scenario}, keyframe ablation{setting} (box mass, initial yaw)"
        write_figure(out_dir / f"{figure}.png", fig6(records, bound, title))
        return _fig6_report(name, figure, records)

    report.__doc__ = f"{name}: the keyframe ablation{setting}, bars and convergence per setting."
    return report


def _fig6_report(name: str, figure: str, records: list[dict[str, Any]]) -> FigureReport:
    n_cells = len({(r["box_mass"], r["initial_yaw"]) for r in records})
    ran = {r["run"] for r in records}
    converged = {
        run.name: sum(r["status"] == "converged" for r in records if r["run"] == run.name)
        for run in KEYFRAME_RUNS
        if run.name in ran
    }
    return FigureReport(
        name=name,
        heading=name,
        table=f"Per setting, over {n_cells} cells:\n\n{setting_table(records)}\n"
        f"Per run:\n\n{markdown_table(records)}",
        claims=fig6_claims(records, figure),
        metrics={
            "cells": n_cells,
            "converged_rate": {name: n / n_cells for name, n in converged.items()},
            "errors": sum(r["status"] == "error" for r in records),
            "penetration_all_vs_none": fig6_comparison(records).as_dict(),
            "penetration_by_class": penetration_by_class(records),
        },
    )


def report_vb(
    cfg: RootCfg, scenario: str, records: list[dict[str, Any]], out_dir: Path, data_dir: Path
) -> FigureReport:
    """V-B over the grid: ours against the geometry-unaware contacts, paired by cell."""
    title = f"Paper A, V-B over the grid: {scenario}, no collision terms"
    write_figure(out_dir / "vb.png", vb_figure(records, title))
    return FigureReport(
        name="V-B over the grid",
        heading="V-B over the grid",
        table=markdown_table(records),
        claims=vb_claims(records),
        metrics=vb_comparison(records).as_dict()
        | {"penetration_by_class": penetration_by_class(records)},
    )


REPORTS: dict[str, ReportFunction] = {
    "fig5": report_fig5,
    "fig6": _keyframe_report("fig6", "Fig. 6", ""),
    "vb": report_vb,
    "fig6_paper": _keyframe_report(
        "fig6_paper", "Fig. 6, paper A's settings", " in paper A's settings"
    ),
}
"""The figures a scenario can have, in the summary's order: name -> report function."""


def default_figures(cfg: RootCfg, scenario: str) -> list[str]:
    """The figures the ``figures`` stage draws for ``scenario``: every one it can run
    (``fig6_paper`` where ``solve.paper_a`` describes the scenario)."""
    return [f for f in REPORTS if f != "fig6_paper" or scenario in cfg.solve.paper_a]


def figures_scenario(
    cfg: RootCfg,
    scenario: str,
    out_dir: Path,
    data_dir: Path = Path("data"),
    params_file: Path = Path("params.yaml"),
    figures: Sequence[str] | None = None,
    runs: Sequence[str] | None = None,
    solve: bool = True,
) -> dict[str, Any]:
    """Run the grids of ``figures`` (None: :func:`default_figures`) for ``scenario`` (cells
    up to date are skipped), draw, summarise; return the metrics. ``cfg`` is
    ``params_file``'s, which the cells read. ``runs``: only these of each figure's runs
    (Fig. 6's NoKeyframe and AllKeyframe, say, where a grid of every setting costs hours);
    ``solve`` False draws the cells' records as they are.

    Raises:
        ConfigError: An unknown figure.
    """
    if figures is None:
        figures = default_figures(cfg, scenario)
    unknown = set(figures) - set(REPORTS)
    if unknown:
        raise ConfigError(f"unknown figures {sorted(unknown)}; known: {list(REPORTS)}")
    figures = [f for f in REPORTS if f in figures]
    if not solve:
        return draw(cfg, scenario, figures, out_dir, data_dir, runs=runs)
    seconds = launch_figures(cfg, scenario, figures, params_file=params_file, runs=runs)
    return draw(cfg, scenario, figures, out_dir, data_dir, seconds, runs)


def draw(
    cfg: RootCfg,
    scenario: str,
    figures: Sequence[str],
    out_dir: Path,
    data_dir: Path = Path("data"),
    seconds: dict[str, float] | None = None,
    runs: Sequence[str] | None = None,
) -> dict[str, Any]:
    """Draw and summarise ``figures`` from their cells' records into ``out_dir``; return the
    metrics. ``seconds``: each grid's wall time [s], for ``timing.json`` (None: the one there
    is kept); ``runs``: only these of each figure's runs.

    Raises:
        ArtifactError: A cell has no record.
    """
    records = {f: collect(cfg, scenario, f, data_dir, runs) for f in figures}
    reports = {f: REPORTS[f](cfg, scenario, records[f], out_dir, data_dir) for f in figures}

    claims = [c for report in reports.values() for c in report.claims]
    rows = [r for f in figures for r in records[f]]
    write_text_atomic(out_dir / "summary.csv", summary_csv(rows))
    names = " and ".join(r.name for r in reports.values())
    sections = "\n".join(f"## {r.heading}\n\n{r.table}" for r in reports.values())
    write_text_atomic(
        out_dir / "summary.md",
        f"# {scenario}: paper A's {names}\n\n"
        "## Where the paper's claims stand\n\n"
        f"{claims_markdown(claims)}\n{sections}",
    )
    metrics = {f: r.metrics for f, r in reports.items()} | {
        "claims": {c.key: c.holds for c in claims}
    }
    timing = out_dir / "timing.json"
    # Redrawn without running: the grid's wall times stay those of the run that made it.
    kept = timing.read_text() if seconds is None and timing.is_file() else None
    write_metrics(out_dir, metrics)
    if kept is not None:
        write_text_atomic(timing, kept)
    if seconds is not None:
        write_json_atomic(
            out_dir / "timing.json",
            {
                "grid_wall_time_s": seconds,
                "cells_wall_time_s": {
                    f: sum(r.get("wall_time_s", 0.0) for r in records[f]) for f in figures
                },
            },
        )
    return metrics
