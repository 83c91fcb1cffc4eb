"""Typed configuration of retargeting (paper A, Sec. III-A.3).

Section ``retarget``: the weights of the placo IK tasks, and the
margins of its constraints.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from locoman.config.cost import at_most


@dataclass
class RetargetCfg:
    """Stage ``retarget``: one G1 keyframe (35-D) per subtask.

    Attributes:
        hand_weight: Hand contact position tasks (soft, high weight) [-].
        reach_step_m: Each IK step aims a hand at most this far from where it is [m].
        base_weight: Base orientation of the human placement [-].
        posture_weight: Mapped human joint angles; low, so they only guide [-].
        fallback_posture_weight: The posture weight of a second round of starts, when no
            start meets every contact at ``posture_weight``; ``null`` (with the margin): no
            second round [-].
        fallback_collision_margin_m: The self-collision margin of that round [m].
        fallback_palm_facing_weight: That round's pull of each palm's normal into its
            contact surface [-].
        base_tilt_max_rad: A keyframe's base roll and pitch at most this, below the TO's
            bound on them (``locoman.to.solve.bounds.BASE_TILT_MAX``, short of the roll-pitch-yaw
            singularity at pi/2); a start that ends more tilted ranks after every other
            [rad].
        regularization: placo's damping of each step [-].
        foot_weight: Sole positions at the foot contacts or stances; the heaviest task, as
            near to hard as a QP whose steps are bounded allows [-].
        foot_flat_weight: Feet flat, turned like the base [-].
        stance_weight: A standing foot's pull, in the plane, towards the human's stance [-].
        com_weight: The CoM inside the support polygon, by ``com_margin_m`` (soft: a hard
            polygon can make the QP infeasible while a hand reaches) [-].
        com_margin_m: [m].
        collision_weight: Self-collision shapes at least ``collision_margin_m`` apart (soft,
            for the same reason) [-].
        collision_margin_m: [m].
        collision_trigger_m: Pairs closer than this enter the QP [m].
        reach_tolerance_m: A contact missed by more is reported as unreachable [m].
        max_contact_miss_m: A contact missed by more stops the stage: the TO would start from
            a keyframe that does not touch what its subtask acts on [m].
        start_knees_rad: Knee angles of the standing postures the IK starts from, in turn,
            until one meets every contact [rad].
        iterations: Most IK steps per start.
        step_s: Each step moves every joint by at most its velocity limit times this, so
            a far target is approached, not jumped at [s].
        tolerance: Stop when a step moves q by less than this [-].
    """

    hand_weight: float = 1e3
    foot_weight: float = 1e5
    foot_flat_weight: float = 1e4
    stance_weight: float = 10.0
    com_weight: float = 1e3
    collision_weight: float = 1e4
    reach_step_m: float = 0.01
    base_weight: float = 10.0
    posture_weight: float = 1e-2
    fallback_posture_weight: float | None = None
    fallback_collision_margin_m: float | None = None
    fallback_palm_facing_weight: float = 0.0
    base_tilt_max_rad: float = 1.4
    regularization: float = 1e-3
    com_margin_m: float = 0.02
    collision_margin_m: float = 0.005
    collision_trigger_m: float = 0.03
    reach_tolerance_m: float = 0.005
    max_contact_miss_m: float = 0.05
    start_knees_rad: list[float] = field(default_factory=lambda: [0.42, 1.2])
    iterations: int = 500
    step_s: float = 0.05
    tolerance: float = 1e-4

    def check(self) -> list[tuple[str, str]]:
        errors = []
        weights = (
            self.hand_weight,
            self.foot_weight,
            self.foot_flat_weight,
            self.stance_weight,
            self.com_weight,
            self.collision_weight,
            self.base_weight,
            self.posture_weight,
            self.regularization,
        )
        fallback = (self.fallback_posture_weight, self.fallback_collision_margin_m)
        if (fallback[0] is None) != (fallback[1] is None):
            errors.append(
                ("fallback_posture_weight", "set it and fallback_collision_margin_m, or neither")
            )
        if fallback[0] is not None:
            weights += (fallback[0], self.fallback_palm_facing_weight)
        if fallback[1] is not None and not 0.0 <= fallback[1] < self.collision_trigger_m:
            errors.append(("fallback_collision_margin_m", "must be in [0, collision_trigger_m) m"))
        if min(weights) < 0.0:
            errors.append(("hand_weight", "task weights and the regularization must be >= 0"))
        if self.max_contact_miss_m < self.reach_tolerance_m:
            errors.append(("max_contact_miss_m", "must be >= reach_tolerance_m [m]"))
        if min(self.com_margin_m, self.collision_margin_m, self.reach_tolerance_m) < 0.0:
            errors.append(("com_margin_m", "margins and tolerances must be >= 0 m"))
        if self.collision_trigger_m <= self.collision_margin_m:
            errors.append(("collision_trigger_m", "must exceed collision_margin_m"))
        if self.reach_step_m <= 0.0:
            errors.append(("reach_step_m", "must be > 0 m"))
        if not 0.0 < self.base_tilt_max_rad <= 1.45:
            errors.append(("base_tilt_max_rad", "must be in (0, 1.45] rad (the TO's bound)"))
        if not self.start_knees_rad or not all(0.0 <= k <= 2.5 for k in self.start_knees_rad):
            errors.append(("start_knees_rad", "needs at least one knee angle in [0, 2.5] rad"))
        if self.iterations < 1 or self.tolerance <= 0.0:
            errors.append(("iterations", "needs iterations >= 1 and tolerance > 0"))
        errors += at_most("iterations", self.iterations, 100_000, "IK converges in hundreds")
        return errors
