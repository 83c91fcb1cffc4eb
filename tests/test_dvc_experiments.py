"""DVC on a cheap stage, from a copy of the working tree: caching, and experiments run in
DVC's own copies (`dvc exp run --temp`, `--queue`)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

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
    # Only `validate` runs again: it runs first on every `dvc repro` (dvc.yaml).
    ran = [ln for ln in second.stdout.splitlines() if ln.startswith("Running stage")]
    assert ran == ["Running stage 'validate':"], second.stdout


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


def test_an_objects_extents_rerun_the_scene(workdir, run_cli):
    """issue 53: with the dimensions under a key named ``size``, DVC's run cache restored the
    previous scene after they changed (treeverse/dvc#10296), through an edit of params.yaml
    and through ``dvc exp run -S`` alike."""
    import yaml

    git = ["git", "-c", "user.name=test", "-c", "user.email=test@example.com"]
    dvc = [sys.executable, "-m", "dvc"]
    params = workdir / "params.yaml"
    original = params.read_text()
    objects = workdir / "data" / "tiny" / "scene" / "objects.json"

    def box_extents() -> list[float]:
        return json.loads(objects.read_text())["objects"]["box"]["size_m"]

    assert run_cli([*dvc, "repro", "scene@tiny"], workdir).returncode == 0
    first = box_extents()
    edited = yaml.safe_load(original)
    edited["scenarios"]["tiny"]["objects"]["box"]["extents_m"][2] = first[2] + 0.05
    params.write_text(yaml.safe_dump(edited, sort_keys=False))
    run = run_cli([*dvc, "repro", "scene@tiny"], workdir)
    assert run.returncode == 0, run.stderr
    assert "Running stage 'scene@tiny'" in run.stdout, run.stdout
    assert box_extents()[2] == pytest.approx(first[2] + 0.05)

    params.write_text(original)
    assert run_cli([*git, "add", "-A"], workdir).returncode == 0
    assert run_cli([*git, "commit", "-qm", "extents", "--allow-empty"], workdir).returncode == 0
    wider = [first[0] + 0.05, first[1], first[2]]
    override = "scenarios.tiny.objects.box.extents_m=[" + ",".join(map(str, wider)) + "]"
    run = run_cli([*dvc, "exp", "run", "-S", override, "scene@tiny"], workdir)
    assert run.returncode == 0, run.stdout + run.stderr
    assert box_extents() == pytest.approx(wider)
    params.write_text(original)


def test_a_misspelt_key_fails_the_experiment_naming_it(workdir, run_cli):
    """issue 49: ``-S +scenario.box_mas=5`` changed no parameter that ``scene@tiny`` tracks, so
    DVC skipped it and the experiment succeeded with the typo recorded. The ``validate``
    stage tracks all of params.yaml and runs before every root stage."""
    git = ["git", "-c", "user.name=test", "-c", "user.email=test@example.com"]
    dvc = [sys.executable, "-m", "dvc"]
    assert run_cli([*dvc, "repro", "scene@tiny"], workdir).returncode == 0
    assert run_cli([*git, "add", "-A"], workdir).returncode == 0
    assert run_cli([*git, "commit", "-qm", "typo", "--allow-empty"], workdir).returncode == 0
    run = run_cli([*dvc, "exp", "run", "-S", "+scenario.box_mas=5", "scene@tiny"], workdir)
    assert run.returncode != 0, run.stdout + run.stderr
    assert "scenario.box_mas" in run.stdout + run.stderr
    assert "Running stage 'scene@tiny'" not in run.stdout
    # A valid change of a parameter the scene does not track reruns the check only.
    assert run_cli([*git, "checkout", "--", "params.yaml"], workdir).returncode == 0
    run = run_cli([*dvc, "exp", "run", "-S", "retarget.base_weight=11.0", "scene@tiny"], workdir)
    assert run.returncode == 0, run.stdout + run.stderr
    assert "Running stage 'validate'" in run.stdout, run.stdout
    assert "Running stage 'scene@tiny'" not in run.stdout, run.stdout
    assert run_cli([*git, "checkout", "--", "params.yaml"], workdir).returncode == 0


def test_a_scenario_added_as_one_file_runs_and_a_wrong_python_removes_nothing(workdir, run_cli):
    """A scenario is one file of conf/scenario/: `make params` lists it, `dvc repro` runs
    its scene. A Python without the project's packages stops `validate`, which runs first
    on every `dvc repro`, before DVC removes the outputs of the stage it was asked for."""
    import yaml

    dvc = [sys.executable, "-m", "dvc"]
    task = yaml.safe_load((workdir / "conf" / "scenario" / "tiny.yaml").read_text())
    task["description"] = "a user's own task"
    path = workdir / "conf" / "scenario" / "my_task.yaml"
    path.write_text(yaml.safe_dump(task))
    unlisted = run_cli([*dvc, "repro", "validate"], workdir)
    assert unlisted.returncode != 0
    assert "['my_task'], which params.yaml lacks: run `make params`" in unlisted.stderr
    assert run_cli([sys.executable, "-m", "locoman.config.compose"], workdir).returncode == 0
    ran = run_cli([*dvc, "repro", "scene@my_task"], workdir)
    assert ran.returncode == 0, ran.stdout + ran.stderr
    scene = workdir / "data" / "my_task" / "scene"
    built = {p.name: p.read_bytes() for p in scene.iterdir() if p.is_file()}
    assert "overview.png" in built and "plan.json" in built
    task["objects"]["box"]["rgba"] = [0.2, 0.6, 0.3, 1.0]  # the scene must run again
    path.write_text(yaml.safe_dump(task))
    assert run_cli([sys.executable, "-m", "locoman.config.compose"], workdir).returncode == 0
    bare = Path(sys.base_prefix) / "bin" / "python3"  # the interpreter without the venv
    wrong = run_cli([*dvc, "repro", "scene@my_task"], workdir, {"LOCOMAN_PYTHON": str(bare)})
    assert wrong.returncode != 0
    assert "cannot import locoman and its dependencies" in wrong.stdout + wrong.stderr
    assert {p.name: p.read_bytes() for p in scene.iterdir() if p.is_file()} == built
