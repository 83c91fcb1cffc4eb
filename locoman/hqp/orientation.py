"""Orientation reference of the gripper.

Paper B learns only the wrist position and velocity; the gripper's orientation is a task
choice. Here it is constant: the gripper is horizontal, its approach axis (hand z) points along
the horizontal part of the demonstrated grasp velocity and its fingers close horizontally,
so the moving gripper slides onto the upright bottle along its approach axis and closes on
it; the hand's x axis points down.

Two alternatives were tried and dropped: a top grasp (gripper pointing down) cannot take a
bottle while rising at the grasp (the palm sweeps below the bottle's top just before the
grasp), and a side grasp pointing along the arm is reachable only with joint 6 at its limit.
"""

from __future__ import annotations

import numpy as np

#: Hand frame for heading 0: approach (z) along world +x, fingers (y) along world +y, x down.
SIDE_GRASP = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])


def yaw_matrix(yaw: float) -> np.ndarray:
    """Rotation about world z by ``yaw`` [rad]."""
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def grasp_orientation(grasp_velocity: np.ndarray) -> np.ndarray:
    """Gripper orientation (3, 3), world: approach along the horizontal grasp velocity."""
    return yaw_matrix(float(np.arctan2(grasp_velocity[1], grasp_velocity[0]))) @ SIDE_GRASP
