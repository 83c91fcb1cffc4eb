"""Pinhole cameras in the OpenCV convention: x right, y down, z forward (the optical axis).

MuJoCo cameras look along their -z axis with y up; :func:`mujoco_xyaxes` converts at the
boundary, once. Pixel (u, v) is the pixel's index; its centre is at (u + 0.5, v + 0.5) in the
continuous image coordinates that the intrinsics map to.
"""

from __future__ import annotations

import numpy as np


def intrinsics_from_fovy(width: int, height: int, fovy_rad: float) -> np.ndarray:
    """Intrinsic matrix K (3, 3) of a renderer with square pixels and a centred principal point.

    f = (height / 2) / tan(fovy / 2) [px].
    """
    f = 0.5 * height / np.tan(0.5 * fovy_rad)
    return np.array([[f, 0.0, 0.5 * width], [0.0, f, 0.5 * height], [0.0, 0.0, 1.0]])


def heuristic_intrinsics(width: int, height: int) -> np.ndarray:
    """Paper A's guess for a generated image: f_x = width, f_y = height, c = half of them.

    "Using the LDMs' image resolution as the focal lengths and half the focal lengths for the
    principal point offsets leads to a reasonable point cloud geometry" (Sec. III-A.2).
    """
    return np.array(
        [[float(width), 0.0, 0.5 * width], [0.0, float(height), 0.5 * height], [0.0, 0.0, 1.0]]
    )


def look_at(eye: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Camera-to-world pose T (4, 4), OpenCV axes, at ``eye`` [m] looking at ``target`` [m].

    The image's x axis stays horizontal (no roll).
    """
    forward = np.asarray(target, float) - np.asarray(eye, float)
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, [0.0, 0.0, 1.0])
    if np.linalg.norm(right) < 1e-9:
        raise ValueError("look_at: the camera looks straight up or down; its roll is undefined")
    right /= np.linalg.norm(right)
    down = np.cross(forward, right)
    pose = np.eye(4)
    pose[:3, :3] = np.column_stack([right, down, forward])
    pose[:3, 3] = eye
    return pose


def mujoco_xyaxes(pose: np.ndarray) -> list[float]:
    """MuJoCo ``xyaxes`` (camera x and y axes in the world) of an OpenCV camera pose."""
    right, down = pose[:3, 0], pose[:3, 1]
    return [*right, *(-down)]


def to_camera(points_world: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """Points (N, 3) [m] from the world into the frame of a camera with pose ``T_world_cam``."""
    return (np.asarray(points_world) - pose[:3, 3]) @ pose[:3, :3]


def project(points_cam: np.ndarray, K: np.ndarray) -> np.ndarray:
    """Continuous pixel coordinates (N, 2) of camera-frame points (N, 3) [m] (z > 0)."""
    p = np.asarray(points_cam, float)
    uv = p[:, :2] / p[:, 2:3]
    return uv * np.diag(K)[:2] + K[:2, 2]


def pixel_rays(pixels: np.ndarray, K: np.ndarray) -> np.ndarray:
    """Camera-frame rays (N, 3) with z = 1 through pixel indices (N, 2) (u, v) [px]."""
    uv = np.asarray(pixels, float) + 0.5
    xy = (uv - K[:2, 2]) / np.diag(K)[:2]
    return np.column_stack([xy, np.ones(len(xy))])


def backproject(depth: np.ndarray, mask: np.ndarray, K: np.ndarray) -> np.ndarray:
    """Camera-frame points (N, 3) [m] of the pixels where ``mask`` holds and depth > 0.

    Args:
        depth: (H, W) depth along the optical axis [m]; 0 marks a missing pixel.
        mask: (H, W) boolean.
        K: (3, 3) intrinsics used for the lifting.
    """
    v, u = np.nonzero(mask & (depth > 0.0))
    rays = pixel_rays(np.column_stack([u, v]), K)
    return rays * depth[v, u][:, None]


def transform(points: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """Apply a homogeneous transform (4, 4) to points (N, 3)."""
    return np.asarray(points) @ pose[:3, :3].T + pose[:3, 3]
