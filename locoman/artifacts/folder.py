"""An output folder replaced whole: written aside, then swapped in under a lock.

Stages (:mod:`locoman.stage`) and grid cells (:mod:`locoman.grid.cell`) write every output
into a staging folder of their own run (``.<name>.staging.<pid>`` beside the folder), and
only a run that succeeds swaps it in: the old folder is renamed away, the staging folder
renamed into place, the old one removed. A reader sees the old folder or the new one, never
a mix; a failed or killed run leaves the old one as it was. Two runs at once each have their
own staging folder and swap under the folder's lock (``.<name>.lock``), so the last one to
finish wins, whole.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import shutil
from collections.abc import Iterator
from pathlib import Path


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _remove_dead_runs(final: Path) -> None:
    """Remove the staging and old folders of ``final`` whose run is gone (a killed one's)."""
    for folder in final.parent.glob(f".{final.name}.*.*"):
        kind, pid = folder.name.rsplit(".", 2)[-2:]
        if kind in ("staging", "old") and pid.isdigit() and not _alive(int(pid)):
            shutil.rmtree(folder, ignore_errors=True)


def staging_folder(final: Path) -> Path:
    """A new, empty folder beside ``final`` for this process's run to write into."""
    final.parent.mkdir(parents=True, exist_ok=True)
    _remove_dead_runs(final)
    staging = final.with_name(f".{final.name}.staging.{os.getpid()}")
    shutil.rmtree(staging, ignore_errors=True)
    staging.mkdir()
    return staging


@contextlib.contextmanager
def locked(final: Path) -> Iterator[None]:
    """Hold ``final``'s lock (a file beside it) while the block runs."""
    final.parent.mkdir(parents=True, exist_ok=True)
    with open(final.with_name(f".{final.name}.lock"), "w") as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)


def swap_in(staging: Path, final: Path) -> None:
    """Make ``final`` the folder ``staging`` (two renames under ``final``'s lock). The old
    folder's dotfiles that ``staging`` lacks come along, at any depth where ``staging`` has
    the folder: DVC's ``.gitignore`` of the cached outputs (``plots/.gitignore`` too)
    belongs to the folder, not to a run."""
    with locked(final):
        if final.is_dir():
            for dotfile in final.rglob(".*"):
                kept = staging / dotfile.relative_to(final)
                if dotfile.is_file() and kept.parent.is_dir() and not kept.exists():
                    shutil.copy2(dotfile, kept)
        old = final.with_name(f".{final.name}.old.{os.getpid()}")
        shutil.rmtree(old, ignore_errors=True)
        if final.exists():
            final.rename(old)
        staging.rename(final)
        shutil.rmtree(old, ignore_errors=True)
