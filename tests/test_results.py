"""`make results` and the README's tables: today's numbers, the claims, and where they come from."""

from __future__ import annotations

import json
import re

from locoman.results import (
    BEGIN,
    END,
    claim_text,
    execution_cell,
    main,
    readme_section,
    readme_tables,
    update_readme,
)


def _metrics(path, data):
    path.mkdir(parents=True)
    (path / "metrics.json").write_text(json.dumps(data))


def test_the_table_shows_each_scenarios_headline_and_what_is_missing(tmp_path, capsys):
    data = tmp_path / "data"
    _metrics(data / "tiny" / "contacts", {"contact_error_median_m": 0.0197})
    _metrics(
        data / "tiny" / "retarget", {"hand_contact_residual_max_m": 0.0, "unreachable_contacts": 0}
    )
    _metrics(data / "tiny" / "solve", {"status": "Solve_Succeeded", "iterations": 86})
    _metrics(
        data / "tiny" / "evaluate",
        {"avg_penetration_m": 4e-4, "success": False, "failed_checks": ["max_penetration"]},
    )
    _metrics(data / "s1" / "contacts", {"contact_error_median_m": 0.027})
    replay = {"rmse_ee_pos_m": [0.0037, 0.0033, 0.0061], "rmse_ee_vel_mps": [0.01, 0.01, 0.02]}
    replay |= {"bottle_final_error_m": 0.0037, "success": True}
    _metrics(data / "mm" / "hqp_replay", {"replica": replay})
    assert main(["--data", str(data)]) == 0
    out = capsys.readouterr().out
    tiny = next(line for line in out.splitlines() if line.startswith("tiny"))
    assert "2.0 cm" in tiny and "Solve_Succeeded" in tiny and "0.40 mm" in tiny
    assert tiny.rstrip().endswith("max_penetration")
    s1 = next(line for line in out.splitlines() if line.startswith("s1"))
    assert "2.7 cm" in s1 and s1.split()[3] == "-"  # scenario, 2.7, cm, then no retarget
    assert "0.37, 0.33, 0.61" in out and "3.7" in out


def test_no_data_folder_is_a_message(tmp_path, capsys):
    assert main(["--data", str(tmp_path / "none")]) == 2
    assert "make run" in capsys.readouterr().err


def test_the_readmes_results_tables_are_the_files_they_cite(repo):
    """The README's two tables are generated from the metrics and grids they link to; after
    a change to any of those files, `python -m locoman.results --update-readme`."""
    readme = (repo / "README.md").read_text()
    assert readme_section(readme) == readme_tables(repo)


def test_the_readme_links_only_canonical_result_folders(repo):
    section = readme_section((repo / "README.md").read_text())
    for target in re.findall(r"\]\(([^)]+)\)", section):
        assert (repo / target).exists(), target
        if target.startswith("benchmarks/results/") and target.endswith("/"):
            assert (repo / target / "provenance.json").is_file(), target


def _paired(a_wins: int, paired: int, median: float, interval: list[float]) -> dict:
    return {
        "a_wins": a_wins,
        "paired": paired,
        "median_difference": median,
        "interval": interval,
        "cells": paired,
    }


def test_a_claims_cell_says_the_verdict_and_the_numbers_behind_it():
    few = {"claims": {"vb_contact_transfer": None}, "vb": {
        "penetration_ours_vs_geometry_unaware": _paired(2, 2, -0.065, [-0.07, -0.05])}}  # fmt: skip
    assert claim_text("vb_contact_transfer", "vb", few) == (
        "undecided (ours lower in 2 of 2 cells; < 5 pairs)"
    )
    many = {"claims": {"fig6_penetration": False}, "fig6": {
        "penetration_all_vs_none": _paired(0, 6, 0.0413, [0.0124, 0.0681])}}  # fmt: skip
    assert claim_text("fig6_penetration", "fig6", many) == (
        "NOT reproduced (AllKeyframe lower in 0 of 6; median +41.3 mm, [+12.4, +68.1])"
    )
    rates = {"all": 1.0, "none": 2 / 3}
    conv = {"claims": {"fig6_convergence": True}, "fig6": {"cells": 6, "converged_rate": rates}}
    assert claim_text("fig6_convergence", "fig6", conv) == "yes (AllKeyframe 6/6, NoKeyframe 4/6)"
    runs = {"ours": {"status": "converged", "avg_penetration_m": 0.0}}
    runs["naive"] = {"status": "not_converged", "avg_penetration_m": 0.0529}
    fig5 = {"claims": {"fig5_minimal_set": True}, "fig5": runs}
    assert claim_text("fig5_minimal_set", "fig5", fig5) == (
        "reproduced (ours converged, 0.0 mm; naive not_converged, 52.9 mm)"
    )


def test_update_readme_writes_between_the_markers_only(repo, tmp_path):
    readme = tmp_path / "README.md"
    readme.write_text(f"# x\n\nbefore\n\n{BEGIN}\nold\n{END}\n\nafter\n")
    assert update_readme(readme, repo)
    text = readme.read_text()
    assert text.startswith("# x\n\nbefore\n\n") and text.endswith(f"{END}\n\nafter\n")
    assert readme_section(text) == readme_tables(repo)
    assert not update_readme(readme, repo)


def test_the_execution_row_says_whether_the_g1_carried_it_out(tmp_path):
    assert execution_cell(tmp_path, "tiny") == "not run"
    folder = tmp_path / "tiny" / "execute"
    folder.mkdir(parents=True)
    link = "([execute](data/tiny/execute/))"
    for failed, up, error, cell in (
        (["completed", "stayed_up", "object_goal"], 1.2, 0.98, "no: fell at 1.2 of 6.2 s"),
        (["object_goal"], 6.24, 1.09, "no: up throughout; box 109 cm from its goal"),
    ):
        metrics = {
            "success": False,
            "failed_checks": failed,
            "time_up_s": up,
            "duration_s": 6.24,
            "box_goal_error_m": error,
        }
        (folder / "metrics.json").write_text(json.dumps(metrics))
        assert execution_cell(tmp_path, "tiny") == f"{cell} {link}"
    carried = {"success": True, "failed_checks": [], "box_goal_error_m": 0.031}
    (folder / "metrics.json").write_text(json.dumps(carried))
    assert execution_cell(tmp_path, "tiny") == (
        "yes; objects within 3.1 cm of their goals ([execute](data/tiny/execute/))"
    )
