"""The compact results table reads every stage's metrics; a stage not run shows '-'."""

from __future__ import annotations

import json

from locoman.results import main


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
