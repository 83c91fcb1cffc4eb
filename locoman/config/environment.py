"""Whether the running Python has the packages the project pins.

The stages run with whatever interpreter ``stages/python.sh`` finds; the ``validate`` stage
checks it first, so a Python without the project's packages stops the pipeline before any
stage's outputs are removed, and one with other versions than ``requirements.lock`` pins is
named (its outputs may differ from ``dvc.lock``'s in their last bits).
"""

from __future__ import annotations

import importlib.metadata
import logging
import re
from pathlib import Path

from locoman.errors import SetupError

log = logging.getLogger(__name__)
_NAME = re.compile(r"^([A-Za-z0-9][A-Za-z0-9._-]*)")


def _canonical(name: str) -> str:
    return re.sub(r"[-_.]+", "-", name).lower()


def lock_pins(lock: Path) -> dict[str, str]:
    """``requirements.lock``'s ``name==version`` lines, by canonical name."""
    pins = {}
    for line in lock.read_text().splitlines():
        name, sep, version = line.split("#")[0].strip().partition("==")
        if sep:
            pins[_canonical(name)] = version.strip()
    return pins


def core_requirements() -> list[str]:
    """The canonical names of the packages locoman needs (its extras apart); empty where
    locoman runs from a source tree it was not installed from."""
    try:
        requires = importlib.metadata.requires("locoman") or []
    except importlib.metadata.PackageNotFoundError:
        return []
    names = [_NAME.match(r) for r in requires if "extra ==" not in r]
    return [_canonical(m.group(1)) for m in names if m]


def check_environment(lock: Path) -> list[str]:
    """The packages installed at another version than ``lock`` pins (a warning each, also
    returned).

    Raises:
        SetupError: A package locoman needs is not installed: names them and how to set up.
    """
    pins = lock_pins(lock) if lock.is_file() else {}
    missing, other = [], []
    for name in core_requirements():
        try:
            version = importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:
            missing.append(name)
            continue
        if name in pins and version != pins[name]:
            other.append(f"{name} {version} (requirements.lock: {pins[name]})")
    if missing:
        raise SetupError(
            f"this Python lacks {missing}, which locoman needs: run `make setup` and use its "
            ".venv, or `pip install -c requirements.lock -e .` in your environment"
        )
    if other:
        log.warning(
            "packages at other versions than requirements.lock pins: %s; outputs may differ "
            "from dvc.lock's in their last bits (`make setup` installs the pins)",
            ", ".join(other),
        )
    return other
