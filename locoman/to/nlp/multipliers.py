"""IPOPT's primal-dual start (a *warm start*: x, the bound and constraint multipliers)
carried from one NLP to the next: from a solve to the next round of found pairs, or from
one grid cell to its neighbour, row by row through the blocks that own the rows."""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from locoman.to.terms.term import Block


@dataclasses.dataclass(frozen=True)
class WarmStart:
    """A primal-dual point of an NLP of the same structure to start IPOPT from: primal x,
    bound multipliers lam_x, constraint multipliers lam_g; ``rows``: which calls own its
    constraint rows (:func:`row_owners`), so that a problem with more rows can take the
    multipliers of the calls it shares (:func:`carried_multipliers`)."""

    x: np.ndarray
    lam_x: np.ndarray
    lam_g: np.ndarray
    rows: dict[tuple[str, int], Block] | None = None


def row_owners(blocks: Sequence[Block]) -> dict[tuple[str, int], Block]:
    """The blocks with constraint rows, by (term name, occurrence of that name)."""
    seen: dict[str, int] = {}
    out = {}
    for block in blocks:
        if block.defines or not block.rows.size:
            continue
        name = block.term.name
        out[(name, seen.get(name, 0))] = block
        seen[name] = seen.get(name, 0) + 1
    return out


def carried_multipliers(warm: WarmStart, blocks: Sequence[Block], n_g: int) -> WarmStart | None:
    """``warm`` for a problem of ``blocks`` with ``n_g`` rows that extends its own (a round
    of found pairs under a hard treatment adds rows): each block's first calls, where they
    are the same calls (the same numbers), take their multipliers, the new rows start at
    0. None without ``warm.rows``. Starting the new rows' multipliers at 0 keeps IPOPT's
    warm start: from the primal point alone it restarted its barrier, and S1's Base+Foot
    at 5 kg, 1.2 rad wandered through restoration to its iteration limit where the
    carried start converged (docs/trajectory-optimisation.md)."""
    if warm.rows is None:
        return None
    lam = np.zeros(n_g)
    new = row_owners(blocks)
    for key, old in warm.rows.items():
        block = new.get(key)
        if block is None:
            continue
        n = min(old.calls, block.calls)
        same = np.all(old.p[:n] == block.p[:n], axis=1)
        lam[block.rows[:n][same].ravel()] = warm.lam_g[old.rows[:n][same].ravel()]
    return WarmStart(warm.x, warm.lam_x, lam, row_owners(blocks))


# IPOPT's warm start: the point is taken as it is, pushed off the bounds by little, and the
# barrier starts small, as near an optimum it should.
WARM_START_OPTIONS = {
    "warm_start_init_point": "yes",
    "warm_start_bound_push": 1e-6,
    "warm_start_bound_frac": 1e-6,
    "warm_start_slack_bound_push": 1e-6,
    "warm_start_slack_bound_frac": 1e-6,
    "warm_start_mult_bound_push": 1e-6,
    "mu_init": 1e-4,
}
