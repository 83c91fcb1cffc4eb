"""Where the product stands, in one place: today's numbers, the papers' claims, and how old
each committed result is.

Usage::

    python -m locoman.results                    (make results)
    python -m locoman.results --readme           the README's two results tables (markdown)
    python -m locoman.results --update-readme    write them into README.md

``make results`` prints three things. Today's headline numbers per scenario, from the
stages' ``metrics.json`` under ``data/`` (a stage that has not run shows ``-``; the full
figures stay in each stage's ``metrics.json`` and ``details.json``). Where each of the
papers' claims stands, from each figure's canonical folder: ``benchmarks/results/
<scenario>/<figure>/`` for the grids run outside the pipeline, the ``figures`` stage's
``data/<scenario>/figures/`` for those ``dvc repro`` draws (``tiny``'s), and paper B's
replay; with, for each grid, whether today's code and parameters would give it again
(:mod:`locoman.grid.provenance`). And each benchmark's JSON with the commit it ran at.

The README's two tables are made here from the same files (:func:`readme_tables`), and
``tests/test_results.py`` checks that the README holds exactly them.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import yaml

from locoman.errors import ArtifactError
from locoman.grid.provenance import canonical_folders, status_line

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
# The humanoid scenarios of the papers, in the README's order, with their short names.
PAPER_SCENARIOS = {"tiny": "`tiny`", "s1_basket": "S1", "s2_trolley": "S2"}
# Paper A's claims (Sec. V): (metrics key, figure, short name, the claim in a line).
CLAIMS = (
    (
        "fig5_minimal_set",
        "fig5",
        "V-A",
        "A, V-A: with the minimal collision set ours is collision-free, the naive contacts "
        "penetrate",
    ),
    (
        "vb_contact_transfer",
        "vb",
        "V-B",
        "A, V-B: without collision terms, geometry-unaware contacts penetrate more than ours "
        "(paired grid cells)",
    ),
    (
        "fig6_convergence",
        "fig6",
        "V-C converges",
        "A, V-C: AllKeyframe converges at least as often as NoKeyframe",
    ),
    (
        "fig6_penetration",
        "fig6",
        "V-C penetration",
        "A, V-C: AllKeyframe penetrates less than NoKeyframe (paired grid cells)",
    ),
    (
        "fig6_paper_convergence",
        "fig6_paper",
        "V-C converges, paper's settings",
        "A, V-C in paper A's settings (`solve.mode: paper_a`): AllKeyframe converges at "
        "least as often",
    ),
    (
        "fig6_paper_penetration",
        "fig6_paper",
        "V-C penetration, paper's settings",
        "A, V-C in paper A's settings: AllKeyframe penetrates less",
    ),
)
# The figures the ``figures`` stage draws into data/<scenario>/figures/.
STAGE_FIGURES = ("fig5", "fig6", "vb")
# Fewer paired cells than this decide nothing (locoman.grid.paired).
MIN_PAIRS = 5
RESULTS = Path("benchmarks/results")
SOLVERS_JSON = "to_solvers.json"
SOLVERS_CONFIG = "gcc:-O1"


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


def markdown(header: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    """A markdown table."""
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(row) + " |" for row in rows]
    return "\n".join(lines)


# --- the papers' claims --------------------------------------------------------------------


def claim_folder(scenario: str, figure: str, root: Path = Path(".")) -> Path:
    """The canonical folder of ``scenario``'s ``figure``, relative to the repository at
    ``root``: the figures stage's ``data/<scenario>/figures/`` where ``dvc repro`` draws it,
    else ``benchmarks/results/<scenario>/<figure>/``."""
    stage = Path("data") / scenario / "figures"
    if figure in STAGE_FIGURES and (root / stage / "metrics.json").is_file():
        return stage
    return RESULTS / scenario / figure


def _verdict(holds: bool | None) -> str:
    return {True: "reproduced", False: "NOT reproduced", None: "undecided"}[holds]


def _mm(value: float | None) -> str:
    return "-" if value is None else f"{1000 * value:.1f} mm"


def _fig5_text(holds: bool | None, fig5: Mapping[str, Any]) -> str:
    ours, naive = fig5.get("ours", {}), fig5.get("naive", {})
    return (
        f"{_verdict(holds)} (ours {ours.get('status', '-')}, "
        f"{_mm(ours.get('avg_penetration_m'))}; naive {naive.get('status', '-')}, "
        f"{_mm(naive.get('avg_penetration_m'))})"
    )


def _paired_text(holds: bool | None, paired: Mapping[str, Any], who: str) -> str:
    n, wins = paired["paired"], paired["a_wins"]
    if n < MIN_PAIRS:
        return f"{_verdict(holds)} ({who} lower in {wins} of {n} cells; < {MIN_PAIRS} pairs)"
    low, high = (1000 * v for v in paired["interval"])
    return (
        f"{_verdict(holds)} ({who} lower in {wins} of {n}; median "
        f"{1000 * paired['median_difference']:+.1f} mm, [{low:+.1f}, {high:+.1f}])"
    )


def _converged(section: Mapping[str, Any], run: str) -> str:
    cells = section["cells"]
    return f"{round(section['converged_rate'][run] * cells)}/{cells}"


def claim_text(key: str, figure: str, metrics: Mapping[str, Any]) -> str:
    """A claim's verdict with the numbers that decide it, from a figure's metrics.json."""
    holds = metrics.get("claims", {}).get(key)
    section = metrics.get(figure)
    if section is None or key not in metrics.get("claims", {}):
        raise ArtifactError(f"the {figure} metrics hold no claim {key!r}")
    if key == "fig5_minimal_set":
        return _fig5_text(holds, section)
    if key == "vb_contact_transfer":
        return _paired_text(holds, section["penetration_ours_vs_geometry_unaware"], "ours")
    if key.endswith("_convergence"):
        word = {True: "yes", False: "no", None: "undecided"}[holds]
        return (
            f"{word} (AllKeyframe {_converged(section, 'all')}, NoKeyframe "
            f"{_converged(section, 'none')})"
        )
    return _paired_text(holds, section["penetration_all_vs_none"], "AllKeyframe")


def _vb_section(metrics: dict[str, Any]) -> dict[str, Any]:
    """The V-B paired comparison under one name, whether the summary keeps it under its
    figure (``vb``) as the comparison itself or beside the runs' numbers."""
    vb = metrics.get("vb", {})
    if "penetration_ours_vs_geometry_unaware" not in vb and "paired" in vb:
        metrics = {**metrics, "vb": {"penetration_ours_vs_geometry_unaware": vb}}
    return metrics


