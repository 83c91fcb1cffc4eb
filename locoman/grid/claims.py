"""Whether our grids reproduce paper A's qualitative claims (Sec. V), from the records.

Each claim is checked as stated, with the evaluation's own penetration bounds for
"collision-free"; a claim that the records cannot decide (a run missing or errored, or two
penetrations within :data:`RESOLUTION_M`) is ``None``, never counted as reproduced.
"""

from __future__ import annotations

import dataclasses
import statistics
from collections.abc import Sequence
from typing import Any

from locoman.config.to import EvaluateCfg

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


def collision_free(record: dict[str, Any], cfg: EvaluateCfg) -> bool:
    """The evaluation's penetration checks: average and deepest penetration within bounds."""
    return (
        record["avg_penetration_m"] <= cfg.penetration_tol_m
        and record["max_penetration_m"] <= cfg.max_penetration_tol_m
    )


def _describe(record: dict[str, Any] | None) -> str:
    if record is None:
        return "not run"
    if record["status"] == "error":
        return f"error ({record['reason']})"
    return (
        f"{record['status']}, average {record['avg_penetration_m'] * 1000:.1f} mm, deepest "
        f"{record['max_penetration_m'] * 1000:.1f} mm"
    )


def fig5_claims(records: dict[str, dict[str, Any]], cfg: EvaluateCfg) -> list[Claim]:
    """Sec. V-A and V-B, from the four runs of Fig. 5 (run name -> record)."""
    ours, naive = records.get("ours"), records.get("naive")
    free = None
    if _pen(ours) is not None and _pen(naive) is not None:
        free = collision_free(ours, cfg) and not collision_free(naive, cfg)
    plain, unaware = records.get("ours_no_collision"), records.get("geometry_unaware")
    more = None
    if _pen(plain) is not None and _pen(unaware) is not None:
        more = _less(plain["avg_penetration_m"], unaware["avg_penetration_m"])
    bounds = (
        f"collision-free: average <= {cfg.penetration_tol_m * 1000:g} mm and deepest <= "
        f"{cfg.max_penetration_tol_m * 1000:g} mm"
    )
    return [
        Claim(
            "fig5_minimal_set",
            "with the minimal collision penalties, ours stays collision-free while the naive "
            "approach penetrates",
            free,
            f"ours: {_describe(ours)}; naive: {_describe(naive)} ({bounds})",
        ),
        Claim(
            "fig5_contact_transfer",
            "with no collision terms, geometry-unaware contacts penetrate more than ours",
            more,
            f"ours: {_describe(plain)}; geometry-unaware: {_describe(unaware)}",
        ),
    ]


def fig6_claims(records: Sequence[dict[str, Any]]) -> list[Claim]:
    """Sec. V-C: AllKeyframe against NoKeyframe over the grid's cells."""
    by = {(r["box_mass"], r["initial_yaw"], r["run"]): r for r in records}
    cells = sorted({(r["box_mass"], r["initial_yaw"]) for r in records})
    converged = {
        run: sum(by.get((*c, run), {}).get("status") == "converged" for c in cells)
        for run in ("none", "all")
    }
    pairs = [
        (_pen(by.get((*c, "none"))), _pen(by.get((*c, "all"))))
        for c in cells
        if _pen(by.get((*c, "none"))) is not None and _pen(by.get((*c, "all"))) is not None
    ]
    lower = None
    if pairs:
        lower = _less(statistics.fmean(a for _, a in pairs), statistics.fmean(n for n, _ in pairs))
    mean_none = statistics.fmean(n for n, _ in pairs) * 1000 if pairs else float("nan")
    mean_all = statistics.fmean(a for _, a in pairs) * 1000 if pairs else float("nan")
    return [
        Claim(
            "fig6_convergence",
            "AllKeyframe converges at least as often as NoKeyframe",
            converged["all"] >= converged["none"] if cells else None,
            f"converged cells: AllKeyframe {converged['all']}/{len(cells)}, NoKeyframe "
            f"{converged['none']}/{len(cells)}",
        ),
        Claim(
            "fig6_penetration",
            "AllKeyframe gives lower penetration than NoKeyframe",
            lower,
            f"mean average penetration over {len(pairs)} cells: AllKeyframe {mean_all:.2f} mm, "
            f"NoKeyframe {mean_none:.2f} mm (a difference within {RESOLUTION_M * 1000:g} mm "
            "decides nothing)",
        ),
    ]


def claims_markdown(claims: Sequence[Claim]) -> str:
    """A list: reproduced / NOT reproduced / undecided, the claim, our numbers."""
    word = {True: "reproduced", False: "NOT reproduced", None: "undecided"}
    return "".join(f"- **{word[c.holds]}**: {c.paper}. {c.evidence}.\n" for c in claims)
