"""Paper A's Fig. 5 and Fig. 6 and their summary, drawn from the cells' records.

- Fig. 5 (Sec. V-A, V-B): paper A's penetration per node of the TO (the robot's self,
  robot-object and robot-environment pairs), replayed in MuJoCo, for the four runs of
  :data:`~locoman.grid.runs.PIPELINE_RUNS`; left ours against naive with the minimal
  collision set, right ours against the geometry-unaware contacts with every collision
  term off; below each, the same runs per class (:mod:`locoman.sim.penetration`).
- Fig. 6 (Sec. V-C): one panel per (box mass, initial yaw); one bar per keyframe setting,
  its average penetration (the sum over nodes / nodes); hatched where the TO did not
  converge, a triangle at the axis bound where the bar is cut, an ``x`` where the cell
  could not run.
"""

from __future__ import annotations

import csv
import io
import math
import statistics
from collections.abc import Sequence
from typing import Any

import numpy as np
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch

from locoman.grid.runs import KEYFRAME_RUNS, PIPELINE_RUNS
from locoman.sim.penetration import CLASSES

# Paper A's colours where it names them: ours blue, naive red (Fig. 5); NoKeyframe grey and
# AllKeyframe pink (Fig. 6).
FIG5_COLOURS = {
    "ours": "tab:blue",
    "naive": "tab:red",
    "ours_no_collision": "tab:blue",
    "geometry_unaware": "tab:red",
}
FIG6_COLOURS = {
    "none": "tab:grey",
    "base": "tab:orange",
    "foot": "tab:green",
    "warm": "tab:cyan",
    "base_foot": "tab:olive",
    "base_warm": "tab:purple",
    "foot_warm": "tab:brown",
    "all": "tab:pink",
}
# The summary's columns, in order.
SUMMARY_COLUMNS = (
    "figure",
    "run",
    "label",
    "box_mass",
    "initial_yaw",
    "status",
    "reason",
    "iterations",
    "collision_rounds",
    "pairs_found",
    "restarts",
    "avg_penetration_m",
    "max_penetration_m",
    "max_penetration_pair",
    "dynamics_residual_max",
    "object_goal_error_m",
    "success",
)


# A class's line in Fig. 5's lower panels.
CLASS_STYLES = {
    "self": ":",
    "robot_object": "-",
    "robot_environment": "-.",
    "scheduled_contact": (0, (6, 2, 1, 2, 1, 2)),
    "object_environment": "--",
}


def fig5(records: dict[str, dict[str, Any]], curves: dict[str, np.ndarray], title: str) -> Figure:
    """Fig. 5 of one scenario.

    Args:
        records: Run name -> the cell's record.
        curves: Run name -> (N, 2 + classes) time [s], paper A's penetration and each
            class's [m] per node (:data:`locoman.grid.report.CURVE_COLUMNS`).
        title: The figure's title.
    """
    fig = Figure(figsize=(11, 7), layout="constrained")
    fig.suptitle(title)
    panels = (
        ("V-A: minimal collision set", ("ours", "naive")),
        ("V-B: no collision terms", ("ours_no_collision", "geometry_unaware")),
    )
    labels = {r.name: r.label for r in PIPELINE_RUNS}
    axes = fig.subplots(2, 2, sharex="col")
    for (ax, by_class), (name, runs) in zip(axes.T, panels, strict=True):
        for run in runs:
            record = records.get(run)
            if record is None or run not in curves:
                why = record["reason"] if record else "not run"
                ax.plot([], [], color=FIG5_COLOURS[run], label=f"{labels[run]}: {why}")
                continue
            t, pen, *classes = curves[run].T
            converged = "" if record["status"] == "converged" else " (not converged)"
            style = "-" if run in ("ours", "ours_no_collision") else "--"
            ax.plot(t, pen * 1000, style, color=FIG5_COLOURS[run], label=labels[run] + converged)
            for kind, values in zip(CLASSES, classes, strict=True):
                if values.any():
                    by_class.plot(
                        t,
                        values * 1000,
                        ls=CLASS_STYLES[kind],
                        color=FIG5_COLOURS[run],
                        label=f"{run}: {kind}",
                    )
        ax.set_title(name)
        by_class.set_xlabel("time [s]")
        ax.legend(fontsize=7)
        by_class.legend(fontsize=6, ncol=2)
        for a in (ax, by_class):
            a.grid(alpha=0.3)
    axes[0, 0].set_ylabel("penetration at the node [mm]\n(self + robot-object + robot-env.)")
    axes[1, 0].set_ylabel("per class [mm]")
    return fig


