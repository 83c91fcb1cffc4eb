"""A stage's outputs appear whole or not at all, and every stage ends with one line."""

from __future__ import annotations

import json
import os

import pytest

from locoman import stage
from locoman.errors import ArtifactError


@pytest.fixture()
def data(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(stage, "DATA_DIR", tmp_path / "data")
    final = tmp_path / "data" / "demo" / "solve"
    final.mkdir(parents=True)
    (final / "trajectory.npz").write_text("old trajectory")
    (final / "metrics.json").write_text('{"success": true}')
    (final / ".gitignore").write_text("/trajectory.npz\n")
    return final


def test_a_failed_stage_leaves_the_previous_outputs_as_they_were(data, capsys):
    def main(outputs, scenario):
        out = outputs.folder(scenario, "solve")
        (out / "trajectory.npz").write_text("half of a new trajectory")
        raise ArtifactError("the contacts of subtask 2 lack left_hand")

    with pytest.raises(SystemExit) as exit_:
        stage.run_stage(main, ["demo"])
    assert exit_.value.code == 2
    assert (data / "trajectory.npz").read_text() == "old trajectory"
    assert sorted(p.name for p in data.parent.iterdir()) == ["solve"]  # no staging left
    assert "left as they were" in capsys.readouterr().err


def test_a_crash_leaves_the_previous_outputs_too(data):
    def main(outputs, scenario):
        (outputs.folder(scenario, "solve") / "metrics.json").write_text("{")
        raise KeyError("a bug")

    with pytest.raises(KeyError):
        stage.run_stage(main, ["demo"])
    assert json.loads((data / "metrics.json").read_text()) == {"success": True}


def test_a_stage_that_succeeds_leaves_exactly_its_new_outputs(data, capsys):
    def main(outputs, scenario):
        out = outputs.folder(scenario, "solve")
        (out / "plots").mkdir()
        (out / "plots" / "penetration.csv").write_text("node,m\n")
        (out / "metrics.json").write_text('{"success": false, "status": "Maximum_Iterations"}')
        return out

    stage.run_stage(main, ["demo"])
    files = sorted(str(p.relative_to(data)) for p in data.rglob("*") if p.is_file())
    assert files == [".gitignore", "metrics.json", "plots/penetration.csv"]  # old npz gone
    line = capsys.readouterr().out.strip().splitlines()[-1]
    assert line.startswith("[test_stage_outputs demo] wrote ")
    assert "data/demo/solve/ (2 files" in line
    assert "checks FAILED: success (Maximum_Iterations)" in line


@pytest.mark.parametrize(
    ("metrics", "expected"),
    [
        ({"success": True, "failed_checks": []}, "checks passed"),
        ({"success": False, "failed_checks": ["finite", "max_penetration"]}, "(finite, max_pen"),
        ({"replica": {"success": True}, "generalisation": {"success": False}}, "generalisation"),
        ({"unreachable_contacts": 4, "self_collision_pairs": 0}, "unreachable_contacts = 4"),
        ({"n_geoms": 12}, "checks passed"),
    ],
)
def test_the_verdict_reads_every_check_of_the_metrics(metrics, expected):
    assert expected in stage.verdict(metrics)
    assert ("FAILED" in stage.verdict(metrics)) == (expected != "checks passed")


def test_the_dvc_plots_stay_small_enough_to_open(repo):
    """`dvc plots show` inlines every row of every curve into one page (it once wrote 36 MB):
    each CSV the top-level plots draw holds at most 1,000 rows."""
    import yaml

    plots = yaml.safe_load((repo / "dvc.yaml").read_text())["plots"]
    files = {f for entry in plots for spec in entry.values() for f in spec["y"]}
    assert files
    for name in files:
        rows = (repo / name).read_text().count("\n") - 1
        assert 0 < rows <= 1000, (name, rows)


def test_a_stage_runs_on_one_blas_thread_whatever_the_machine(data, monkeypatch):
    """A threaded BLAS reduction sums in an order set by the core count (the KMP fit
    differed in the 8th digit between 1 and 2 threads), so stages run on one thread."""
    import numpy  # noqa: F401  (loads OpenBLAS, the library to limit)
    from threadpoolctl import threadpool_info

    monkeypatch.setenv("OPENBLAS_NUM_THREADS", "4")
    monkeypatch.setenv("OMP_NUM_THREADS", "4")
    seen = {}

    def main(outputs, scenario):
        seen["threads"] = {i["internal_api"]: i["num_threads"] for i in threadpool_info()}
        seen["env"] = (os.environ["OPENBLAS_NUM_THREADS"], os.environ["OMP_NUM_THREADS"])
        return outputs.folder(scenario, "solve")

    stage.run_stage(main, ["demo"])
    assert seen["env"] == ("1", "1")
    assert seen["threads"] and set(seen["threads"].values()) == {1}


RACER = """
import sys, time
from locoman import stage

def main(outputs, scenario):
    out = outputs.folder(scenario, "contacts")
    for i in range(9):
        (out / f"subtask_{i}.npz").write_text(sys.argv[1] * 1000)
        time.sleep(0.05)
    (out / "metrics.json").write_text('{"success": true}')
    return out

stage.run_stage(main, ["demo"])
"""


def test_two_runs_of_a_stage_at_once_leave_one_whole_output(tmp_path):
    """Issue 53: two `stages/contacts.py tiny` at once both said "checks passed" and left 7
    of 9 files: each deleted the other's staging folder. Now each stages into its own and
    commits under the output folder's lock."""
    import subprocess
    import sys

    script = tmp_path / "racer.py"
    script.write_text(RACER)
    runs = [
        subprocess.Popen([sys.executable, str(script), tag], cwd=tmp_path, stdout=subprocess.PIPE)
        for tag in ("a", "b")
    ]
    outs = [run.communicate(timeout=120)[0].decode() for run in runs]
    assert all(run.returncode == 0 for run in runs) and all("checks passed" in o for o in outs)
    final = tmp_path / "data" / "demo" / "contacts"
    files = sorted(p.name for p in final.iterdir())
    assert files == ["metrics.json"] + [f"subtask_{i}.npz" for i in range(9)]
    tags = {(final / f"subtask_{i}.npz").read_text()[0] for i in range(9)}
    assert len(tags) == 1  # every file from the same run
    assert not list(final.parent.glob(".contacts.*.*"))  # no staging, no old folder left


def test_dvcs_gitignore_files_stay_at_every_depth(data):
    """The folder swap lost ``plots/.gitignore`` (DVC's, for a cached plot): a dotfile of the
    old folder comes along wherever the new one has its folder."""
    (data / "plots").mkdir()
    (data / "plots" / ".gitignore").write_text("/filmstrip.png\n")

    def main(outputs, scenario):
        out = outputs.folder(scenario, "solve")
        (out / "plots").mkdir()
        (out / "plots" / "filmstrip.png").write_text("png")
        return out

    stage.run_stage(main, ["demo"])
    assert (data / ".gitignore").read_text() == "/trajectory.npz\n"
    assert (data / "plots" / ".gitignore").read_text() == "/filmstrip.png\n"
