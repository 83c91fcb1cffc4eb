"""Tasks of the stack, each a least-squares target A qdot = b (paper B, eq. (4)-(6)).

Level 1 is closed-loop inverse kinematics (CLIK) of the end-effector pose, eq. (4):

    J qdot = K_v (xd_dot - xa_dot) + K_p (x_d - x_a).

Taken literally with the measured velocity xa_dot = J qdot_measured, the law solved every
step is J qdot_k = xd_dot - J qdot_{k-1} + K_p e with K_v = 1, so qdot alternates between two
values (the chatter) and its average only reaches (xd_dot + K_p e) / 2, a lag of about
xd_dot / K_p (5 cm at 0.2 m/s). The velocity error belongs to the acceleration level, where
CLIK gets it by differentiating the position error. The default therefore feeds the desired
velocity forward, J qdot = K_v xd_dot + K_p e, which is first-order stable with error
dynamics edot = -K_p e; the literal law is kept as an option for comparison.
"""

from __future__ import annotations

import math

import numpy as np

from locoman.scene.mobile_manipulator import rotation_error


class ClikTask:
    """Level 1, eq. (4): end-effector pose and velocity tracking, evaluated into buffers of
    its own (it runs at 1 kHz): the b of a call is overwritten by the next call.

    Args:
        kp: Diagonal of K_p [1/s].
        kv: Diagonal of K_v [-].
    """

    def __init__(self, kp: float, kv: float) -> None:
        self.kp, self.kv = kp, kv
        self._b = np.empty(6)
        self._b_pos, self._b_rot = self._b[:3], self._b[3:]
        self._velocity = np.empty(6)
        rel = np.empty((3, 3))
        self._work = (rel, rel.reshape(9), np.empty(4))

    def __call__(
        self,
        jacobian: np.ndarray,
        x_desired: tuple[np.ndarray, np.ndarray],
        xdot_desired: np.ndarray,
        x_actual: tuple[np.ndarray, np.ndarray],
        xdot_actual: np.ndarray | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """(A, b) with A = J and b the commanded end-effector velocity.

        Args:
            jacobian: (6, n) end-effector Jacobian, world frame (linear rows, then angular).
            x_desired: Desired pose as (position (3,) [m], rotation (3, 3)).
            xdot_desired: (6,) desired linear [m/s] and angular [rad/s] velocity.
            x_actual: Actual pose as (position, rotation).
            xdot_actual: (6,) measured velocity for the literal law; ``None`` for
                feed-forward.
        """
        (p_d, r_d), (p_a, r_a) = x_desired, x_actual
        b = self._b
        np.subtract(p_d, p_a, self._b_pos)
        rotation_error(r_d, r_a, self._b_rot, self._work)
        b *= self.kp
        velocity = xdot_desired if xdot_actual is None else xdot_desired - xdot_actual
        # K_v = 1 (the paper's) would multiply by one, which leaves every bit as it is.
        b += velocity if self.kv == 1.0 else np.multiply(velocity, self.kv, self._velocity)
        return jacobian, b


_H_B = np.eye(3, 10)
_H_A = np.eye(7, 10, 3)


def base_pose_task(
    q_base_desired: np.ndarray, q_base_star: np.ndarray, gain: float
) -> tuple[np.ndarray, np.ndarray]:
    """First term of eq. (6) divided by dt: H_b qdot = g (q_b,d - q_b*).

    H_b selects the base (3 of 10 joints). With g = 1 / dt this is the paper's term exactly;
    a smaller g spreads the correction over 1 / g seconds.
    """
    err = q_base_desired - q_base_star
    err[2] = wrap_angle(float(err[2]))
    return _H_B, gain * err


def arm_mid_range_task(
    q_arm_mid: np.ndarray, q_arm_star: np.ndarray, gain: float
) -> tuple[np.ndarray, np.ndarray]:
    """Second term of eq. (6) divided by dt: H_a qdot = g (q_a,mid - q_a*), H_a the arm (7)."""
    return _H_A, gain * (q_arm_mid - q_arm_star)


def wrap_angle(angle: float) -> float:
    """``angle`` in [-pi, pi) [rad]."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi
