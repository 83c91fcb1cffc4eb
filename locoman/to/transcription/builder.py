"""Collects the calls of each term kind across the transcription's sections, then hands
out one block per kind (:class:`BlockBuilder`)."""

from __future__ import annotations

import numpy as np

from locoman.to.terms.term import Block, Calls, RowSpace, TermKind


class BlockBuilder:
    """Collects the calls of every kind, then hands out their blocks."""

    def __init__(self) -> None:
        self.rows = RowSpace()
        self.blocks: list[Block] = []
        self._calls: dict[str, Calls] = {}
        self._targets: dict[str, list[np.ndarray]] = {}

    def calls(self, kind: TermKind) -> Calls:
        return self._calls.setdefault(kind.name, Calls(kind))

    def own(self, kind: TermKind) -> Calls:
        """Calls whose rows are their own (flushed by :meth:`close`)."""
        return self.calls(kind)

    def onto(self, kind: TermKind, x: dict, p: dict, target: np.ndarray) -> None:
        """A call whose rows add to existing ``target`` rows."""
        key = f"onto:{kind.name}"
        calls = self._calls.setdefault(key, Calls(kind))
        calls.add(x, p)
        self._targets.setdefault(key, []).append(np.asarray(target))

    def define(self, kind: TermKind) -> None:
        """The calls of ``kind`` so far define virtual variables (:attr:`Block.defines`)."""
        calls = self._calls.pop(kind.name, None)
        if calls is not None and len(calls):
            x, p = calls.arrays()
            self.blocks.append(Block(kind.term, x, p, np.zeros((len(x), 0), int), defines=True))

    def flush_owned(self, kind: TermKind) -> np.ndarray:
        """The rows of the calls of ``kind`` so far, as one block (n, ng); the kind's calls
        start afresh."""
        calls = self._calls.pop(kind.name)
        block = calls.own(self.rows)
        self.blocks.append(block)
        return block.rows

    def close(self) -> list[Block]:
        for key, calls in self._calls.items():
            if not len(calls):
                continue
            if key.startswith("onto:"):
                self.blocks.append(calls.onto(self._targets[key]))
            elif calls.kind.term.ng:
                self.blocks.append(calls.own(self.rows))
            else:
                self.blocks.append(calls.costs())
        self._calls.clear()
        return self.blocks