def claim_cell(scenario: str, key: str, figure: str, root: Path, link: bool) -> str:
    """One cell of the claims table: the verdict, its numbers and (``link``) the folder;
    empty where the scenario has no such grid."""
    folder = claim_folder(scenario, figure, root)
    metrics = _read(root / folder / "metrics.json")
    if metrics is None or key not in metrics.get("claims", {}):
        return ""
    text = claim_text(key, figure, _vb_section(metrics))
    return f"{text} ([{figure}]({folder.as_posix()}/))" if link else text


def mobile_claim(data: Path) -> str | None:
    """Paper B's RMSEs against ours: in how many of the paper's numbers ours are lower."""
    from locoman.hqp.figures import PAPER_RMSE

    metrics = _read(data / "mm_pick_place" / "hqp_replay" / "metrics.json")
    if metrics is None:
        return None
    lower = total = 0
    for case, paper in PAPER_RMSE.items():
        for key, values in paper.items():
            ours = metrics.get(case, {}).get(key)
            if ours is not None:
                lower += sum(o < p for o, p in zip(ours, values, strict=True))
                total += len(values)
    return (
        f"ours lower than the paper's in {lower} of {total} (a simulated robot against a real one)"
    )


# --- the README's tables -------------------------------------------------------------------


def _solve_seconds(results: Path) -> dict[str, float]:
    solvers = _read(results / SOLVERS_JSON) or {}
    return {
        r["scenario"]: r["solve_time_median_s"]
        for r in solvers.get("results", [])
        if r.get("config") == SOLVERS_CONFIG
    }


def _deepest(evaluation: Mapping[str, Any], kind: str) -> str | None:
    pair = evaluation.get("penetration_by_class", {}).get(kind, {}).get("deepest_pair")
    if not pair:
        return None
    return f"{1000 * pair['depth_m']:.1f} mm ({' / '.join(pair['geoms'])})"


