"""Typed configuration of the whole-body TO and its evaluation (paper A, Sec. IV and V).

Sections ``solve`` and ``evaluate``. The keyframe ablations of Sec. V-C (none, base, foot,
warm start, all) are the switches ``keyframe_base``, ``keyframe_foot`` and
``solver.warm_start``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from locoman.contact.io import CONTACT_FIELDS
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
        contacts: Where the hands hold the object: ``registration`` (the transferred
            contacts, Sec. III-A.2) or ``naive`` (the geometry-unaware baseline, Sec. V-B).
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
    contacts: str = "registration"
    schedule: ScheduleCfg = field(default_factory=ScheduleCfg)
    contact: ContactCfg = field(default_factory=ContactCfg)
    collision: CollisionCfg = field(default_factory=CollisionCfg)
    weights: CostWeights = field(default_factory=CostWeights)
    solver: SolverCfg = field(default_factory=SolverCfg)
    cache_dir: str = ".cache/casadi"

    def check(self) -> list[tuple[str, str]]:
        if self.contacts not in CONTACT_FIELDS:
            return [("contacts", f"must be one of {sorted(CONTACT_FIELDS)}")]
        return []


@dataclass
class EvaluateCfg:
    """Stage ``evaluate``: the MuJoCo replay and the independent checks.

    Attributes:
        dynamics_tol: Largest residual of (1) that counts as physically consistent
            [kg m/s, kg m^2/s, m].
        friction_tol: Largest violation of (3) allowed [N, N m].
        slip_tol_m: Largest stance-foot slip allowed [m].
        penetration_tol_m: Largest average penetration allowed [m].
        max_penetration_tol_m: Largest penetration at any node [m] (the average hides a
            deep one; tiny's deepest is 2.4 mm, a foot on the floor).
        goal_tol_m: Largest distance of an object from its target [m], where its subtask
            ends.
        rest_height_tol_m: At the end each object's bottom lies this close to a support's
            top face (the floor or another object's) [m].
        rest_speed_tol: ... and every rate of its (p, rpy) is at most this [m/s, rad/s].
        rest_tilt_tol_rad: ... and its roll and pitch at most this [rad].
        nonholonomic_tol_mps: Largest lateral velocity of a chassis's rear wheels, (7a)
            over each step as the TO holds it [m/s].
        rider_slip_tol_m: Largest slide of an object on the object carrying it [m].
        lift_tol_m: An object both hands hold at the end is at least this far above the
            support it was taken from (``<object>_lift_m``; S1: the basket) [m].
        filmstrip_frames: Frames in the PNG filmstrip.
    """

    dynamics_tol: float = 1e-6
    friction_tol: float = 1e-6
    slip_tol_m: float = 1e-3
    penetration_tol_m: float = 0.01
    max_penetration_tol_m: float = 0.02
    goal_tol_m: float = 0.02
    rest_height_tol_m: float = 0.01
    rest_speed_tol: float = 0.01
    rest_tilt_tol_rad: float = 0.1
    nonholonomic_tol_mps: float = 1e-4
    rider_slip_tol_m: float = 0.005
    lift_tol_m: float = 0.05
    filmstrip_frames: int = 8

    def check(self) -> list[tuple[str, str]]:
        tols = (
            "dynamics_tol",
            "friction_tol",
            "slip_tol_m",
            "penetration_tol_m",
            "max_penetration_tol_m",
            "goal_tol_m",
            "rest_height_tol_m",
            "rest_speed_tol",
            "rest_tilt_tol_rad",
            "nonholonomic_tol_mps",
            "rider_slip_tol_m",
            "lift_tol_m",
        )
        errors = [
            (name, f"must be finite and > 0, got {getattr(self, name)}")
            for name in tols
            if not (math.isfinite(getattr(self, name)) and getattr(self, name) > 0.0)
        ]
        if self.filmstrip_frames < 1:
            errors.append(("filmstrip_frames", "must be >= 1"))
        return errors
