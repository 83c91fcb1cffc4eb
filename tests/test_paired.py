"""Issue 52: claims decided on paired grid cells, not on one cell."""

from __future__ import annotations

import numpy as np
import pytest

from locoman.grid.paired import MIN_PAIRS, bootstrap_median_interval, paired_comparison

RESOLUTION = 5e-4  # [m]


def _records(a: list[float | None], b: list[float | None]) -> list[dict]:
    """One cell per index (mass 5, yaw = index); None: that run did not converge."""
    out = []
    for k, (x, y) in enumerate(zip(a, b, strict=True)):
        for run, value in (("ours", x), ("other", y)):
            status = "converged" if value is not None else "not_converged"
            out.append(
                {
                    "box_mass": 5.0,
                    "initial_yaw": float(k),
                    "run": run,
                    "status": status,
                    "avg_penetration_m": value if value is not None else 0.5,
                }
            )
    return out


def test_lower_in_every_cell_is_decided_with_an_interval_below_zero():
    ours = [0.001, 0.002, 0.0, 0.004, 0.003, 0.001]
    other = [0.011, 0.012, 0.02, 0.009, 0.013, 0.03]
    c = paired_comparison(_records(ours, other), "ours", "other", "avg_penetration_m", RESOLUTION)
    assert (c.paired, c.a_wins, c.b_wins, c.ties) == (6, 6, 0, 0)
    assert c.interval[1] < 0.0 and c.a_lower is True
    assert c.median_difference == pytest.approx(np.median(np.subtract(ours, other)))
    assert "ours lower in 6" in c.describe({})
    reverse = paired_comparison(
        _records(other, ours), "ours", "other", "avg_penetration_m", RESOLUTION
    )
    assert reverse.a_lower is False


def test_mixed_signs_or_too_few_pairs_decide_nothing():
    mixed = paired_comparison(
        _records([0.001, 0.02, 0.001, 0.03, 0.002, 0.04], [0.01, 0.001, 0.02, 0.0, 0.03, 0.001]),
        "ours",
        "other",
        "avg_penetration_m",
        RESOLUTION,
    )
    assert mixed.interval[0] <= 0.0 <= mixed.interval[1] and mixed.a_lower is None
    few = [0.001] * (MIN_PAIRS - 1)
    c = paired_comparison(
        _records(few, [0.05] * len(few)), "ours", "other", "avg_penetration_m", RESOLUTION
    )
    assert c.interval[1] < 0.0 and c.a_lower is None  # clear, but too few cells
    assert "decide nothing" in c.describe({})


def test_only_cells_where_both_converged_are_paired():
    c = paired_comparison(
        _records([0.001, None, 0.001, 0.0002], [0.01, 0.01, None, 0.0001]),
        "ours",
        "other",
        "avg_penetration_m",
        RESOLUTION,
    )
    assert c.cells == 4 and c.converged == {"ours": 3, "other": 3}
    assert c.paired == 2 and (c.a_wins, c.ties) == (1, 1)


def test_the_bootstrap_interval_is_reproducible_and_holds_the_median():
    d = np.random.default_rng(3).normal(0.002, 0.001, 15)
    lo, hi = bootstrap_median_interval(d)
    assert (lo, hi) == bootstrap_median_interval(d)
    assert lo <= np.median(d) <= hi
    assert paired_comparison([], "a", "b", "avg_penetration_m", RESOLUTION).a_lower is None
