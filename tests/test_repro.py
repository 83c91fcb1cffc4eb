"""`make run`'s arms (locoman/repro.py): a lost DVC lock race starts the arm again, a failed
stage does not."""

from __future__ import annotations

import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from locoman.repro import Step, lock_failure, longest, main, plan, run_arm

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


def test_each_stage_that_ran_is_timed_from_its_line_to_the_next_by_wall_clock(tmp_path):
    command = _script(
        tmp_path,
        """import time
print("Running stage 'a':", flush=True)
time.sleep(0.6)
print("Stage 'c' didn't change, skipping")
print("Running stage 'b':", flush=True)
""",
    )
    ran: list[tuple[str, float]] = []
    assert run_arm(command, "arm 1", ran=ran) == 0
    assert [stage for stage, _ in ran] == ["a", "b"]
    assert ran[0][1] >= 0.5 > ran[1][1]
    assert longest(ran, n=1) == f"a {ran[0][1] / 60:.1f} min"


def test_plan_splits_an_arm_where_another_waits_and_where_it_waits():
    arms = plan(["a b c d", "x after:b y after:d z"])
    assert arms[0] == [Step(("a", "b")), Step(("c", "d"))]
    assert arms[1] == [Step(("x",)), Step(("y",), ("b",)), Step(("z",), ("d",))]


@pytest.mark.parametrize(
    ("arms", "message"),
    [
        (["a b", "after:c d"], "'c', which no other arm runs"),
        (["a b", "c after:a"], "ends on a wait"),
    ],
)
def test_plan_refuses_a_wait_it_cannot_keep(arms, message):
    with pytest.raises(ValueError, match=message):
        plan(arms)


def _fake_dvc(tmp_path, pipeline: str, fail: str = "") -> tuple[str, Path]:
    """A `dvc` that logs each `repro`'s arguments, lists ``pipeline``'s stages, takes a while
    over `b` and fails on ``fail``."""
    log = tmp_path / "log"
    fake = tmp_path / "dvc"
    fake.write_text(
        f"""#!{sys.executable}
import sys, time
if sys.argv[1:3] == ["stage", "list"]:
    print("\\n".join({pipeline.split()!r}))
    raise SystemExit(0)
stages = sys.argv[3:]
if "b" in stages:
    time.sleep(1.5)
with open({str(log)!r}, "a") as f:
    f.write(" ".join(sys.argv[2:]) + "\\n")
raise SystemExit(1 if {fail!r} in stages else 0)
"""
    )
    fake.chmod(0o755)
    return str(fake), log


def test_an_arm_waits_for_the_other_arms_stage(tmp_path):
    """Arm 2's `y` comes after arm 1's `b`, which takes a while; every stage ran, so no
    final `dvc repro`."""
    dvc, log = _fake_dvc(tmp_path, "a b x y")
    assert main(["a b", "x after:b y"], dvc=dvc) == 0
    calls = log.read_text().splitlines()
    assert sorted(calls) == ["-s a b", "-s x", "-s y"]
    assert calls.index("-s a b") < calls.index("-s y")


@pytest.mark.parametrize(("pipeline", "fail"), [("a b x y", "x"), ("a b x y z", "")])
def test_a_failed_arm_or_an_unnamed_stage_leaves_it_to_dvc_repro(tmp_path, pipeline, fail):
    dvc, log = _fake_dvc(tmp_path, pipeline, fail)
    status = main(["a b", "x after:b y"], dvc=dvc)
    calls = log.read_text().splitlines()
    assert calls[-1] == ""  # `dvc repro`, on everything
    assert "-s y" not in calls if fail else "-s y" in calls
    assert status == 0  # the fake's `dvc repro` succeeds: it is the verdict


def _make_run_arms() -> list[str]:
    """The arms `make run` names, from `make -n run`."""
    lines = subprocess.run(
        ["make", "-n", "run"], cwd=ROOT, capture_output=True, text=True, check=True
    ).stdout.splitlines()
    line = next(line for line in lines if "-m locoman.repro" in line)
    return shlex.split(line)[3:]


def _dvc(*args: str) -> str:
    dvc = Path(sys.executable).with_name("dvc")
    return subprocess.run([dvc, *args], cwd=ROOT, capture_output=True, text=True, check=True).stdout


def _finished_before(plans: list[list[Step]]) -> dict[tuple[int, int], set[str]]:
    """For each step (arm, index): the stages sure to have run when it starts (its arm's
    earlier steps, and what the steps it waits for had behind them)."""
    where = {
        s: (a, k) for a, steps in enumerate(plans) for k, st in enumerate(steps) for s in st.stages
    }
    memo: dict[tuple[int, int], set[str]] = {}

    def before(a: int, k: int) -> set[str]:
        if (a, k) not in memo:
            out = before(a, k - 1) | set(plans[a][k - 1].stages) if k else set()
            for stage in plans[a][k].waits:
                b, j = where[stage]
                out |= before(b, j) | set(plans[b][j].stages)
            memo[(a, k)] = out
        return memo[(a, k)]

    return {(a, k): before(a, k) for a, steps in enumerate(plans) for k in range(len(steps))}


def test_make_run_runs_every_stage_once_after_its_upstream():
    """The arms cover the pipeline, no stage on two arms (they would fight over its lock),
    each stage after the stages it reads (earlier in its arm, or behind an `after:`), and
    no two arms wait for each other."""
    plans = plan(_make_run_arms())
    named = [s for steps in plans for step in steps for s in step.stages]
    stages = set(_dvc("stage", "list", "--name-only").split())
    assert sorted(named) == sorted(stages)
    edges = re.findall(r'"([^"]+)" -> "([^"]+)"', _dvc("dag", "--dot"))
    finished = _finished_before(plans)
    for (a, k), ran in finished.items():
        step = plans[a][k]
        for upstream, stage in edges:
            if stage in step.stages:
                earlier = ran | set(step.stages[: step.stages.index(stage)])
                assert upstream in earlier, f"{stage} may run before {upstream}, which it reads"
    for (a, k), ran in finished.items():  # a cycle of waits would need a step before itself
        assert not set(plans[a][k].stages) & ran
    assert (
        "solve@tiny"
        in finished[
            next(
                (a, k)
                for a, steps in enumerate(plans)
                for k, st in enumerate(steps)
                if "solve@s1_basket" in st.stages
            )
        ]
    ), "S1's solve must wait for tiny's, which compiles the G1's terms"
