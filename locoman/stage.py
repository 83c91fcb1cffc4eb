"""Helpers shared by the thin entry points in ``stages/``."""

from __future__ import annotations

import inspect
import re
import sys
from collections.abc import Callable
from pathlib import Path

from locoman.errors import ConfigError, LocomanError

DATA_DIR = Path("data")

# A scenario's name is a folder under data/: one path component, no way out of it.
_SCENARIO_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_-]{0,63}")
SCENARIO_NAME_RULE = (
    "a scenario name is a folder of data/: 1 to 64 letters, digits, '_' or '-', "
    "starting with a letter or digit"
)


def valid_scenario_name(name: str) -> bool:
    """Whether ``name`` may name a scenario (:data:`SCENARIO_NAME_RULE`)."""
    return _SCENARIO_NAME.fullmatch(name) is not None


def stage_dir(scenario: str, stage: str) -> Path:
    """``data/<scenario>/<stage>/``, created if needed.

    Raises:
        ConfigError: If ``scenario`` is not a valid name (``../x`` would write outside
            data/); nothing is created then.
    """
    if not valid_scenario_name(scenario):
        raise ConfigError(f"scenario {scenario!r}: {SCENARIO_NAME_RULE}")
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
