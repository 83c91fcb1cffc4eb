"""Rotation conversions, done once at the boundary between libraries.

Conventions: roll-pitch-yaw is ``R = Rz(yaw) Ry(pitch) Rx(roll)`` (Pinocchio's ``rpyToMatrix``);
quaternion order is always in the name: ``xyzw`` (Pinocchio, SciPy) or ``wxyz`` (MuJoCo).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation


def rpy_to_matrix(rpy: np.ndarray) -> np.ndarray:
    """Rotation matrix of roll-pitch-yaw angles [rad] (``Rz(y) Ry(p) Rx(r)``)."""
    return Rotation.from_euler("ZYX", np.asarray(rpy, dtype=float)[::-1]).as_matrix()


def matrix_to_rpy(rot: np.ndarray) -> np.ndarray:
    """Roll-pitch-yaw [rad] of a rotation matrix; pitch in [-pi/2, pi/2]."""
    return Rotation.from_matrix(rot).as_euler("ZYX")[::-1].copy()


def rpy_to_quat_xyzw(rpy: np.ndarray) -> np.ndarray:
    """Quaternion (x, y, z, w) of roll-pitch-yaw angles [rad]."""
    return Rotation.from_euler("ZYX", np.asarray(rpy, dtype=float)[::-1]).as_quat()


def quat_xyzw_to_rpy(quat_xyzw: np.ndarray) -> np.ndarray:
    """Roll-pitch-yaw [rad] of a quaternion (x, y, z, w)."""
    return Rotation.from_quat(quat_xyzw).as_euler("ZYX")[::-1].copy()


def xyzw_to_wxyz(quat_xyzw: np.ndarray) -> np.ndarray:
    """Reorder a quaternion from (x, y, z, w) to (w, x, y, z)."""
    q = np.asarray(quat_xyzw, dtype=float)
    return np.array([q[3], q[0], q[1], q[2]])


def wxyz_to_xyzw(quat_wxyz: np.ndarray) -> np.ndarray:
    """Reorder a quaternion from (w, x, y, z) to (x, y, z, w)."""
    q = np.asarray(quat_wxyz, dtype=float)
    return np.array([q[1], q[2], q[3], q[0]])


def yaw_quat_wxyz(yaw: float) -> np.ndarray:
    """Quaternion (w, x, y, z) of a rotation by ``yaw`` [rad] about world z."""
    return np.array([np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)])


def quat_wxyz_to_matrix(quat_wxyz: np.ndarray) -> np.ndarray:
    """Rotation matrix of a quaternion (w, x, y, z) (normalised first)."""
    return Rotation.from_quat(wxyz_to_xyzw(quat_wxyz)).as_matrix()