VB_MARKERS = "osD^vP*X"  # one per initial yaw, in the grid's order


def vb_figure(records: Sequence[dict[str, Any]], title: str) -> Figure:
    """V-B over a grid: per cell, ours (x) against the geometry-unaware contacts (y), paper
    A's average penetration, both without collision terms; above the diagonal ours is lower.
    A colour per box mass, a marker per initial yaw; filled where both converged (the pairs
    the claim is decided on), hollow otherwise."""
    fig = Figure(figsize=(6, 5), layout="constrained")
    ax = fig.subplots()
    by = {(r["box_mass"], r["initial_yaw"], r["run"]): r for r in records}
    cells = _cell_panels(records)
    masses = list(dict.fromkeys(m for m, _ in cells))
    yaws = list(dict.fromkeys(y for _, y in cells))
    colours = {m: f"C{k}" for k, m in enumerate(masses)}
    markers = {y: VB_MARKERS[k % len(VB_MARKERS)] for k, y in enumerate(yaws)}
    top = 0.0
    for mass, yaw in cells:
        ours = by.get((mass, yaw, "ours_no_collision"))
        other = by.get((mass, yaw, "geometry_unaware"))
        if not ours or not other or None in (ours["avg_penetration_m"], other["avg_penetration_m"]):
            continue
        x, y = ours["avg_penetration_m"] * 1000, other["avg_penetration_m"] * 1000
        both = ours["status"] == other["status"] == "converged"
        colour = colours[mass]
        ax.plot(x, y, markers[yaw], ms=8, color=colour, mfc=colour if both else "none")
        top = max(top, x, y)
    top = top * 1.1 or 1.0
    ax.plot([0, top], [0, top], color="grey", lw=0.8)
    ax.set_xlim(0, top)
    ax.set_ylim(0, top)
    ax.set_xlabel("ours, no collision terms: average penetration [mm]")
    ax.set_ylabel("geometry-unaware contacts: average penetration [mm]")
    ax.set_title(title, fontsize=10)
    ax.grid(alpha=0.3)
    handles = [Patch(color=colours[m], label=f"{m:g} kg") for m in masses]
    handles += [
        Line2D([], [], ls="", marker=markers[y], color="black", label=f"{y:g} rad") for y in yaws
    ]
    handles.append(
        Line2D([], [], ls="", marker="o", mfc="none", color="black", label="one did not converge")
    )
    ax.legend(handles=handles, fontsize=7, loc="lower right", ncol=2)
    return fig


def _cell_panels(records: Sequence[dict[str, Any]]) -> list[tuple[float, float]]:
    return list(dict.fromkeys((r["box_mass"], r["initial_yaw"]) for r in records))


# IPOPT's statuses and the found-pair search's, as a hatched bar of Fig. 6 says why the cell
# did not converge.
SHORT_REASONS = {
    "Collision_Pairs_Missing": "pairs",
    "Collision_Pairs_Unfreed": "unfreed",
    "Maximum_Iterations_Exceeded": "iter",
    "Maximum_WallTime_Exceeded": "time",
    "Maximum_CpuTime_Exceeded": "time",
    "Infeasible_Problem_Detected": "infeas",
    "Restoration_Failed": "restor",
    "Diverging_Iterates": "diverg",
    "Error_In_Step_Computation": "step",
    "Search_Direction_Becomes_Too_Small": "dir",
    "Invalid_Number_Detected": "nan",
}


