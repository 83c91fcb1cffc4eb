"""Hands and feet of the generated image in 3D, in the frame of R_g's object cloud.

The paper lifts the 2D hand and foot keypoints with the estimated depth D_g (``depth``). That
fails for a hand behind the object, whose pixel shows the object's near face. The ``pose``
lift anchors the 3D pose estimate (metric, in R_g's camera frame) to the depth-lifted
keypoints that are visible, through the distortion that the heuristic intrinsics and a depth
scale make: with f the true and f' the guessed focal length and s the depth scale, a point
(x, y, z) lifts to s (f / f') (x, y) and s z, so

    q = diag(k_xy, k_xy, k_z) p + t                                           (anchor model)

with t = 0, since both frames share the optical centre.
"""

from __future__ import annotations

import dataclasses

import numpy as np

MIN_ANCHORS = 4  # keypoints needed for a robust anchor fit


@dataclasses.dataclass(frozen=True)
class Anchor:
    """Map from the pose estimate's camera frame into the lifted cloud's frame.

    Attributes:
        scale: (3,) per-axis scale (k_xy, k_xy, k_z) [-].
        offset: (3,) translation t [m].
        inliers: Keypoints used in the final fit.
        residual_m: Median distance of the inliers to the fit [m].
    """

    scale: np.ndarray
    offset: np.ndarray
    inliers: int
    residual_m: float

    def __call__(self, points: np.ndarray) -> np.ndarray:
        return np.asarray(points) * self.scale + self.offset

    def undo(self, points: np.ndarray) -> np.ndarray:
        """Points of the lifted cloud's frame (N, 3) back in the metric camera frame [m]."""
        return (np.asarray(points) - self.offset) / self.scale


def fit_anchor(pose: np.ndarray, lifted: np.ndarray, usable: np.ndarray, quantile: float) -> Anchor:
    """Fit the anchor model from pose keypoints (K, 3) to lifted keypoints (K, 3) [m].

    Both frames share the optical centre, so t = 0. The ray of a keypoint does not depend
    on depth errors, so the focal ratio a = k_xy / k_z is the least-squares ratio of the
    lifted and the pose rays, q_xy / q_z = a p_xy / p_z. Depth scales are robust ratios
    k_z = q_z / p_z: keypoints hidden behind something read a nearer depth and give a
    smaller ratio, and the body's surface sits in front of its joints, so an upper
    ``quantile`` of the ratios is taken rather than their mean.

    Args:
        pose: 3D pose estimate, R_g camera frame [m].
        lifted: Keypoints lifted with D_g (NaN where there is none) [m].
        usable: Keypoints that may anchor (e.g. not on the object's mask).
        quantile: Quantile of the depth ratios taken as k_z, in [0, 1].

    Raises:
        ValueError: With fewer than four usable keypoints.
    """
    keep = usable & np.isfinite(lifted).all(axis=1) & np.isfinite(pose).all(axis=1)
    keep &= (pose[:, 2] > 0.0) & (lifted[:, 2] > 0.0)
    if keep.sum() < MIN_ANCHORS:
        raise ValueError(f"{keep.sum()} usable keypoints; the anchor needs {MIN_ANCHORS}")
    p, q = pose[keep], lifted[keep]
    ray_p = p[:, :2] / p[:, 2:]
    ray_q = q[:, :2] / q[:, 2:]
    ratio = float(np.sum(ray_p * ray_q) / np.sum(ray_p**2))
    k_z = float(np.quantile(q[:, 2] / p[:, 2], quantile))
    anchor = Anchor(np.array([ratio * k_z, ratio * k_z, k_z]), np.zeros(3), int(keep.sum()), 0.0)
    residual = np.linalg.norm(anchor(p) - q, axis=1)
    return dataclasses.replace(anchor, residual_m=float(np.median(residual)))


SOLE_KEYPOINTS = ("left_foot", "left_toe", "right_foot", "right_toe")


def support_up(points: np.ndarray, pelvis: np.ndarray) -> np.ndarray | None:
    """Unit up direction of the plane the soles stand on, from the sole and toe keypoints
    (4, 3) [m], pointing towards the pelvis (3,) [m]; None when they are not usable."""
    if not np.isfinite(points).all() or not np.isfinite(pelvis).all():
        return None
    centred = points - points.mean(axis=0)
    normal = np.linalg.svd(centred)[2][2]
    return normal if normal @ (pelvis - points.mean(axis=0)) > 0.0 else -normal
