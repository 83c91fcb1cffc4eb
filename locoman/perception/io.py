"""Artifacts of the perception stages ``generate``, ``masks`` and ``clouds``.

Layout under ``data/<scenario>/``::

    generate/prompts.json                         augmented prompts, one entry per subtask
    generate/images/subtask_<i>/image.png         R_g
    generate/images/subtask_<i>/sim_rgb.png       R_s
    generate/images/subtask_<i>/sim_view.npz      D_s, true intrinsics, camera and object poses,
                                                  the object's mask in R_s
    generate/images/subtask_<i>/user_input.npz    ``folder`` backend: the user's box, keypoints,
                                                  depth (locoman.perception.user_images)
    generate/ground_truth/subtask_<i>.npz         scoring only (see below)
    masks/subtasks/subtask_<i>.npz                object masks in R_g and R_s, 2D keypoints
    masks/subtasks/pose_<i>.npz                   3D human pose estimate in R_g's camera frame
    clouds/subtasks/subtask_<i>.npz               depth and intrinsics of R_g, clouds, 3D points
    clouds/contact_sheets/subtask_<i>.png         what a person checks at a glance

The ground truth is read only to score a stage and by the backends that stand in for a learned
model (``render`` masks, jittered keypoints, the depth error model), never by the geometry.

Cameras use OpenCV axes (x right, y down, z forward); ``T_a_b`` maps frame b into frame a.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from locoman.artifacts import ArtifactSchema, Field
from locoman.errors import ArtifactError

PROMPTS_FILE = "prompts.json"
IMAGES_DIR = "images"
GROUND_TRUTH_DIR = "ground_truth"
SUBTASKS_DIR = "subtasks"
CONTACT_SHEETS_DIR = "contact_sheets"

# 2D keypoints of R_g, found (masks) or given (a user's annotations).
KEYPOINTS_PX = Field(
    "keypoints_px", "float64", ("K", 2), "px", "(u, v) in R_g; NaN where none", nan_allowed=True
)
PROMPTS = ArtifactSchema(
    "perception.prompts",
    1,
    "generate",
    (
        Field("backend", "str", doc="image backend that made the images"),
        Field(
            "subtasks",
            "list",
            doc="index, prompt, augmented_prompt, object, contacts, image, sim_image, sim_view",
        ),
    ),
)
SIM_VIEW = ArtifactSchema(
    "perception.sim_view",
    2,
    "generate",
    (
        Field("depth_m", "float32", ("H", "W"), "m", "D_s: depth along the optical axis, 0 = none"),
        Field("object_mask", "bool", ("H", "W"), "-", "the object's pixels: the simulator's"),
        Field("K", "float64", (3, 3), "px", "true intrinsics of R_s"),
        Field("T_world_cam", "float64", (4, 4), "m", "camera pose in the scene (OpenCV axes)"),
        Field("T_world_object", "float64", (4, 4), "m", "the object's pose in the scene"),
    ),
)
GROUND_TRUTH = ArtifactSchema(
    "perception.ground_truth",
    1,
    "generate",
    (
        Field("K", "float64", (3, 3), "px", "true intrinsics of R_g"),
        Field("T_world_cam", "float64", (4, 4), "m", "R_g camera pose, generation world"),
        Field("depth_m", "float32", ("H", "W"), "m", "true depth of R_g, 0 = sky"),
        Field("object_mask", "bool", ("H", "W"), "-", "the object's pixels in R_g"),
        Field("human_mask", "bool", ("H", "W"), "-", "the demonstrator's pixels in R_g"),
        Field("sim_object_mask", "bool", ("Hs", "Ws"), "-", "the object's pixels in R_s"),
        Field("keypoint_names", "str", ("K",)),
        Field("keypoints_px", "float64", ("K", 2), "px", "(u, v) pixel index coordinates"),
        Field("keypoints_world_m", "float64", ("K", 3), "m", "generation world"),
        Field("keypoints_visible", "bool", ("K",), "-", "in the image and not occluded"),
        Field("contact_names", "str", ("C",), "-", "end effectors of the plan's contacts"),
        Field("contact_patches", "str", ("C",), "-", "patch touched, or floor"),
        Field("contact_uv", "float64", ("C", 2), "-", "normalised patch coordinates"),
        Field("contact_points_variant_m", "float64", ("C", 3), "m", "variant's object frame"),
        Field("contact_points_object_m", "float64", ("C", 3), "m", "scene object's frame"),
        Field("T_world_object", "float64", (4, 4), "m", "variant pose, generation world"),
        Field("variant_size_m", "float64", ("S",), "m", "extents of the drawn variant"),
        Field("object_size_m", "float64", ("S",), "m", "extents of the scene's object"),
        Field("variant_rgba", "float64", (4,)),
        Field("variant_textured", "bool", ()),
        Field("human_qpos", "float64", (43,), "mixed", "demonstrator MuJoCo qpos (quat w,x,y,z)"),
    ),
)
MASKS = ArtifactSchema(
    "perception.masks",
    1,
    "masks",
    (
        Field("object_mask", "bool", ("H", "W"), "-", "object pixels in R_g"),
        Field("sim_object_mask", "bool", ("Hs", "Ws"), "-", "object pixels in R_s"),
        Field("keypoint_names", "str", ("K",)),
        KEYPOINTS_PX,
        Field("keypoint_confidence", "float64", ("K",), "-", "in [0, 1]"),
    ),
)
POSE = ArtifactSchema(
    "perception.pose",
    1,
    "masks",
    (
        Field("keypoint_names", "str", ("K",)),
        Field("keypoints_cam_m", "float64", ("K", 3), "m", "3D keypoints, R_g camera frame"),
        Field("joint_names", "str", ("J",), "-", "human_description joints"),
        Field("joint_angles_rad", "float64", ("J",), "rad", "estimated joint angles"),
        Field("T_cam_pelvis", "float64", (4, 4), "m", "pelvis pose in R_g's camera frame"),
    ),
)
CLOUDS = ArtifactSchema(
    "perception.clouds",
    1,
    "clouds",
    (
        Field("depth_m", "float32", ("H", "W"), "m", "estimated depth D_g of R_g, 0 = none"),
        Field("K", "float64", (3, 3), "px", "intrinsics used to lift R_g"),
        Field("points_gen_m", "float64", ("N", 3), "m", "object cloud of R_g, camera frame"),
        Field("points_sim_m", "float64", ("M", 3), "m", "object cloud of R_s, scene world"),
        Field("keypoint_names", "str", ("K",)),
        Field(
            "keypoints_cam_m",
            "float64",
            ("K", 3),
            "m",
            "lifted 2D keypoints; NaN if none",
            nan_allowed=True,
        ),
    ),
)


def subtask_dir(generate_dir: Path, index: int) -> Path:
    """``<generate_dir>/images/subtask_<index>/``."""
    return Path(generate_dir) / IMAGES_DIR / f"subtask_{index}"


def read_png(path: str | Path, producer: str) -> np.ndarray:
    """An RGB uint8 image; a clear error naming the producing stage when missing or corrupt."""
    path = Path(path)
    if not path.is_file():
        raise ArtifactError(f"image {path} is missing (rerun `dvc repro {producer}`)")
    bgr = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if bgr is None:
        raise ArtifactError(f"image {path} is not a readable PNG (rerun `dvc repro {producer}`)")
    return np.ascontiguousarray(bgr[:, :, ::-1])
