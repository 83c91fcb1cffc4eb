"""Progress bars for the long steps: on a terminal only, so logs and CI stay quiet."""

from __future__ import annotations

import sys
from collections.abc import Iterable, Iterator
from typing import TypeVar

from tqdm import tqdm

T = TypeVar("T")


def progress(items: Iterable[T], desc: str, total: int | None = None) -> Iterator[T]:
    """``items`` with a bar on stderr named ``desc`` when stderr is a terminal; the plain
    items otherwise (a log file or CI gets the stage's one-line summary instead)."""
    if not sys.stderr.isatty():
        yield from items
        return
    yield from tqdm(items, desc=desc, total=total, leave=False, file=sys.stderr, unit="step")
