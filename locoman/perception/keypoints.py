"""2D human keypoints in R_g and the 3D pose estimate (paper A: a human pose estimator [25]).

Backends: ``render`` (the true keypoints plus Gaussian pixel jitter) and ``mediapipe``
(BlazePose, optional package). The 3D pose artifact is the true pose plus noise
(``truth_noise``, standing in for a 3D human pose estimator) or the human model fitted to the
2D keypoints (``fit``, :mod:`locoman.perception.pose_fit`); both are scored here.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from locoman.errors import ModelError
from locoman.perception.camera import to_camera
from locoman.perception.demonstrator import KEYPOINTS
from locoman.scene.rotations import quat_wxyz_to_matrix

# BlazePose landmark indices averaged into each of our keypoints (person's left/right).
BLAZEPOSE = {
    "pelvis": (23, 24),
    "neck": (11, 12),
    "head": (0,),
    "left_shoulder": (11,),
    "right_shoulder": (12,),
    "left_elbow": (13,),
    "right_elbow": (14,),
    "left_wrist": (15,),
    "right_wrist": (16,),
    "left_hand": (15, 17, 19),
    "right_hand": (16, 18, 20),
    "left_hip": (23,),
    "right_hip": (24,),
    "left_knee": (25,),
    "right_knee": (26,),
    "left_ankle": (27,),
    "right_ankle": (28,),
    "left_foot": (29, 31),
    "right_foot": (30, 32),
    "left_toe": (31,),
    "right_toe": (32,),
}
OCCLUDED_CONFIDENCE = 0.5  # what the jitter backend reports for a hidden keypoint


def jittered_keypoints(
    truth: dict[str, np.ndarray], jitter_px: float, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """True keypoints plus N(0, jitter_px^2) noise [px] and a confidence per keypoint."""
    px = truth["keypoints_px"] + rng.normal(0.0, jitter_px, truth["keypoints_px"].shape)
    conf = np.where(truth["keypoints_visible"], 1.0, OCCLUDED_CONFIDENCE)
    return px, conf


def mediapipe_keypoints(rgb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """BlazePose keypoints [px] (NaN when no person is found) and their visibility scores.

    Raises:
        ModelError: When the ``mediapipe`` package (0.10.x, which ships the pose model) is
            not installed.
    """
    try:
        from mediapipe.python.solutions import pose as mp_pose
    except ImportError:
        raise ModelError(
            "perception.masks.keypoints = mediapipe needs the optional package: "
            "`.venv/bin/pip install mediapipe==0.10.14` (0.10.x wheels ship BlazePose)"
        ) from None
    h, w = rgb.shape[:2]
    with mp_pose.Pose(static_image_mode=True, model_complexity=1) as estimator:
        result: Any = estimator.process(np.ascontiguousarray(rgb))
    px = np.full((len(KEYPOINTS), 2), np.nan)
    conf = np.zeros(len(KEYPOINTS))
    if result.pose_landmarks is None:
        return px, conf
    marks = result.pose_landmarks.landmark
    for k, name in enumerate(KEYPOINTS):
        idx = BLAZEPOSE[name]
        px[k] = np.mean([[marks[i].x * w - 0.5, marks[i].y * h - 0.5] for i in idx], axis=0)
        conf[k] = float(np.mean([marks[i].visibility for i in idx]))
    return px, conf


def keypoint_errors(estimate: np.ndarray, truth: dict[str, np.ndarray]) -> dict[str, float | None]:
    """Pixel error statistics over visible keypoints (None when none was found)."""
    visible = truth["keypoints_visible"]
    err = np.linalg.norm(estimate - truth["keypoints_px"], axis=1)[visible]
    found = np.isfinite(err)
    if not found.any():
        return {"median_px": None, "max_px": None, "detected_fraction": 0.0}
    return {
        "median_px": float(np.median(err[found])),
        "max_px": float(err[found].max()),
        "detected_fraction": float(found.mean()),
    }


def pose_errors(pose: dict[str, np.ndarray], truth: dict[str, np.ndarray]) -> dict[str, float]:
    """A 3D pose estimate against the truth, in R_g's camera frame.

    Returns:
        ``mpjpe_m``: mean keypoint distance [m] (the absolute placement, depth included);
        ``mpjpe_pelvis_aligned_m``: the same after moving both pelvises to the origin [m]
        (the posture); ``pelvis_rotation_error_deg``: angle between the pelvis frames [deg].
    """
    true_kp = to_camera(truth["keypoints_world_m"], truth["T_world_cam"])
    est = pose["keypoints_cam_m"]
    pelvis = list(KEYPOINTS).index("pelvis")
    aligned = (est - est[pelvis]) - (true_kp - true_kp[pelvis])
    q = truth["human_qpos"]
    R_true = np.linalg.inv(truth["T_world_cam"])[:3, :3] @ quat_wxyz_to_matrix(q[3:7])
    R_rel = R_true.T @ pose["T_cam_pelvis"][:3, :3]
    cos = np.clip(0.5 * (np.trace(R_rel) - 1.0), -1.0, 1.0)
    return {
        "mpjpe_m": float(np.linalg.norm(est - true_kp, axis=1).mean()),
        "mpjpe_pelvis_aligned_m": float(np.linalg.norm(aligned, axis=1).mean()),
        "pelvis_rotation_error_deg": float(np.degrees(np.arccos(cos))),
    }


def pose_estimate(
    truth: dict[str, np.ndarray],
    joint_names: list[str],
    noise_m: float,
    noise_rad: float,
    rng: np.random.Generator,
) -> dict[str, np.ndarray]:
    """3D pose in R_g's camera frame: true keypoints and joint angles plus Gaussian noise.

    Returns:
        Arrays of the ``perception.pose`` artifact.
    """
    T_cam_world = np.linalg.inv(truth["T_world_cam"])
    kp_cam = to_camera(truth["keypoints_world_m"], truth["T_world_cam"])
    q = truth["human_qpos"]
    T_world_pelvis = np.eye(4)
    T_world_pelvis[:3, :3] = quat_wxyz_to_matrix(q[3:7])
    T_world_pelvis[:3, 3] = q[:3]
    return {
        "keypoint_names": truth["keypoint_names"],
        "keypoints_cam_m": kp_cam + rng.normal(0.0, noise_m, kp_cam.shape),
        "joint_names": np.array(joint_names),
        "joint_angles_rad": q[7:] + rng.normal(0.0, noise_rad, q[7:].shape),
        "T_cam_pelvis": T_cam_world @ T_world_pelvis,
    }
