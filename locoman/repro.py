"""`make run`: the pipeline's arms at once, then one `dvc repro` as the authority.

DVC runs a pipeline's stages one after the other, on one core. Its own answer to parallel
work is several `dvc repro` processes on disjoint parts of the DAG: it releases the repo lock
while a stage's command runs. Two things make that fragile, and this module handles both:

- a plain `dvc repro <target>` also asks to write the outputs of every upstream stage, even
  an unchanged one, and fails when the other arm reads them (`... is busy`); so each arm
  names its stages in order and runs them with ``-s``;
- DVC takes the repo lock at each stage's start and end for 3 s at most, then fails
  (`Unable to acquire lock`); an arm that failed so is started again (its finished stages are
  up to date and skipped).

An arm may wait for a stage of another arm: the token ``after:<stage>`` holds it until that
stage has run (or its arm has ended). It is how an arm reads what another writes (S1's scene
reads `validate`'s output) and how the scenarios' solves wait for the first one, which
compiles the robot's terms for all of them (a dependency the DAG does not show). An arm that
fails otherwise is left, and so are the waits on it: the final `dvc repro` runs what was not
run and shows the stage's own error. Where every arm ran to its end and the arms named every
stage, that `dvc repro` is left out: it would only hash every output again (20 s).

Usage: ``python -m locoman.repro "<stage> <stage> ..." "after:<stage> <stage> ..."`` (one
argument per arm).
"""

from __future__ import annotations

import dataclasses
import re
import subprocess
import sys
import threading
import time
from collections.abc import Sequence
from pathlib import Path

RUNNING = re.compile(r"Running stage '([^']+)':")
LOCK_ERRORS = ("Unable to acquire lock", "is busy, it is being blocked by")
ATTEMPTS = 5
AFTER = "after:"


def lock_failure(output: str) -> bool:
    """Whether a failed `dvc repro`'s output says it lost a lock race, not that a stage failed."""
    return any(message in output for message in LOCK_ERRORS)


def _clock(start: float) -> str:
    minutes, seconds = divmod(int(time.monotonic() - start), 60)
    return f"{minutes:02d}:{seconds:02d}"


def run_arm(
    command: Sequence[str],
    prefix: str,
    attempts: int = ATTEMPTS,
    backoff_s: float = 2.0,
    start: float | None = None,
    ran: list[tuple[str, float]] | None = None,
) -> int:
    """Run ``command`` with its output prefixed (and the minutes since ``start``, where
    given); again, up to ``attempts`` times, while it fails on a DVC lock. Each stage that
    ran, with its wall time [s] (from its `Running stage` line to the next or the end), is
    appended to ``ran``. Returns the last exit status."""
    status = 0
    for attempt in range(attempts):
        process = subprocess.Popen(
            command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, bufsize=1
        )
        lines = []
        stage, since = None, 0.0
        assert process.stdout is not None
        for line in process.stdout:
            lines.append(line)
            stamp = "" if start is None else f" {_clock(start)}"
            sys.stdout.write(f"[{prefix}{stamp}] {line}")
            sys.stdout.flush()
            running = RUNNING.match(line)
            if running:
                if stage is not None and ran is not None:
                    ran.append((stage, time.monotonic() - since))
                stage, since = running.group(1), time.monotonic()
        status = process.wait()
        if stage is not None and ran is not None:
            ran.append((stage, time.monotonic() - since))
        if status == 0 or not lock_failure("".join(lines)) or attempt == attempts - 1:
            return status
        sys.stdout.write(f"[{prefix}] lost a DVC lock race; starting again ({attempt + 2})\n")
        time.sleep(backoff_s * (attempt + 1))
    return status


def longest(ran: Sequence[tuple[str, float]], n: int = 8) -> str:
    """The ``n`` stages that took longest, as one line: ``stage 3.2 min, ...``."""
    top = sorted(ran, key=lambda item: -item[1])[:n]
    return ", ".join(f"{stage} {seconds / 60:.1f} min" for stage, seconds in top)