def short_reason(reason: str) -> str:
    """A few letters for IPOPT's status or the found-pair search's (``pairs``: the rounds
    ended with pairs still missing, ``unfreed``: with a pair they could not free), or the
    reason's first word."""
    return SHORT_REASONS.get(reason, reason.split(" ")[0][:6] or "?")


def fig6(records: Sequence[dict[str, Any]], bound_m: float, title: str) -> Figure:
    """Fig. 6 of one scenario: a panel per (mass, yaw), a bar per keyframe setting."""
    panels = _cell_panels(records)
    cols = min(len(panels), 3)
    rows = math.ceil(len(panels) / cols)
    # At least two panels wide: the title and the legend's row span that much.
    fig = Figure(figsize=(4.2 * max(cols, 2), 3.2 * rows + 0.8), layout="constrained")
    fig.suptitle(title)
    axes = np.atleast_1d(fig.subplots(rows, cols, sharey=True, squeeze=False)).ravel()
    by_cell = {(r["box_mass"], r["initial_yaw"], r["run"]): r for r in records}
    bound_mm = bound_m * 1000
    # The settings the grid ran (all 8, or a chosen few).
    ran = {r["run"] for r in records}
    settings = [run for run in KEYFRAME_RUNS if run.name in ran]
    for ax, (mass, yaw) in zip(axes, panels, strict=False):
        for k, run in enumerate(settings):
            record = by_cell.get((mass, yaw, run.name))
            colour = FIG6_COLOURS[run.name]
            if record is None or record["status"] == "error" or record["avg_penetration_m"] is None:
                ax.plot(k, 0.0, "x", color=colour, ms=9, mew=2)
                continue
            value = record["avg_penetration_m"] * 1000
            hatch = None if record["status"] == "converged" else "//"
            ax.bar(k, min(value, bound_mm), color=colour, hatch=hatch, edgecolor="black", lw=0.5)
            # The value on top: a 0 mm bar is otherwise indistinguishable from no bar.
            ax.text(
                k,
                min(value, bound_mm) + bound_mm * 0.01,
                f"{value:.1f}",
                ha="center",
                va="bottom",
                fontsize=7,
            )
            if hatch is not None:
                why = short_reason(str(record.get("reason") or record["status"]))
                ax.text(
                    k,
                    bound_mm * 0.02,
                    why,
                    rotation=90,
                    ha="center",
                    va="bottom",
                    fontsize=8,
                    bbox={"facecolor": "white", "edgecolor": "none", "pad": 1.0},
                )
            if value > bound_mm:
                ax.plot(k, bound_mm, "^", color="black", ms=8)
        ax.set_title(f"({mass:g} kg, {yaw:g} rad)")
        ax.set_ylim(0.0, bound_mm * 1.08)
        ax.set_xticks(range(len(settings)), [""] * len(settings))
        ax.grid(axis="y", alpha=0.3)
    for ax in axes[len(panels) :]:
        ax.set_visible(False)
    for ax in axes[::cols]:
        ax.set_ylabel("average penetration [mm]")
    handles = [Patch(color=FIG6_COLOURS[r.name], label=r.label) for r in settings]
    handles += [
        Patch(
            facecolor="white",
            edgecolor="black",
            hatch="//",
            label="not converged (why: iter, time, infeas,\nrestor, diverg, pairs, unfreed)",
        ),
        Line2D([], [], ls="", marker="^", color="black", label="beyond the axis bound"),
        Line2D([], [], ls="", marker="x", color="black", label="could not run"),
    ]
    # Six columns fit three panels' width; two panels take four (the legend was clipped).
    fig.legend(handles=handles, loc="outside lower center", ncols=6 if cols >= 3 else 4, fontsize=8)
    return fig


