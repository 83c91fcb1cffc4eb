"""Typed configuration of paper A's figures (section ``figures``, stage ``figures``)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

# Hydra launcher plugins the grids are tested with (hydra/launcher=<name>).
LAUNCHERS = ("joblib", "submitit_local", "submitit_slurm", "basic")


@dataclass
class GridCfg:
    """Fig. 6's grid of one scenario: every keyframe setting at every (mass, yaw).

    Attributes:
        box_mass: Masses of the object named ``box`` [kg].
        initial_yaw: The robot's initial yaws [rad].
        axis_bound_m: Fig. 6's y-axis bound: a bar beyond it is cut and marked [m].
    """

    box_mass: list[float] = field(default_factory=lambda: [5.0])
    initial_yaw: list[float] = field(default_factory=lambda: [0.0])
    axis_bound_m: float = 0.075

    def check(self) -> list[tuple[str, str]]:
        errors = []
        if not self.box_mass or any(not m > 0.0 for m in self.box_mass):
            errors.append(("box_mass", "needs one or more masses > 0 kg"))
        if not self.initial_yaw or any(abs(y) > math.pi for y in self.initial_yaw):
            errors.append(("initial_yaw", "needs one or more yaws in [-pi, pi] rad"))
        if len(set(self.box_mass)) != len(self.box_mass) or len(set(self.initial_yaw)) != len(
            self.initial_yaw
        ):
            errors.append(("box_mass", "a mass or yaw is listed twice"))
        if not self.axis_bound_m > 0.0:
            errors.append(("axis_bound_m", "must be > 0 m"))
        return errors


@dataclass
class FiguresCfg:
    """Stage ``figures``: Fig. 5 and Fig. 6 per scenario, from grids of TO cells.

    Attributes:
        scenarios: Scenarios drawn by ``dvc repro`` (each must be a ``solve`` scenario).
        launcher: Hydra launcher plugin of the cells (:data:`LAUNCHERS`).
        n_jobs: Cells at a time with ``joblib``.
        time_limit_s: IPOPT's wall-time limit per cell [s] (its ``max_wall_time``; the
            compile and the evaluation do not count): a cell that reaches it is recorded as
            not converged (``Maximum_WallTime_Exceeded``). A safety net for runaway cells
            (S1's slowest 1000-iteration solve took 696 s here), not what decides Fig. 6's
            convergence.
        grids: Fig. 6's grid per scenario.
    """

    scenarios: list[str] = field(default_factory=lambda: ["tiny"])
    launcher: str = "joblib"
    n_jobs: int = 2
    time_limit_s: float = 1800.0
    grids: dict[str, GridCfg] = field(default_factory=dict)

    def check(self) -> list[tuple[str, str]]:
        errors = []
        if self.launcher not in LAUNCHERS:
            errors.append(("launcher", f"must be one of {list(LAUNCHERS)}"))
        if self.n_jobs < 1:
            errors.append(("n_jobs", "must be >= 1"))
        if not self.time_limit_s > 0.0:
            errors.append(("time_limit_s", "must be > 0 s"))
        errors += [
            ("scenarios", f"{name!r} has no grid under figures.grids")
            for name in self.scenarios
            if name not in self.grids
        ]
        return errors
