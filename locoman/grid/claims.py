"""Whether our grids reproduce paper A's qualitative claims (Sec. V), from the records.

Each claim is checked as stated, with the evaluation's own penetration bounds for
"collision-free". V-B and V-C's penetration are decided on paired cells of a grid
(:mod:`locoman.grid.paired`); a claim that the records cannot decide (a run missing or
errored, too few pairs, an interval that holds 0) is ``None``, never counted as reproduced.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any

from locoman.config.to import EvaluateCfg
from locoman.grid.paired import PairedComparison, paired_comparison
from locoman.grid.runs import FIGURE_RUNS

# Two average penetrations closer than this are the same for a claim [m]: a standing G1's
# soles alone sink about 0.4 mm on average into MuJoCo's floor, and settings differ by
# tenths of a millimetre there without a body passing through anything.
RESOLUTION_M = 5e-4


def _less(a: float, b: float) -> bool | None:
    """a < b by more than :data:`RESOLUTION_M`; None when they are within it."""
    if abs(a - b) <= RESOLUTION_M:
        return None
    return a < b


@dataclasses.dataclass(frozen=True)
class Claim:
    """One of the paper's claims and what our records say.

    Attributes:
        key: Short name (the metrics' key).
        paper: The claim, in the paper's words.
        holds: True (reproduced), False (not), None (the records cannot tell).
        evidence: Our numbers.
    """

    key: str
    paper: str
    holds: bool | None
    evidence: str


def _pen(record: dict[str, Any] | None) -> float | None:
    if record is None or record["status"] == "error":
        return None
    return record.get("avg_penetration_m")


# The evaluation's checks of the classes beside paper A's headline: a hand deep inside the
# box it holds (naive contacts put it there) is a robot-object collision all the same.
CLASS_CHECKS = ("scheduled_contact_penetration", "object_penetration")


def collision_free(record: dict[str, Any], cfg: EvaluateCfg) -> bool:
    """The evaluation's penetration checks: average and deepest penetration within bounds,
    and no scheduled contact or object deeper than its own bound."""
    return (
        record["avg_penetration_m"] <= cfg.penetration_tol_m
        and record["max_penetration_m"] <= cfg.max_penetration_tol_m
        and not set(CLASS_CHECKS) & set(record.get("failed_checks", ()))
    )


def _describe(record: dict[str, Any] | None) -> str:
    if record is None:
        return "not run"
    if record["status"] == "error":
        return f"error ({record['reason']})"
    failed = [c for c in CLASS_CHECKS if c in record.get("failed_checks", ())]
    return (
        f"{record['status']}, average {record['avg_penetration_m'] * 1000:.1f} mm, deepest "
        f"{record['max_penetration_m'] * 1000:.1f} mm"
        + (f", failed {' and '.join(failed)}" if failed else "")
    )


def fig5_claims(records: dict[str, dict[str, Any]], cfg: EvaluateCfg) -> list[Claim]:
    """Sec. V-A, from Fig. 5's runs (run name -> record). Its V-B panel is one cell: V-B is
    decided over the grid (:func:`vb_claims`)."""
    ours, naive = records.get("ours"), records.get("naive")
    free = None
    if _pen(ours) is not None and _pen(naive) is not None:
        free = collision_free(ours, cfg) and not collision_free(naive, cfg)
    bounds = (
        f"collision-free: average <= {cfg.penetration_tol_m * 1000:g} mm, deepest <= "
        f"{cfg.max_penetration_tol_m * 1000:g} mm, scheduled contacts <= "
        f"{cfg.scheduled_contact_tol_m * 1000:g} mm, objects <= "
        f"{cfg.object_penetration_tol_m * 1000:g} mm"
    )
    return [
        Claim(
            "fig5_minimal_set",
            "with the minimal collision penalties, ours stays collision-free while the naive "
            "approach penetrates",
            free,
            f"ours: {_describe(ours)}; naive: {_describe(naive)} ({bounds})",
        ),
    ]


def _labels(figure: str) -> dict[str, str]:
    return {r.name: r.label for r in FIGURE_RUNS[figure]}


def vb_comparison(records: Sequence[dict[str, Any]]) -> PairedComparison:
    """Sec. V-B over the grid: ours against the geometry-unaware contacts, no collision
    terms, paper A's penetration paired by cell."""
    return paired_comparison(
        records, "ours_no_collision", "geometry_unaware", "avg_penetration_m", RESOLUTION_M
    )


def vb_claims(records: Sequence[dict[str, Any]]) -> list[Claim]:
    """Sec. V-B, decided on the paired cells of the ``vb`` grid."""
    comparison = vb_comparison(records)
    return [
        Claim(
            "vb_contact_transfer",
            "with no collision terms, geometry-unaware contacts penetrate more than ours",
            comparison.a_lower,
            comparison.describe(_labels("vb")),
        )
    ]


def fig6_comparison(records: Sequence[dict[str, Any]]) -> PairedComparison:
    """Sec. V-C: AllKeyframe against NoKeyframe, paper A's penetration paired by cell."""
    return paired_comparison(records, "all", "none", "avg_penetration_m", RESOLUTION_M)


def fig6_claims(records: Sequence[dict[str, Any]], figure: str = "fig6") -> list[Claim]:
    """Sec. V-C: AllKeyframe against NoKeyframe over the grid's cells of ``figure``
    (``fig6``, or ``fig6_paper``: in paper A's settings)."""
    setting = " (paper A's settings)" if figure == "fig6_paper" else ""
    texts = {
        f"{figure}_convergence": f"AllKeyframe converges at least as often as NoKeyframe{setting}",
        f"{figure}_penetration": f"AllKeyframe gives lower penetration than NoKeyframe{setting}",
    }
    ran = {r["run"] for r in records}
    absent = [
        label for name, label in (("all", "AllKeyframe"), ("none", "NoKeyframe")) if name not in ran
    ]
    if absent:
        # A draw of other settings (--runs warm all) says nothing of a run it does not hold.
        why = f"{' and '.join(absent)} not in this grid's records"
        return [Claim(key, text, None, why) for key, text in texts.items()]
    comparison = fig6_comparison(records)
    cells, converged = comparison.cells, comparison.converged
    return [
        Claim(
            f"{figure}_convergence",
            texts[f"{figure}_convergence"],
            # Neither converging anywhere is no evidence either way.
            converged["all"] >= converged["none"] if converged["all"] + converged["none"] else None,
            f"converged cells: AllKeyframe {converged['all']}/{cells}, NoKeyframe "
            f"{converged['none']}/{cells}",
        ),
        Claim(
            f"{figure}_penetration",
            texts[f"{figure}_penetration"],
            comparison.a_lower,
            comparison.describe(_labels(figure)),
        ),
    ]


def claims_markdown(claims: Sequence[Claim]) -> str:
    """A list: reproduced / NOT reproduced / undecided, the claim, our numbers."""
    word = {True: "reproduced", False: "NOT reproduced", None: "undecided"}
    return "".join(f"- **{word[c.holds]}**: {c.paper}. {c.evidence}.\n" for c in claims)