def summary_csv(records: Sequence[dict[str, Any]]) -> str:
    """One row per run: :data:`SUMMARY_COLUMNS`."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(SUMMARY_COLUMNS)
    for record in records:
        writer.writerow([_cell_text(record.get(c)) for c in SUMMARY_COLUMNS])
    return buffer.getvalue()


def _cell_text(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, float):
        return f"{value:.6g}"
    if isinstance(value, list):
        return " / ".join(map(str, value))
    return str(value)


def _mm(value: float | None) -> str:
    return "-" if value is None else f"{value * 1000:.1f}"


# IPOPT's status of a solve that ended on the settled stop (``SolverCfg.settled_change``):
# converged, marked "settled" in the summaries.
SETTLED = "Solved_To_Acceptable_Level"


def markdown_table(records: Sequence[dict[str, Any]]) -> str:
    """The summary of one figure as a Markdown table (penetrations in mm); a run whose last
    solve ended on the settled stop reads "converged (settled)"."""
    head = (
        "| run | mass [kg] | yaw [rad] | status | iterations | rounds / pairs found / restarts "
        "| avg pen. [mm] | max pen. [mm] | deepest pair | dynamics residual | goal error [mm] |\n"
        "|---|---|---|---|---|---|---|---|---|---|---|\n"
    )
    rows = []
    for r in records:
        status = r["status"] + (f" ({r['reason']})" if r.get("reason") else "")
        if r.get("solver_status") == SETTLED:
            status += " (settled)"
        residual = r.get("dynamics_residual_max")
        rows.append(
            f"| {r['label']} | {r['box_mass']:g} | {r['initial_yaw']:g} | {status} "
            f"| {r.get('iterations', '-')} "
            f"| {r.get('collision_rounds', '-')} / {r.get('pairs_found', '-')} "
            f"/ {r.get('restarts', '-')} "
            f"| {_mm(r.get('avg_penetration_m'))} "
            f"| {_mm(r.get('max_penetration_m'))} "
            f"| {' / '.join(r.get('max_penetration_pair') or []) or '-'} "
            f"| {'-' if residual is None else f'{residual:.1e}'} "
            f"| {_mm(r.get('object_goal_error_m'))} |"
        )
    return head + "\n".join(rows) + "\n"


def _range_mm(values: Sequence[float]) -> str:
    return "-" if not values else f"{min(values) * 1000:.1f}-{max(values) * 1000:.1f}"


def setting_table(records: Sequence[dict[str, Any]]) -> str:
    """Fig. 6 per keyframe setting over the grid's cells, as a Markdown table: how many
    converged, the mean and range of the cells' average penetration, the range of their
    deepest node [mm], and how many passed every evaluation check. A cell that could not
    run counts as not converged and has no penetration."""
    head = (
        "| setting | converged | avg pen. [mm], mean over cells (range) | max pen. [mm] (range) "
        "| every check passes |\n|---|---|---|---|---|\n"
    )
    rows = []
    for run in KEYFRAME_RUNS:
        mine = [r for r in records if r["run"] == run.name]
        if not mine:
            continue
        ran = [r for r in mine if r.get("avg_penetration_m") is not None]
        avg = [r["avg_penetration_m"] for r in ran]
        deepest = [r["max_penetration_m"] for r in ran if r.get("max_penetration_m") is not None]
        mean = "-" if not avg else f"{statistics.fmean(avg) * 1000:.2f} ({_range_mm(avg)})"
        converged = sum(r["status"] == "converged" for r in mine)
        passed = sum(bool(r.get("success")) for r in mine)
        rows.append(
            f"| {run.label} | {converged}/{len(mine)} | {mean} | {_range_mm(deepest)} "
            f"| {passed}/{len(mine)} |"
        )
    return head + "\n".join(rows) + "\n"
