"""Typed configuration of the whole-body TO and its evaluation (paper A, Sec. IV and V).

Sections ``solve`` and ``evaluate``. The keyframe ablations of Sec. V-C (none, base, foot,
warm start, all) are the switches ``keyframe_base``, ``keyframe_foot`` and
``solver.warm_start``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from locoman.to.collision import CollisionCfg
from locoman.to.costs import CostWeights
from locoman.to.problem import ContactCfg
from locoman.to.schedule import ScheduleCfg
from locoman.to.trajopt import SolverCfg


@dataclass
class SolveCfg:
    """Stage ``solve``: the TO of each listed scenario.

    Attributes:
        scenarios: Humanoid scenarios the TO runs on (their plans must use the predicates
            :mod:`locoman.to.schedule` knows).
        keyframe_base: Keyframe base cost (9) on.
        keyframe_foot: Keyframe foot cost (10) on.
        schedule: Node counts of the contact schedule.
        contact: Contact parameters.
        collision: Collision terms (Sec. IV-D).
        weights: Table I, (9), (10) and the object goal.
        solver: IPOPT, the time grid and the warm start.
        cache_dir: Where compiled derivatives are kept between runs.
    """

    scenarios: list[str] = field(default_factory=lambda: ["tiny"])
    keyframe_base: bool = True
    keyframe_foot: bool = True
    schedule: ScheduleCfg = field(default_factory=ScheduleCfg)
    contact: ContactCfg = field(default_factory=ContactCfg)
    collision: CollisionCfg = field(default_factory=CollisionCfg)
    weights: CostWeights = field(default_factory=CostWeights)
    solver: SolverCfg = field(default_factory=SolverCfg)
    cache_dir: str = ".cache/casadi"


@dataclass
class EvaluateCfg:
    """Stage ``evaluate``: the MuJoCo replay and the independent checks.

    Attributes:
        dynamics_tol: Largest residual of (1) that counts as physically consistent
            [kg m/s, kg m^2/s, m].
        friction_tol: Largest violation of (3) allowed [N, N m].
        slip_tol_m: Largest stance-foot slip allowed [m].
        penetration_tol_m: Largest average penetration allowed [m].
        goal_tol_m: Largest distance of the object from its target [m].
        filmstrip_frames: Frames in the PNG filmstrip.
    """

    dynamics_tol: float = 1e-6
    friction_tol: float = 1e-6
    slip_tol_m: float = 1e-3
    penetration_tol_m: float = 0.01
    goal_tol_m: float = 0.02
    filmstrip_frames: int = 8

    def check(self) -> list[tuple[str, str]]:
        tols = (self.dynamics_tol, self.friction_tol, self.slip_tol_m, self.penetration_tol_m)
        errors = []
        if min(*tols, self.goal_tol_m) <= 0.0:
            errors.append(("dynamics_tol", "tolerances must be > 0"))
        if self.filmstrip_frames < 1:
            errors.append(("filmstrip_frames", "must be >= 1"))
        return errors
