"""Rigid and similarity transforms from 3D correspondences by SVD, batched over hypotheses.

Kabsch (rigid) and Umeyama (similarity) solve

    min_{s, R, t}  sum_i w_i || dst_i - (s R src_i + t) ||^2,   R in SO(3),

in closed form from the SVD of the weighted cross-covariance (Umeyama 1991, eqs. (38)-(42)).
Every function broadcasts over leading axes, so many sampled hypotheses are solved at once.
"""

from __future__ import annotations

import numpy as np


def umeyama(
    src: np.ndarray,
    dst: np.ndarray,
    weights: np.ndarray | None = None,
    with_scale: bool = False,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Best transform dst ~ s R src + t.

    Args:
        src: Source points (..., N, 3) [m].
        dst: Destination points (..., N, 3) [m].
        weights: Non-negative weights (..., N); uniform when None.
        with_scale: Solve for the scale s (Umeyama); else s = 1 (Kabsch).

    Returns:
        scale (...,) [-], rotation (..., 3, 3), translation (..., 3) [m]. Degenerate inputs
        (fewer than three non-collinear weighted points) give a valid but arbitrary rotation.
    """
    src = np.asarray(src, dtype=float)
    dst = np.asarray(dst, dtype=float)
    w = np.ones(src.shape[:-1]) if weights is None else np.asarray(weights, dtype=float)
    w = w / np.maximum(w.sum(axis=-1, keepdims=True), 1e-300)
    mu_s = np.einsum("...n,...nk->...k", w, src)
    mu_d = np.einsum("...n,...nk->...k", w, dst)
    xs = src - mu_s[..., None, :]
    xd = dst - mu_d[..., None, :]
    cov = np.einsum("...n,...ni,...nj->...ij", w, xd, xs)
    u, sig, vt = np.linalg.svd(cov)
    # Reflection guard: flip the weakest axis when det(U V^T) < 0 (Umeyama eq. (39)).
    d = np.ones(sig.shape)
    d[..., 2] = np.sign(np.linalg.det(u) * np.linalg.det(vt))
    d[..., 2][d[..., 2] == 0.0] = 1.0
    rot = np.einsum("...ij,...j,...jk->...ik", u, d, vt)
    if with_scale:
        var_s = np.einsum("...n,...nk,...nk->...", w, xs, xs)
        scale = (sig * d).sum(axis=-1) / np.maximum(var_s, 1e-300)
    else:
        scale = np.ones(sig.shape[:-1])
    trans = mu_d - scale[..., None] * np.einsum("...ij,...j->...i", rot, mu_s)
    return scale, rot, trans


def similarity_matrix(scale: np.ndarray, rot: np.ndarray, trans: np.ndarray) -> np.ndarray:
    """Homogeneous matrices (..., 4, 4) of x -> s R x + t."""
    rot = np.asarray(rot, dtype=float)
    out = np.zeros((*rot.shape[:-2], 4, 4))
    out[..., :3, :3] = np.asarray(scale, dtype=float)[..., None, None] * rot
    out[..., :3, 3] = trans
    out[..., 3, 3] = 1.0
    return out


def decompose_similarity(matrix: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """Scale [-], rotation (3, 3) and translation (3,) [m] of a similarity matrix (4, 4)."""
    linear = np.asarray(matrix, dtype=float)[:3, :3]
    scale = float(np.cbrt(np.linalg.det(linear)))
    return scale, linear / scale, np.asarray(matrix, dtype=float)[:3, 3].copy()


def apply(matrix: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Points (..., N, 3) mapped by homogeneous matrices (..., 4, 4)."""
    matrix = np.asarray(matrix, dtype=float)
    return np.matmul(points, np.swapaxes(matrix[..., :3, :3], -1, -2)) + matrix[..., None, :3, 3]


def nearest_rotation(linear: np.ndarray) -> np.ndarray:
    """The rotation (3, 3) nearest a linear map (3, 3) in the Frobenius norm: U V^T of its
    SVD, with the last axis flipped where that would reflect."""
    u, _, vt = np.linalg.svd(linear)
    d = np.sign(np.linalg.det(u @ vt))
    return u @ np.diag([1.0, 1.0, d]) @ vt


def rotation_angle_deg(rot_a: np.ndarray, rot_b: np.ndarray) -> float:
    """Geodesic angle between two rotations [deg]."""
    cos = 0.5 * (np.trace(np.asarray(rot_a).T @ np.asarray(rot_b)) - 1.0)
    return float(np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))))
