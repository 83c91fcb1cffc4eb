"""Joint limits of the HQP as one box on the joint velocity (paper B, eq. (7)-(9))."""

from __future__ import annotations

import dataclasses

import numpy as np


@dataclasses.dataclass(frozen=True)
class JointLimits:
    """Whole-body limits, joints ordered (base x, base y, base yaw, arm 1..7).

    Attributes:
        arm_min: (7,) lower arm position limits [rad].
        arm_max: (7,) upper arm position limits [rad].
        velocity_max: (10,) symmetric velocity limits [m/s] or [rad/s].
        acceleration_max: (10,) symmetric acceleration limits [m/s^2] or [rad/s^2].
    """

    arm_min: np.ndarray
    arm_max: np.ndarray
    velocity_max: np.ndarray
    acceleration_max: np.ndarray

    @property
    def arm_mid(self) -> np.ndarray:
        """q_a,mid = (q_a,min + q_a,max) / 2 [rad] (below eq. (6))."""
        return 0.5 * (self.arm_min + self.arm_max)


def velocity_box(
    limits: JointLimits, q_arm_star: np.ndarray, qdot_star_prev: np.ndarray, dt: float
) -> tuple[np.ndarray, np.ndarray]:
    """Lower and upper bounds (10,) on the joint velocity qdot of the next step.

    Intersects (8) |qdot| <= qdot_max, (9) |qdot - qdot*| <= qddot_max dt and, for the arm
    only (the base's position is unbounded), (7) q_a,min <= q_a* + qdot_a dt <= q_a,max.
    (8) and (9) always intersect when qdot* obeys (8); where (7) would empty the box (a joint
    too fast to stop before its limit) the acceleration bound wins, so the box is never empty
    and the joint brakes as hard as it may.

    Args:
        limits: The robot's limits.
        q_arm_star: (7,) integrated optimal arm position q_a* [rad].
        qdot_star_prev: (10,) optimal velocity of the previous step qdot*.
        dt: Control period [s].
    """
    lo = np.maximum(-limits.velocity_max, qdot_star_prev - limits.acceleration_max * dt)
    hi = np.minimum(limits.velocity_max, qdot_star_prev + limits.acceleration_max * dt)
    lo = np.minimum(lo, hi)
    arm = slice(3, 10)
    lo[arm] = np.clip((limits.arm_min - q_arm_star) / dt, lo[arm], hi[arm])
    hi[arm] = np.clip((limits.arm_max - q_arm_star) / dt, lo[arm], hi[arm])
    return lo, hi
