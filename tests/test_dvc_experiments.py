"""DVC on a cheap stage, from a copy of the working tree: caching, and experiments run in
DVC's own copies (`dvc exp run --temp`, `--queue`)."""

from __future__ import annotations

import json
import sys

import pytest

pytestmark = pytest.mark.slow


def test_tiny_scene_stage_runs_then_is_cached(workdir, run_cli):
    dvc = [sys.executable, "-m", "dvc"]
    first = run_cli([*dvc, "repro", "scene@tiny"], workdir)
    assert first.returncode == 0, first.stderr
    out = workdir / "data" / "tiny" / "scene"
    for name in ("scene.xml", "objects.json", "plan.json", "initial_state.npz", "overview.png"):
        assert (out / name).is_file(), name
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["max_initial_penetration_m"] <= 1e-3
    second = run_cli([*dvc, "repro", "scene@tiny"], workdir)
    assert second.returncode == 0, second.stderr
    assert "Running stage" not in second.stdout, second.stdout


def test_temporary_and_queued_experiments_run_in_dvcs_own_copies(workdir, run_cli):
    """`dvc exp run --temp` and `--queue` run in copies without the checkout's .venv: the
    scene's MJCF must load there (it once named its meshes through the .venv)."""
    git = ["git", "-c", "user.name=test", "-c", "user.email=test@example.com"]
    assert run_cli([*git, "add", "-A"], workdir).returncode == 0
    assert run_cli([*git, "commit", "-qm", "base"], workdir).returncode == 0
    dvc = [sys.executable, "-m", "dvc"]
    run = run_cli(
        [*dvc, "exp", "run", "--temp", "-S", "scenario.box_mass=2.5", "generate@tiny"], workdir
    )
    assert run.returncode == 0, run.stdout + run.stderr
    assert "Ran experiment" in run.stdout + run.stderr
    shown = run_cli([*dvc, "exp", "show", "--json"], workdir)
    assert shown.returncode == 0 and "2.5" in shown.stdout
    # A queued one runs in DVC's queue workers, in their own copies.
    queued = run_cli(
        [*dvc, "exp", "run", "--queue", "-S", "scenario.box_mass=7.5", "scene@tiny"], workdir
    )
    assert queued.returncode == 0, queued.stderr
    assert run_cli([*dvc, "exp", "run", "--run-all"], workdir).returncode == 0
    status = run_cli([*dvc, "queue", "status"], workdir)
    assert "Success" in status.stdout and "Failed" not in status.stdout, status.stdout
