"""`make run`: the pipeline's independent arms at once, then one `dvc repro` as the authority.

DVC runs a pipeline's stages one after the other, on one core. Its own answer to parallel
work is several `dvc repro` processes on disjoint parts of the DAG: it releases the repo lock
while a stage's command runs. Two things make that fragile, and this module handles both:

- a plain `dvc repro <target>` also asks to write the outputs of every upstream stage, even
  an unchanged one, and fails when the other arm reads them (`... is busy`); so each arm
  names its stages in order and runs them with ``-s``;
- DVC takes the repo lock at each stage's start and end for 3 s at most, then fails
  (`Unable to acquire lock`); an arm that failed so is started again (its finished stages are
  up to date and skipped).

An arm that fails otherwise is left: the final `dvc repro` runs what it did not and shows the
stage's own error.

Usage: ``python -m locoman.repro "<stage> <stage> ..." "<stage> ..."`` (one argument per arm).
"""

from __future__ import annotations

import subprocess
import sys
import threading
import time
from collections.abc import Sequence
from pathlib import Path

LOCK_ERRORS = ("Unable to acquire lock", "is busy, it is being blocked by")
ATTEMPTS = 5


def lock_failure(output: str) -> bool:
    """Whether a failed `dvc repro`'s output says it lost a lock race, not that a stage failed."""
    return any(message in output for message in LOCK_ERRORS)


def run_arm(
    command: Sequence[str], prefix: str, attempts: int = ATTEMPTS, backoff_s: float = 2.0
) -> int:
    """Run ``command`` with its output prefixed; again, up to ``attempts`` times, while it fails
    on a DVC lock. Returns its last exit status."""
    status = 0
    for attempt in range(attempts):
        process = subprocess.Popen(
            command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, bufsize=1
        )
        lines = []
        assert process.stdout is not None
        for line in process.stdout:
            lines.append(line)
            sys.stdout.write(f"[{prefix}] {line}")
            sys.stdout.flush()
        status = process.wait()
        if status == 0 or not lock_failure("".join(lines)) or attempt == attempts - 1:
            return status
        sys.stdout.write(f"[{prefix}] lost a DVC lock race; starting again ({attempt + 2})\n")
        time.sleep(backoff_s * (attempt + 1))
    return status


def main(arms: Sequence[str], dvc: str = str(Path(sys.executable).with_name("dvc"))) -> int:
    """Run each arm's stages (``-s``, in order) beside the others, then `dvc repro` on all
    (``dvc``: this environment's)."""
    threads = [
        threading.Thread(target=run_arm, args=([dvc, "repro", "-s", *arm.split()], f"arm {i}"))
        for i, arm in enumerate(arms, 1)
    ]
    for thread in threads:
        thread.start()
        time.sleep(1.0)  # DVC's first lock: one arm at a time
    for thread in threads:
        thread.join()
    return subprocess.call([dvc, "repro"])


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
