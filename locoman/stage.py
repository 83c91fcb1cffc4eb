"""Helpers shared by the thin entry points in ``stages/``."""

from __future__ import annotations

import inspect
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
    """Run a stage; bad arguments or a :class:`LocomanError` end it with a message and exit 2."""
    try:
        inspect.signature(main).bind(*argv)
    except TypeError as exc:
        doc = (sys.modules[main.__module__].__doc__ or "").strip()
        print(f"{doc}\n\nbad arguments {argv}: {exc}", file=sys.stderr)
        sys.exit(2)
    try:
        main(*argv)
    except LocomanError as exc:
        print(f"locoman: {type(exc).__name__}: {exc}", file=sys.stderr)
        sys.exit(2)