def _scenario_row(
    scenario: str, description: str, data: Path, seconds: dict[str, float]
) -> list[str]:
    solve = _read(data / scenario / "solve" / "metrics.json") or {}
    evaluation = _read(data / scenario / "evaluate" / "metrics.json") or {}
    rounds = [r for r in solve.get("collision_rounds", []) if r.get("pairs_added", 0) > 0]
    time = f", solve {seconds[scenario]:.1f} s" if scenario in seconds else ""
    to = (
        f"{solve.get('status', '-')}: {solve.get('iterations', '-')} iterations "
        f"({len(rounds)} {'round' if len(rounds) == 1 else 'rounds'}, "
        f"{solve.get('pairs_found', 0)} found pairs){time}"
    )
    failed = evaluation.get("failed_checks") or []
    verdict = "passes" if evaluation.get("success") else f"fails {', '.join(failed)}"
    parts = [
        verdict,
        f"penetration {_mm(evaluation.get('avg_penetration_m'))} on average, "
        f"{_mm(evaluation.get('max_penetration_m'))} at the worst node",
    ]
    for kind, what in (
        ("scheduled_contact", "deepest contact"),
        ("object_environment", "an object"),
    ):
        deepest = _deepest(evaluation, kind)
        if deepest:
            parts.append(f"{what} {deepest}")
    goals = [
        f"{k.removesuffix('_goal_error_m')} {_mm(v)}"
        for k, v in sorted(evaluation.items())
        if k.endswith("_goal_error_m") and k != "object_goal_error_m"
    ]
    if goals:
        parts.append("goal " + ", ".join(goals))
    return [f"{PAPER_SCENARIOS[scenario]}: {description}", to, "; ".join(parts)]


EXECUTION_CLAIM = "ours: carried out in MuJoCo's physics (`execute`)"


def execution_cell(data: Path, scenario: str) -> str:
    """Whether the G1 carried the scenario out in MuJoCo's forward dynamics
    (``data/<scenario>/execute/metrics.json``), with what failed and for how long it stood."""
    metrics = _read(data / scenario / "execute" / "metrics.json")
    if metrics is None:
        return "not run"
    link = f"([execute](data/{scenario}/execute/))"
    goals = [v for k, v in sorted(metrics.items()) if k.endswith("_goal_error_m")]
    if metrics["success"]:
        worst = f"; objects within {100 * max(goals):.1f} cm of their goals" if goals else ""
        return f"yes{worst} {link}"
    failed = metrics["failed_checks"]
    when = f"{metrics['time_up_s']:.1f} of {metrics['duration_s']:.1f} s"
    if "stayed_up" in failed:
        return f"no: fell at {when} {link}"
    if "completed" in failed:
        return f"no: stopped at {when} {link}"
    missed = [
        f"{k.removesuffix('_goal_error_m')} {100 * v:.0f} cm from its goal"
        for k, v in sorted(metrics.items())
        if k.endswith("_goal_error_m") and v > metrics.get("goal_tol_m", 0.05)
    ]
    others = [check for check in failed if check != "object_goal"]
    return f"no: up throughout; {'; '.join(missed + others)} {link}"


def readme_tables(root: Path = Path(".")) -> str:
    """The README's two tables, from the files they cite: each scenario's solve and
    evaluation (``data/<scenario>/{solve,evaluate}/metrics.json``, the solve time from
    ``benchmarks/results/to_solvers.json``), and where each of the papers' claims stands
    (each figure's canonical folder, linked; paper B's replay)."""
    data, results = root / "data", root / RESULTS
    params = yaml.safe_load((root / "params.yaml").read_text())
    seconds = _solve_seconds(results)
    head = [
        "scenario (`dvc repro`; solve time: median of 3, "
        f"[`{SOLVERS_JSON}`](benchmarks/results/{SOLVERS_JSON}))",
        "TO",
        "evaluation",
    ]
    rows = [
        _scenario_row(s, params["scenarios"][s]["description"].rstrip("."), data, seconds)
        for s in PAPER_SCENARIOS
    ]
    claims_head = ["claim", *PAPER_SCENARIOS.values()]
    claims = [
        [text, *(claim_cell(s, key, figure, root, True) for s in PAPER_SCENARIOS)]
        for key, figure, _, text in CLAIMS
    ]
    claims.append([EXECUTION_CLAIM, *(execution_cell(data, s) for s in PAPER_SCENARIOS)])
    text = markdown(head, rows) + "\n\n" + markdown(claims_head, claims)
    mobile = mobile_claim(data)
    if mobile is not None:
        text += (
            "\n\nPaper B on `mm_pick_place`, the EE and base tracking RMSEs of Sec. IV-C: "
            f"{mobile} ([replay](data/mm_pick_place/hqp_replay/results.md))."
        )
    return text


