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


class VelocityBox:
    """The velocity box of eq. (7)-(9) for one robot and control period, its constant factors
    computed once (it is evaluated at 1 kHz).

    Intersects (8) |qdot| <= qdot_max, (9) |qdot - qdot*| <= qddot_max dt and, for the arm
    only (the base's position is unbounded), (7) q_a,min <= q_a* + qdot_a dt <= q_a,max.
    (8) and (9) intersect because qdot* obeys (8) (a precondition: every qdot* solved
    inside this box does). Where (7) would empty the box (a joint too fast
    to stop before its limit) the acceleration bound wins, so the box is never empty and the
    joint brakes as hard as it may.

    Args:
        limits: The robot's limits.
        dt: Control period [s].
    """

    def __init__(self, limits: JointLimits, dt: float) -> None:
        self._vmax = limits.velocity_max
        self._neg_vmax = -limits.velocity_max
        self._step = limits.acceleration_max * dt
        # (7) over all 10 joints: the base's position limits are -inf, +inf, for which the
        # clip below leaves the (8)-(9) box as it is.
        inf = np.full(3, np.inf)
        self._q_min, self._q_max = np.r_[-inf, limits.arm_min], np.r_[inf, limits.arm_max]
        self._dt = dt
        self._box = np.empty((4, 10))  # (8)-(9) lower, upper; (7) lower, upper

    def __call__(
        self,
        q_star: np.ndarray,
        qdot_star_prev: np.ndarray,
        out: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper bounds (10,) on the next step's joint velocity qdot.

        Args:
            q_star: (10,) integrated optimal configuration q* (the base's entries unused).
            qdot_star_prev: (10,) optimal velocity of the previous step qdot*, within (8).
            out: Arrays (10,) to write the bounds into, e.g. a QP's bound buffers.
        """
        # One-dimensional ufuncs with out=, no temporaries: this runs at 1 kHz, and numpy's
        # call overhead is three times larger on stacked (2, 10) rows with broadcasting.
        # min(max(x, a), b) is np.clip(x, a, b) without its overhead.
        mx, mn = np.maximum, np.minimum
        lo, hi, pos_lo, pos_hi = self._box
        # (8)-(9): qdot* -+ the step, each clipped to its side of +-qdot_max; with
        # |qdot*| <= qdot_max, lower <= qdot* <= upper.
        mx(np.subtract(qdot_star_prev, self._step, lo), self._neg_vmax, lo)
        mn(np.add(qdot_star_prev, self._step, hi), self._vmax, hi)
        # (7): each end of the position box clipped into the (8)-(9) box. Clipping its upper
        # end against the clipped lower end would change nothing: (7)'s lower end is below
        # its upper end.
        np.divide(np.subtract(self._q_min, q_star, pos_lo), self._dt, pos_lo)
        np.divide(np.subtract(self._q_max, q_star, pos_hi), self._dt, pos_hi)
        out_lo, out_hi = (np.empty(10), np.empty(10)) if out is None else out
        mn(mx(pos_lo, lo, out_lo), hi, out_lo)
        mn(mx(pos_hi, lo, out_hi), hi, out_hi)
        return out_lo, out_hi
