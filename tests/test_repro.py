"""`make run`'s arms (locoman/repro.py): a lost DVC lock race starts the arm again, a failed
stage does not."""

from __future__ import annotations

import re
import shlex
import subprocess
import sys
from pathlib import Path

from locoman.repro import lock_failure, run_arm

ROOT = Path(__file__).resolve().parents[1]


def _script(tmp_path, body: str) -> list[str]:
    path = tmp_path / "fake_dvc.py"
    path.write_text(body)
    return [sys.executable, str(path)]


def test_lock_failure_tells_a_lock_race_from_a_failed_stage():
    assert lock_failure("ERROR: Unable to acquire lock. Most likely another DVC process")
    assert lock_failure(
        "ERROR: failed to reproduce 'validate': 'x.json' is busy, it is being blocked by:"
    )
    assert not lock_failure(
        "ERROR: failed to reproduce 'solve@tiny': failed to run: python stages/solve.py"
    )


def test_an_arm_that_loses_a_lock_race_starts_again(tmp_path, capsys):
    counter = tmp_path / "count"
    command = _script(
        tmp_path,
        f"""import pathlib, sys
p = pathlib.Path({str(counter)!r})
n = int(p.read_text()) if p.exists() else 0
p.write_text(str(n + 1))
if n < 2:
    print("ERROR: Unable to acquire lock.")
    sys.exit(255)
print("Running stage 'x'")
""",
    )
    assert run_arm(command, "arm 1", backoff_s=0.0) == 0
    assert counter.read_text() == "3"
    out = capsys.readouterr().out
    assert "[arm 1] Running stage 'x'" in out
    assert out.count("lost a DVC lock race") == 2


def test_an_arm_whose_stage_fails_is_not_started_again(tmp_path):
    counter = tmp_path / "count"
    command = _script(
        tmp_path,
        f"""import pathlib, sys
p = pathlib.Path({str(counter)!r})
p.write_text(str(int(p.read_text()) + 1 if p.exists() else 1))
print("ERROR: failed to reproduce 'solve@tiny'")
sys.exit(1)
""",
    )
    assert run_arm(command, "arm 1", backoff_s=0.0) == 1
    assert counter.read_text() == "1"


def test_an_arm_that_keeps_losing_gives_up(tmp_path):
    command = _script(tmp_path, 'print("Unable to acquire lock"); raise SystemExit(255)\n')
    assert run_arm(command, "arm 1", attempts=3, backoff_s=0.0) == 255


def _make_run_plan() -> tuple[list[str], list[list[str]]]:
    """The stages `make run` names: its serial head and its arms, from `make -n run`."""
    lines = subprocess.run(
        ["make", "-n", "run"], cwd=ROOT, capture_output=True, text=True, check=True
    ).stdout.splitlines()
    head = next(line for line in lines if "dvc repro -s" in line).split("-s", 1)[1].split()
    arms = next(line for line in lines if "-m locoman.repro" in line)
    return head, [arm.split() for arm in shlex.split(arms)[3:]]


def _dvc(*args: str) -> str:
    dvc = Path(sys.executable).with_name("dvc")
    return subprocess.run([dvc, *args], cwd=ROOT, capture_output=True, text=True, check=True).stdout


def test_make_run_runs_every_stage_once_after_its_upstream():
    """The head and the arms cover the pipeline, no stage on two arms (they would fight over
    its lock), and each stage after the stages it reads, in the head or earlier in its arm."""
    head, arms = _make_run_plan()
    stages = set(_dvc("stage", "list", "--name-only").split())
    named = head + [s for arm in arms for s in arm]
    assert sorted(named) == sorted(stages)
    edges = re.findall(r'"([^"]+)" -> "([^"]+)"', _dvc("dag", "--dot"))
    for arm in arms:
        for upstream, stage in edges:
            if stage in arm:
                before = head + arm[: arm.index(stage)]
                assert upstream in before, f"{stage} runs before {upstream}, which it reads"
    for upstream, stage in edges:
        if stage in head:
            assert head.index(upstream) < head.index(stage)