BEGIN, END = "<!-- results: begin -->", "<!-- results: end -->"


def readme_section(readme: str) -> str:
    """The part of a README between :data:`BEGIN` and :data:`END`.

    Raises:
        ArtifactError: The README has no such part.
    """
    try:
        start = readme.index(BEGIN) + len(BEGIN)
        return readme[start : readme.index(END, start)].strip()
    except ValueError as exc:
        raise ArtifactError(f"the README has no {BEGIN} ... {END} section") from exc


def update_readme(path: Path, root: Path = Path(".")) -> bool:
    """Write :func:`readme_tables` between the README's markers; return whether it changed.

    Raises:
        ArtifactError: The README has no marked section.
    """
    text = path.read_text()
    old = readme_section(text)
    new = readme_tables(root)
    if old == new:
        return False
    start = text.index(BEGIN) + len(BEGIN)
    end = text.index(END, start)
    path.write_text(f"{text[:start]}\n{new}\n{text[end:]}")
    return True


# --- how old each result is ----------------------------------------------------------------


def grid_lines(data: Path, results: Path) -> list[str]:
    """A line per canonical grid: where it is and whether it is at today's code."""
    lines = []
    for folder in sorted(data.glob("*/figures/metrics.json")):
        lines.append(
            f"{folder.parent}/: drawn by `dvc repro figures@{folder.parent.parent.name}`, at "
            "today's code when `dvc status` is clean"
        )
    for folder in canonical_folders(results):
        try:
            lines.append(f"{folder}/: {status_line(folder)}")
        except ArtifactError as exc:
            lines.append(f"{folder}/: {exc}")
    return lines


def benchmark_lines(results: Path) -> list[str]:
    """A line per benchmark JSON: the commit and date it ran at, where it says."""
    lines = []
    for path in sorted(results.glob("*.json")):
        record = _read(path) or {}
        commit = record.get("commit", "no commit recorded")
        date = f", {record['date']}" if "date" in record else ""
        lines.append(f"{path}: at {commit}{date}")
    return lines


def claims_report(root: Path) -> str:
    """Where each claim stands per scenario, with the canonical folder behind it."""
    rows = []
    for key, figure, short, _ in CLAIMS:
        for scenario in PAPER_SCENARIOS:
            cell = claim_cell(scenario, key, figure, root, False)
            if cell:
                folder = claim_folder(scenario, figure, root)
                rows.append([short, scenario, cell, f"{folder}/"])
    return table(["claim", "scenario", "where it stands", "from"], rows)


def _section(title: str, body: str) -> str:
    return f"\n{title}\n\n{body}"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=Path("data"))
    parser.add_argument("--results", type=Path, default=RESULTS)
    parser.add_argument("--readme", action="store_true", help="print the README's tables")
    parser.add_argument("--update-readme", action="store_true", help="write them into README.md")
    args = parser.parse_args(argv)
    if not args.data.is_dir():
        print(f"locoman: no {args.data}/ folder; run `make run` first", file=sys.stderr)
        return 2
    if args.readme:
        print(readme_tables())
        return 0
    if args.update_readme:
        changed = update_readme(Path("README.md"))
        print("README.md " + ("updated" if changed else "already up to date"))
        return 0
    show = print
    header = ["scenario", *(c[0] for c in HUMANOID_COLUMNS), "failed checks"]
    show("Paper A (humanoid), today's outputs: per scenario\n")
    show(table(header, humanoid_rows(args.data)))
    show("\nPaper B (mobile manipulator), today's outputs: per replay\n")
    mobile = ["replay", "EE pos RMSE x,y,z [cm]", "EE vel RMSE [cm/s]", "bottle err [mm]"]
    show(table([*mobile, "success"], mobile_rows(args.data)))
    show(_section("Where the papers' claims stand, and the folder behind each:", ""))
    show(claims_report(Path(".")))
    show(
        _section(
            "The grids: are they at today's code?", "\n".join(grid_lines(args.data, args.results))
        )
    )
    show(_section("The benchmarks (benchmarks/*.py):", "\n".join(benchmark_lines(args.results))))
    return 0


if __name__ == "__main__":
    sys.exit(main())
