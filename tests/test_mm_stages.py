"""Paper B's branch through its stages, as ``dvc repro`` runs them: the demos, the KMP fit
(``stages/kmp_fit.py``: the GMR reference and each case adapted to its via points) and the
1 kHz HQP replay in MuJoCo (``stages/hqp_replay.py``: ``replay_metrics``, ``write_replay``)."""

from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

from locoman.artifacts import read_npz
from locoman.config import load_params
from locoman.kmp.io import REFERENCE


@pytest.fixture(scope="module")
def branch_b(repo, workdir, run_cli):
    scenario = load_params(workdir / "params.yaml").demos.scenario
    # The demos stage depends on the recorded demos' folder, an input the copy leaves out
    # with the rest of data/.
    recorded = Path("data") / scenario / "recorded"
    shutil.copytree(repo / recorded, workdir / recorded)
    result = run_cli([sys.executable, "-m", "dvc", "repro", "hqp_replay"], workdir)
    assert result.returncode == 0, result.stderr
    return workdir / "data" / scenario


def test_the_kmp_fit_passes_through_each_cases_via_points(branch_b, workdir):
    cfg = load_params(workdir / "params.yaml")
    metrics = json.loads((branch_b / "kmp_fit" / "metrics.json").read_text())
    assert metrics["success"] and metrics["failed_checks"] == []
    assert set(metrics["cases"]) == set(cfg.kmp.cases)
    for name in cfg.kmp.cases:
        ref = read_npz(branch_b / "kmp_fit" / f"reference_{name}.npz", REFERENCE)
        assert len(ref["via_time_s"]) == len(cfg.kmp.cases[name].via_points)
        outputs = np.c_[ref["wrist_pos"], ref["wrist_vel"], ref["pelvis"]]
        for t, mean in zip(ref["via_time_s"], ref["via_mean"], strict=True):
            k = int(np.argmin(np.abs(ref["time_s"] - t)))
            np.testing.assert_allclose(
                outputs[k, 0:3], mean[0:3], atol=cfg.kmp.via_point_error_max_m
            )
        assert np.allclose(np.diff(ref["time_s"]), 1.0 / cfg.kmp.rate_hz)
        assert (branch_b / "kmp_fit" / f"reference_{name}.png").stat().st_size > 0


def test_the_replay_carries_the_bottle_within_the_bounds(branch_b, workdir):
    cfg = load_params(workdir / "params.yaml")
    metrics = json.loads((branch_b / "hqp_replay" / "metrics.json").read_text())
    assert set(metrics) == set(cfg.kmp.cases)
    for name, case in metrics.items():
        assert case["success"] and case["failed_checks"] == [], (name, case)
        assert case["bottle_final_error_m"] <= cfg.hqp.success_tolerance_m
        assert case["bottle_lift_m"] > 0.02  # lifted, not pushed along the table
        assert max(case["bound_violation_max"].values()) < 1e-9  # (7)-(9)
        assert case["level1_residual_max"] < 1e-4  # the end-effector task, level 1
        for suffix in (".npz", ".mcap", ".mp4"):
            assert (branch_b / "hqp_replay" / f"replay_{name}{suffix}").stat().st_size > 0
        assert name in (branch_b / "hqp_replay" / "results.md").read_text()