@dataclasses.dataclass(frozen=True)
class Step:
    """A run of an arm's stages in one `dvc repro -s`, after the stages in ``waits``."""

    stages: tuple[str, ...]
    waits: tuple[str, ...] = ()


def plan(arms: Sequence[str]) -> list[list[Step]]:
    """Each arm (stages and ``after:<stage>`` tokens, in order) as its steps: a step ends
    where another arm waits for its last stage or where the arm waits itself.

    Raises:
        ValueError: An arm waits for a stage that no other arm runs, or for nothing.
    """
    tokens = [arm.split() for arm in arms]
    waited = {t.removeprefix(AFTER) for arm in tokens for t in arm if t.startswith(AFTER)}
    owner = {t: i for i, arm in enumerate(tokens) for t in arm if not t.startswith(AFTER)}
    plans = []
    for i, arm in enumerate(tokens):
        steps: list[Step] = []
        stages: list[str] = []
        waits: list[str] = []
        for token in arm:
            if token.startswith(AFTER):
                target = token.removeprefix(AFTER)
                if owner.get(target, i) == i:
                    raise ValueError(
                        f"arm {i + 1} waits for {target!r}, which no other arm runs: name it "
                        "in the arm that runs it, or drop the wait"
                    )
                if stages:
                    steps.append(Step(tuple(stages), tuple(waits)))
                    stages, waits = [], []
                waits.append(target)
                continue
            stages.append(token)
            if token in waited:
                steps.append(Step(tuple(stages), tuple(waits)))
                stages, waits = [], []
        if waits and not stages:
            raise ValueError(f"arm {i + 1} ends on a wait ({waits}): it has nothing to run after")
        if stages:
            steps.append(Step(tuple(stages), tuple(waits)))
        plans.append(steps)
    return plans


def main(arms: Sequence[str], dvc: str = str(Path(sys.executable).with_name("dvc"))) -> int:
    """Run each arm's stages (``-s``, in order, waiting where it says ``after:``) beside the
    others (``dvc``: this environment's); then, unless every arm ran to its end and the arms
    named every stage of the pipeline, `dvc repro` on all, which runs what is left and
    shows a failed stage's own error."""
    plans = plan(arms)
    done = {s: threading.Event() for steps in plans for step in steps for s in step.stages}
    start = time.monotonic()

    failed: list[str] = []
    ran: list[tuple[str, float]] = []  # list.append is atomic: the arms share it

    def run(steps: list[Step], prefix: str) -> None:
        try:
            for step in steps:
                for stage in step.waits:
                    done[stage].wait()
                command = [dvc, "repro", "-s", *step.stages]
                if run_arm(command, prefix, start=start, ran=ran) != 0:
                    failed.append(prefix)
                    return
                for stage in step.stages:
                    done[stage].set()
        finally:  # a failed or finished arm holds nobody up
            for step in steps:
                for stage in step.stages:
                    done[stage].set()

    threads = [
        threading.Thread(target=run, args=(steps, f"arm {i}")) for i, steps in enumerate(plans, 1)
    ]
    for thread in threads:
        thread.start()
        time.sleep(1.0)  # DVC's first lock: one arm at a time
    for thread in threads:
        thread.join()
    if ran:
        print(f"[make run] the longest stages: {longest(ran)}", flush=True)
    if not failed and set(done) >= set(stages(dvc)):
        print(
            f"[make run] every arm ran to its end, in {_clock(start)}; the pipeline is up to date"
        )
        return 0
    print(f"[make run] the arms ended after {_clock(start)}; now `dvc repro` on all", flush=True)
    return subprocess.call([dvc, "repro"])


def stages(dvc: str) -> list[str]:
    """The pipeline's stages, by name (`dvc stage list`)."""
    listed = subprocess.run(
        [dvc, "stage", "list", "--name-only"], capture_output=True, text=True, check=False
    )
    return listed.stdout.split() if listed.returncode == 0 else ["(unknown)"]


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
