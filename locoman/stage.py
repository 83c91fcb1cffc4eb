"""Helpers shared by the thin entry points in ``stages/``."""

from __future__ import annotations

import sys
from collections.abc import Callable
from pathlib import Path

from locoman.errors import LocomanError

DATA_DIR = Path("data")


def stage_dir(scenario: str, stage: str) -> Path:
    """``data/<scenario>/<stage>/``, created if needed."""
    path = DATA_DIR / scenario / stage
    path.mkdir(parents=True, exist_ok=True)
    return path


def run_stage(main: Callable[..., None], argv: list[str]) -> None:
    """Run a stage; a :class:`LocomanError` ends it with its message and exit code 2."""
    try:
        main(*argv)
    except LocomanError as exc:
        print(f"locoman: {type(exc).__name__}: {exc}", file=sys.stderr)
        sys.exit(2)
    except TypeError as exc:
        if "positional argument" in str(exc):
            print(f"usage: {main.__module__} {main.__doc__ or ''}: {exc}", file=sys.stderr)
            sys.exit(2)
        raise
