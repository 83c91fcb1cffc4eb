"""Cell slots: grids launched side by side on one machine share its workers.

A figure's grid is one Hydra multirun, and a figures stage runs several (Fig. 5, Fig. 6,
V-B). Run one after the other, each grid's last cells leave workers idle: `tiny`'s Fig. 5
waits minutes on its naive run with one core unused. Run side by side, each with
``figures.n_jobs`` workers, they would oversubscribe the cores. So each job first takes
one of ``n`` slots, an exclusive lock on a file in a folder that the grids share, and holds
it while its cell runs. The locks are the kernel's (``flock``): a job that dies frees its
slot. A job started without the slots in its environment (by hand, on a cluster) runs at
once.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import time
from collections.abc import Iterator, Mapping
from pathlib import Path

SLOTS_ENV = "LOCOMAN_GRID_SLOTS"  # how many cells run at once
SLOT_DIR_ENV = "LOCOMAN_GRID_SLOT_DIR"  # the folder of their lock files
POLL_S = 0.2  # [s] between looks for a free slot


@contextlib.contextmanager
def slot(folder: Path, n: int, poll_s: float = POLL_S) -> Iterator[int]:
    """Hold one of ``n`` slots in ``folder``, waiting until one is free; yield its index."""
    folder.mkdir(parents=True, exist_ok=True)
    while True:
        for i in range(n):
            handle = open(folder / f"slot{i}.lock", "a")  # noqa: SIM115 (held while yielding)
            try:
                fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                handle.close()
                continue
            try:
                yield i
            finally:
                handle.close()  # releases the lock
            return
        time.sleep(poll_s)


def slots_taken(folder: Path, n: int) -> int:
    """How many of the ``n`` slots in ``folder`` a job holds now. A look takes a free slot's
    lock for an instant: a job that asks for it then finds it on its next poll."""
    taken = 0
    for i in range(n):
        path = folder / f"slot{i}.lock"
        if not path.exists():
            continue
        with open(path, "a") as handle:
            try:
                fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                taken += 1
    return taken


def slot_environment(folder: Path, n: int) -> dict[str, str]:
    """The variables that make the jobs of a launch share ``n`` slots in ``folder``."""
    return {SLOT_DIR_ENV: str(folder), SLOTS_ENV: str(n)}


@contextlib.contextmanager
def environment_slot(env: Mapping[str, str] = os.environ) -> Iterator[None]:
    """The slot that ``env`` asks for (:func:`slot_environment`), or none."""
    folder, n = env.get(SLOT_DIR_ENV), env.get(SLOTS_ENV)
    if not folder or not n:
        yield
        return
    with slot(Path(folder), int(n)):
        yield
