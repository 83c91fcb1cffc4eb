"""Scoring contact transfer against the ``render`` backend's ground truth.

Only this module reads the ground truth. Errors are in the scene world [m]:

- contact error: distance between a transferred contact and the true one (the variant's
  contact mapped onto the scene's object by patch and normalised patch coordinates);
- object transform: the rotation between the recovered and the true map from R_g's camera to
  the world, and where the recovered map puts the object's centre;
- placement: the pelvis relative to the object (a foot contact keeps its distance from the
  approach face, so the placement shifts with the approach face in the same way).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from locoman.contact.kabsch import apply, decompose_similarity, rotation_angle_deg
from locoman.contact.transfer import SubtaskInputs, Transfer
from locoman.perception import camera
from locoman.scene.rotations import quat_wxyz_to_matrix


def true_contacts(truth: dict[str, np.ndarray], effectors: list[str], T_world_object: np.ndarray):
    """True contact points (C, 3) in the scene world [m], in the plan's effector order."""
    names = list(truth["contact_names"])
    local = truth["contact_points_object_m"][[names.index(e) for e in effectors]]
    return camera.transform(local, T_world_object)


def score_subtask(
    truth: dict[str, np.ndarray], inputs: SubtaskInputs, result: Transfer
) -> dict[str, Any]:
    """Per-contact errors of both methods, object transform and placement errors."""
    truth_world = true_contacts(truth, inputs.effectors, inputs.T_world_object)
    err = np.linalg.norm(result.points_world - truth_world, axis=1)
    naive_err = np.linalg.norm(result.naive_world - truth_world, axis=1)
    # The true map from R_g's (undistorted) camera frame to the world, through the object.
    T_genworld_variant = truth["T_world_object"]
    T_true = inputs.T_world_object @ np.linalg.inv(T_genworld_variant) @ truth["T_world_cam"]
    reg = result.registration
    _, rot, _ = decompose_similarity(reg.transform)
    rotation_error = rotation_angle_deg(rot, T_true[:3, :3])
    # The registration maps R_g's metric camera frame, which the 3D pose estimate defines
    # and the true camera frame is (up to the estimate's noise): the variant's centre there.
    centre_local = np.array([0.0, 0.0, 0.5 * float(truth["variant_size_m"][-1])])
    centre_cam = camera.to_camera(
        camera.transform(centre_local[None], T_genworld_variant), truth["T_world_cam"]
    )
    scene_centre_local = np.array([0.0, 0.0, 0.5 * float(truth["object_size_m"][-1])])
    scene_centre = camera.transform(scene_centre_local[None], inputs.T_world_object)
    translation_error = float(np.linalg.norm(apply(reg.transform, centre_cam) - scene_centre))
    # Placement: the true pelvis relative to the variant, moved with the approach face.
    q = truth["human_qpos"]
    T_genworld_pelvis = np.eye(4)
    T_genworld_pelvis[:3, :3] = quat_wxyz_to_matrix(q[3:7])
    T_genworld_pelvis[:3, 3] = q[:3]
    T_obj_pelvis_true = np.linalg.inv(T_genworld_variant) @ T_genworld_pelvis
    T_obj_pelvis_true[0, 3] -= 0.5 * float(truth["object_size_m"][0] - truth["variant_size_m"][0])
    T_obj_pelvis = np.linalg.inv(inputs.T_world_object) @ result.T_world_pelvis
    return {
        "contact_errors_m": [float(e) for e in err],
        "naive_contact_errors_m": [float(e) for e in naive_err],
        "rotation_error_deg": rotation_error,
        "translation_error_m": translation_error,
        "pelvis_position_error_m": float(
            np.linalg.norm(T_obj_pelvis[:3, 3] - T_obj_pelvis_true[:3, 3])
        ),
        "pelvis_rotation_error_deg": rotation_angle_deg(
            T_obj_pelvis[:3, :3], T_obj_pelvis_true[:3, :3]
        ),
    }


def summarise(errors: list[float], prefix: str) -> dict[str, float | None]:
    """Median, 90th percentile and maximum of contact errors [m] under ``prefix``."""
    if not errors:
        return {f"{prefix}_median_m": None, f"{prefix}_p90_m": None, f"{prefix}_max_m": None}
    e = np.asarray(errors)
    return {
        f"{prefix}_median_m": float(np.median(e)),
        f"{prefix}_p90_m": float(np.percentile(e, 90)),
        f"{prefix}_max_m": float(e.max()),
    }
