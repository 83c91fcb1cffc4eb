"""Upper bounds on the parameters that size work, with what each bound protects.

A size is checked with the configuration, before anything is allocated: ``swing_nodes:
100000`` once ran two minutes and died in ``std::bad_alloc``. Each bound sits one to two
orders of magnitude above the defaults; raise one here, with its reason, when a machine
can afford more.
"""

from __future__ import annotations


def at_most(name: str, value: float, bound: float, why: str) -> list[tuple[str, str]]:
    """``[(name, message)]`` when ``value`` exceeds ``bound``, the message saying why."""
    if value <= bound:
        return []
    return [(name, f"{value:g} is above its bound {bound:g}: {why}")]
