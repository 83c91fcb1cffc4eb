"""Tracking tasks of the inverse-dynamics QP: rows (A, b) the cost asks A a = b of.

Each task is a PD law on its error with the reference's acceleration fed forward (TSID's
``TaskSE3Equality``, ``TaskComEquality``, ``TaskJointPosture``):

    J a + J_dot v = a_ref + kp e + kd (v_ref - J v)   =>   A = J,  b = a_ref + kp e + kd
    (v_ref - J v) - J_dot v

with e the position error [m] (and, for a pose, the rotation error log(R_ref R^T) [rad], world
axes). J_dot v, the acceleration at zero joint acceleration, is the "drift".
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from locoman.config.execute import MomentumCfg, TaskCfg


def pose_error(
    position: np.ndarray, rotation: np.ndarray, position_ref: np.ndarray, rotation_ref: np.ndarray
) -> np.ndarray:
    """(6,) the error of a frame's pose: p_ref - p [m], log3(R_ref R^T) [rad] (world axes)."""
    return np.r_[position_ref - position, pin.log3(rotation_ref @ rotation.T)]


def pd_target(
    cfg: TaskCfg,
    error: np.ndarray,
    velocity: np.ndarray,
    velocity_ref: np.ndarray,
    acceleration_ref: np.ndarray,
    drift: np.ndarray,
) -> np.ndarray:
    """b = a_ref + kp e + kd (v_ref - v) - J_dot v [m/s^2, rad/s^2]."""
    return acceleration_ref + cfg.kp * error + cfg.damping * (velocity_ref - velocity) - drift


def posture_rows(
    cfg: TaskCfg,
    q: np.ndarray,
    v: np.ndarray,
    q_ref: np.ndarray,
    v_ref: np.ndarray,
    a_ref: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """(A (29, 35), b (29,)) of the joints' posture: a selection of the joint accelerations."""
    nj = len(q) - 7
    a_matrix = np.zeros((nj, nj + 6))
    a_matrix[:, 6:] = np.eye(nj)
    b = pd_target(cfg, q_ref[7:] - q[7:], v[6:], v_ref[6:], a_ref[6:], 0.0)
    return a_matrix, b


def angular_momentum_rows(
    cfg: MomentumCfg, centroidal_map: np.ndarray, map_rate: np.ndarray, v: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """(A (3, nv), b (3,)) of the centroidal angular momentum L = A_G,ang v [kg m^2/s]:
    dL/dt = A_G,ang a + dA_G,ang v asked to be -gain L (TSID's ``TaskAMEquality`` with a
    zero reference). ``centroidal_map`` and ``map_rate`` are A_G and dA_G/dt (6, nv),
    Pinocchio's ``computeCentroidalMapTimeVariation`` (linear rows first)."""
    angular, rate = centroidal_map[3:], map_rate[3:]
    return angular, -cfg.gain * (angular @ v) - rate @ v
