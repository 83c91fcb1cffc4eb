"""The runs each figure compares: registered, one per way of solving a scenario.

Paper A, Sec. V:

- Fig. 5, V-A: ours (registered contacts + keyframes) against naive (the semantic model's
  contacts alone, no keyframes), both with the scenario's minimal collision set (the
  ``solve.collision`` section); V-B: our contact transfer against the geometry-unaware one,
  the same keyframes, every collision term off.
- V-B over the grid (``vb``): the two V-B runs of Fig. 5 at every (box mass, initial yaw) of
  Fig. 6's grid, so that the claim is decided on paired cells, not on one solve.
- Fig. 6, V-C: every combination of the keyframe base cost (9), the keyframe foot cost (10)
  and the subtask-like warm start (Sec. IV-C.2), from NoKeyframe to AllKeyframe.
- Fig. 6 as the paper ran it (``fig6_paper``): the same eight settings in
  ``solve.mode: paper_a`` (Sec. V-A's minimal set alone, (14a)'s averaging, the paper's
  keyframes: :func:`locoman.config.to.scenario_solve`).

A run changes only the switches of :class:`~locoman.config.to.SolveCfg`; everything else comes
from the pipeline's parameters. "No keyframes" keeps the contact schedule, which the TO
derives from the keyframes' stances (how many steps, which foot first): the keyframes then
say when, not where or how.
"""

from __future__ import annotations

import dataclasses
import itertools

from locoman.config.to import KINDS, SolveCfg, scenario_solve
from locoman.errors import ConfigError


@dataclasses.dataclass(frozen=True)
class Run:
    """One way of solving a scenario.

    Attributes:
        name: Folder-safe key (a cell's folder starts with it).
        label: The figure's legend.
        keyframe_base: Keyframe base cost (9).
        keyframe_foot: Keyframe foot cost (10).
        warm_start: Subtask-like warm start (Sec. IV-C.2); off, every node starts at the
            initial state.
        contacts: ``registration`` or ``naive`` (a key of
            :data:`locoman.contact.io.CONTACT_FIELDS`).
        collisions: The configured collision terms; False turns every kind off.
        mode: ``solve.mode`` of the run (a key of :data:`locoman.config.to.MODES`).
    """

    name: str
    label: str
    keyframe_base: bool = True
    keyframe_foot: bool = True
    warm_start: bool = True
    contacts: str = "registration"
    collisions: bool = True
    mode: str = "product"

    def apply(self, solve: SolveCfg, scenario: str) -> SolveCfg:
        """``solve`` with this run's mode for ``scenario`` and its switches.

        Raises:
            ConfigError: The mode has no settings for ``scenario``.
        """
        solve = scenario_solve(dataclasses.replace(solve, mode=self.mode), scenario)
        collision = solve.collision
        if not self.collisions:
            collision = dataclasses.replace(collision, **dict.fromkeys(KINDS, "off"))
        return dataclasses.replace(
            solve,
            keyframe_base=self.keyframe_base,
            keyframe_foot=self.keyframe_foot,
            contacts=self.contacts,
            collision=collision,
            solver=dataclasses.replace(solve.solver, warm_start=self.warm_start),
        )


def _keyframe_runs(mode: str = "product") -> tuple[Run, ...]:
    """The 8 settings of Fig. 6, NoKeyframe first, AllKeyframe last, singles before pairs."""
    parts = (("base", "Base"), ("foot", "Foot"), ("warm", "WarmStart"))
    combos = sorted(itertools.product((False, True), repeat=3), key=lambda c: (sum(c), c[::-1]))
    runs = []
    for on in combos:
        chosen = [p for p, flag in zip(parts, on, strict=True) if flag]
        name = "_".join(p[0] for p in chosen) or "none"
        label = "+".join(p[1] for p in chosen) or "NoKeyframe"
        if all(on):
            name, label = "all", "AllKeyframe"
        runs.append(Run(name, label, on[0], on[1], on[2], mode=mode))
    return tuple(runs)


KEYFRAME_RUNS = _keyframe_runs()
PAPER_KEYFRAME_RUNS = _keyframe_runs("paper_a")

PIPELINE_RUNS = (
    Run("ours", "ours"),
    Run("naive", "naive", False, False, False, contacts="naive"),
    Run("ours_no_collision", "ours, no collision terms", collisions=False),
    Run(
        "geometry_unaware",
        "geometry-unaware contacts, no collision terms",
        contacts="naive",
        collisions=False,
    ),
)

# V-B's two arms, both without any collision term (found pairs included).
VB_RUNS = tuple(r for r in PIPELINE_RUNS if not r.collisions)

# figure -> its runs, in legend order.
FIGURE_RUNS: dict[str, tuple[Run, ...]] = {
    "fig5": PIPELINE_RUNS,
    "fig6": KEYFRAME_RUNS,
    "vb": VB_RUNS,
    "fig6_paper": PAPER_KEYFRAME_RUNS,
}


def find_run(figure: str, name: str) -> Run:
    """The run ``name`` of ``figure``.

    Raises:
        ConfigError: An unknown figure or run, with the known ones.
    """
    if figure not in FIGURE_RUNS:
        raise ConfigError(f"unknown figure {figure!r}; known: {sorted(FIGURE_RUNS)}")
    runs = {r.name: r for r in FIGURE_RUNS[figure]}
    if name not in runs:
        raise ConfigError(f"figure {figure!r} has no run {name!r}; its runs: {list(runs)}")
    return runs[name]
