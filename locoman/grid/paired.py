"""Two runs compared over the cells (box mass, initial yaw) of a grid, paired by cell.

One solve of each run says little: the TO is nonconvex and two settings find different
motions. Over a grid, each cell where both runs converged gives one paired difference of a
metric (run a minus run b); the comparison reports who wins how many cells, the median
difference and a percentile-bootstrap 95 % interval of that median, and decides only when
there are at least :data:`MIN_PAIRS` pairs and the whole interval lies beyond the resolution
(a difference too small to mean anything) on one side of 0.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any

import numpy as np

MIN_PAIRS = 5  # fewer paired cells decide nothing
BOOTSTRAP_SAMPLES = 10_000
BOOTSTRAP_SEED = 0  # the interval is reproducible: same records, same interval
LEVEL = 0.95


def bootstrap_median_interval(
    differences: np.ndarray, samples: int = BOOTSTRAP_SAMPLES, seed: int = BOOTSTRAP_SEED
) -> tuple[float, float]:
    """Percentile-bootstrap :data:`LEVEL` interval of the median of ``differences``."""
    rng = np.random.default_rng(seed)
    draws = rng.choice(differences, size=(samples, len(differences)), replace=True)
    medians = np.median(draws, axis=1)
    tail = (1.0 - LEVEL) / 2.0
    return float(np.quantile(medians, tail)), float(np.quantile(medians, 1.0 - tail))


@dataclasses.dataclass(frozen=True)
class PairedComparison:
    """Run ``a`` against run ``b`` on ``metric`` over a grid's cells.

    Attributes:
        a, b: The runs' names.
        metric: The record's key compared (lower is better), e.g. ``avg_penetration_m``.
        resolution: Differences within this are ties, in the metric's unit.
        cells: Cells in the grid.
        converged: Run -> cells where it converged.
        paired: Cells where both converged (the pairs).
        a_wins, b_wins, ties: Pairs where a's metric is lower by more than the resolution,
            b's is, or neither.
        median_difference: Median of a - b over the pairs (None without pairs).
        interval: Bootstrap interval of that median (None without pairs).
    """

    a: str
    b: str
    metric: str
    resolution: float
    cells: int
    converged: dict[str, int]
    paired: int
    a_wins: int
    b_wins: int
    ties: int
    median_difference: float | None
    interval: tuple[float, float] | None

    @property
    def a_lower(self) -> bool | None:
        """a's metric lower than b's: True where the interval lies below -resolution, False
        where it lies above +resolution, over at least :data:`MIN_PAIRS` pairs; else None
        (undecided: too few pairs, an interval that holds 0, or a tie)."""
        if self.interval is None or self.paired < MIN_PAIRS:
            return None
        lo, hi = self.interval
        if hi < -self.resolution:
            return True
        if lo > self.resolution:
            return False
        return None

    def describe(self, labels: dict[str, str], scale: float = 1000.0, unit: str = "mm") -> str:
        """Our numbers, in words, for the claims list."""
        a, b = labels.get(self.a, self.a), labels.get(self.b, self.b)
        head = (
            f"converged: {a} {self.converged[self.a]}/{self.cells}, {b} "
            f"{self.converged[self.b]}/{self.cells}; over the {self.paired} cells where both "
            "converged"
        )
        if self.median_difference is None or self.interval is None:
            return f"{head}: none to compare"
        lo, hi = self.interval
        why = "" if self.paired >= MIN_PAIRS else f"; fewer than {MIN_PAIRS} pairs decide nothing"
        return (
            f"{head}, {a} lower in {self.a_wins}, {b} lower in {self.b_wins}, {self.ties} "
            f"within the resolution; median {a} - {b} {self.median_difference * scale:+.2f} "
            f"{unit}, {LEVEL:.0%} bootstrap interval [{lo * scale:+.2f}, {hi * scale:+.2f}] "
            f"{unit}{why}"
        )

    def as_dict(self) -> dict[str, Any]:
        """For ``metrics.json``."""
        return dataclasses.asdict(self) | {"a_lower": self.a_lower}


def paired_comparison(
    records: Sequence[dict[str, Any]], a: str, b: str, metric: str, resolution: float
) -> PairedComparison:
    """Compare runs ``a`` and ``b`` over the cells of ``records`` (a grid's cell records)."""
    by = {(r["box_mass"], r["initial_yaw"], r["run"]): r for r in records}
    cells = sorted({(r["box_mass"], r["initial_yaw"]) for r in records})

    def converged(cell: tuple, run: str) -> dict[str, Any] | None:
        record = by.get((*cell, run))
        ok = record is not None and record["status"] == "converged"
        return record if ok and record.get(metric) is not None else None

    pairs = [
        (ra[metric], rb[metric])
        for c in cells
        if (ra := converged(c, a)) is not None and (rb := converged(c, b)) is not None
    ]
    differences = np.array([x - y for x, y in pairs])
    return PairedComparison(
        a=a,
        b=b,
        metric=metric,
        resolution=resolution,
        cells=len(cells),
        converged={run: sum(converged(c, run) is not None for c in cells) for run in (a, b)},
        paired=len(pairs),
        a_wins=int(np.sum(differences < -resolution)),
        b_wins=int(np.sum(differences > resolution)),
        ties=int(np.sum(np.abs(differences) <= resolution)),
        median_difference=float(np.median(differences)) if pairs else None,
        interval=bootstrap_median_interval(differences) if pairs else None,
    )
