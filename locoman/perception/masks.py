"""Stage ``masks``: object masks in R_g and R_s, 2D keypoints and the 3D pose in R_g.

Every backend that can run is scored against the ground truth (mask IoU, keypoint error in
pixels, 3D pose error), whichever one is selected, so one run gives the comparison table.
Images from the ``folder`` backend have no truth: their boxes and keypoints may come from the
user's annotations (:mod:`locoman.perception.user_images`), their pose from the fit.
"""

from __future__ import annotations

import contextlib
import time
from pathlib import Path
from typing import Any

import numpy as np

from locoman.artifacts import read_json, read_npz, write_metrics, write_npz
from locoman.config.perception import MasksCfg
from locoman.errors import ConfigError, InputError, ModelError
from locoman.perception import camera, pose_fit
from locoman.perception import keypoints as kp
from locoman.perception.demonstrator import keypoints_world
from locoman.perception.generate import subtask_rng
from locoman.perception.io import (
    GROUND_TRUTH,
    GROUND_TRUTH_DIR,
    MASKS,
    POSE,
    PROMPTS,
    PROMPTS_FILE,
    SIM_VIEW,
    SUBTASKS_DIR,
    read_png,
)
from locoman.perception.segment import (
    SamSegmenter,
    box_around,
    check_mask,
    grabcut_mask,
    mask_iou,
)
from locoman.perception.user_images import load_user_input
from locoman.progress import progress
from locoman.scene import human
from locoman.scene.rotations import quat_wxyz_to_matrix

MASK_SEED_OFFSET = 1  # the masks stage draws from its own stream, apart from generate's


def load_truth(generate_dir: Path, index: int) -> dict[str, np.ndarray] | None:
    """The ground truth of a subtask, or None when the image backend has none (``flux``)."""
    path = generate_dir / GROUND_TRUTH_DIR / f"subtask_{index}.npz"
    return read_npz(path, GROUND_TRUTH) if path.is_file() else None


def _require_truth(truth: dict | None, what: str) -> dict[str, np.ndarray]:
    """The ground truth, or a :class:`ConfigError`: ``what`` (which says what it takes from
    the truth and what would replace it) cannot run on images without it."""
    if truth is None:
        raise ConfigError(
            f"{what}, and these images have none (perception.generate.backend is not "
            "render): run this step on the render backend's images"
        )
    return truth


def masks_scenario(
    scenario: str, generate_dir: Path, out_dir: Path, cfg: MasksCfg, seed: int
) -> dict[str, Any]:
    """Write masks, keypoints and pose of every subtask; return the stage's metrics."""
    prompts = read_json(generate_dir / PROMPTS_FILE, PROMPTS)
    sam = SamSegmenter(cfg.sam_weights_dir, cfg.sam_runtime) if cfg.backend == "sam" else None
    human_model = pose_fit.human_model()
    joint_names = [human.human_pinocchio_model().names[j] for j in range(2, 38)]
    rows = []
    for entry in progress(prompts["subtasks"], f"masks {scenario}"):
        i = entry["index"]
        where = f"subtask {i} ({entry['prompt']!r}, object {entry['object']!r})"
        t0 = time.perf_counter()
        rgb = read_png(generate_dir / entry["image"], "generate")
        sim_rgb = read_png(generate_dir / entry["sim_image"], "generate")
        sim_mask = read_npz(generate_dir / entry["sim_view"], SIM_VIEW)["object_mask"]
        truth = load_truth(generate_dir, i)
        user = load_user_input(generate_dir, i)
        boxes = _prompt_boxes(truth, user, sim_mask, cfg, where)
        segmenters = {"render": None, "grabcut": None}
        if sam is not None:
            segmenters["sam"] = sam
        results: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        for name in segmenters:
            if name != cfg.backend and truth is None:
                continue
            results[name] = _segment(name, rgb, sim_rgb, truth, sim_mask, boxes, cfg, sam, where)
        obj_mask, sim_obj_mask = results[cfg.backend]
        check_mask(obj_mask, f"{where}, generated image")
        check_mask(sim_obj_mask, f"{where}, simulated view")
        rng = subtask_rng(seed + MASK_SEED_OFFSET, scenario, i)
        names = np.array(list(kp.KEYPOINTS))
        px, conf = _keypoints(rgb, truth, user, cfg, rng, where)
        write_npz(
            out_dir / SUBTASKS_DIR / f"subtask_{i}.npz",
            MASKS,
            {
                "object_mask": obj_mask,
                "sim_object_mask": sim_obj_mask,
                "keypoint_names": names,
                "keypoints_px": px,
                "keypoint_confidence": conf,
            },
        )
        K = camera.heuristic_intrinsics(rgb.shape[1], rgb.shape[0])
        poses = {}
        if cfg.pose == "fit" or truth is not None:
            poses["fit"] = _fitted_pose(human_model, px, conf, K, joint_names, where)
        if cfg.pose == "truth_noise" or truth is not None:
            poses["truth_noise"] = kp.pose_estimate(
                _require_truth(
                    truth,
                    "perception.masks.pose=truth_noise perturbs the true pose "
                    "(pose=fit fits the human model to the 2D keypoints)",
                ),
                joint_names,
                cfg.pose_noise_m,
                cfg.pose_noise_rad,
                rng,
            )
        write_npz(out_dir / SUBTASKS_DIR / f"pose_{i}.npz", POSE, poses[cfg.pose])
        row: dict[str, Any] = {"index": i, "seconds": time.perf_counter() - t0}
        if truth is not None:
            row["mask_iou"] = {
                name: mask_iou(m, truth["object_mask"]) for name, (m, _) in results.items()
            }
            row["sim_mask_iou"] = {
                name: mask_iou(s, truth["sim_object_mask"]) for name, (_, s) in results.items()
            }
            row["keypoints"] = {cfg.keypoints: kp.keypoint_errors(px, truth)}
            if cfg.keypoints != "mediapipe":
                with contextlib.suppress(ModelError):  # optional package
                    row["keypoints"]["mediapipe"] = kp.keypoint_errors(
                        kp.mediapipe_keypoints(rgb)[0], truth
                    )
            row["pose"] = {name: kp.pose_errors(pose, truth) for name, pose in poses.items()}
        rows.append(row)
    metrics = _summary(rows, cfg)
    write_metrics(out_dir, metrics)
    return metrics


def _prompt_boxes(
    truth: dict[str, np.ndarray] | None,
    user: dict[str, np.ndarray] | None,
    sim_mask: np.ndarray,
    cfg: MasksCfg,
    where: str,
) -> tuple[tuple[int, int, int, int], tuple[int, int, int, int]] | None:
    """The boxes (u0, v0, u1, v1) [px] that prompt ``grabcut`` and ``sam`` in R_g and R_s:
    around the true mask plus a margin (render images), the user's ``object_box_px``
    (folder images) or None (no box: only the ``render`` masks can run, on render images).
    R_s's box is around the simulator's mask of the object."""
    sim_box = box_around(check_mask(sim_mask, f"{where}, simulated view"), cfg.box_margin_px)
    if truth is not None:
        mask = check_mask(truth["object_mask"], f"{where}, generated image")
        return box_around(mask, cfg.box_margin_px), sim_box
    if user is not None and np.all(np.isfinite(user["object_box_px"])):
        u0, v0, u1, v1 = (round(float(x)) for x in user["object_box_px"])
        return (u0, v0, u1, v1), sim_box
    return None


def _keypoints(
    rgb: np.ndarray,
    truth: dict[str, np.ndarray] | None,
    user: dict[str, np.ndarray] | None,
    cfg: MasksCfg,
    rng: np.random.Generator,
    where: str,
) -> tuple[np.ndarray, np.ndarray]:
    """2D keypoints (K, 2) [px] (NaN: not found) and their confidences from ``cfg.keypoints``."""
    if cfg.keypoints == "render":
        return kp.jittered_keypoints(
            _require_truth(
                truth,
                "perception.masks.keypoints=render jitters the true keypoints "
                "(keypoints=mediapipe detects them; annotated reads the folder's)",
            ),
            cfg.keypoint_jitter_px,
            rng,
        )
    if cfg.keypoints == "mediapipe":
        return kp.mediapipe_keypoints(rgb)
    if user is None:
        raise ConfigError(
            f"{where}: perception.masks.keypoints=annotated reads the keypoints_px of the "
            "folder backend's annotations, and these images do not come from a folder"
        )
    px = user["keypoints_px"]
    return px, np.all(np.isfinite(px), axis=1).astype(float)


def _fitted_pose(
    model: Any,
    px: np.ndarray,
    conf: np.ndarray,
    K: np.ndarray,
    joint_names: list[str],
    where: str,
) -> dict[str, np.ndarray]:
    """The ``perception.pose`` arrays of the human model fitted to the 2D keypoints."""
    try:
        fit = pose_fit.fit_pose(model, px, conf, K)
    except InputError as exc:
        raise InputError(f"{where}: {exc}") from None
    T_cam_pelvis = np.eye(4)
    T_cam_pelvis[:3, :3] = quat_wxyz_to_matrix(fit.qpos[3:7])
    T_cam_pelvis[:3, 3] = fit.qpos[:3]
    return {
        "keypoint_names": np.array(list(kp.KEYPOINTS)),
        "keypoints_cam_m": keypoints_world(model, fit.qpos),
        "joint_names": np.array(joint_names),
        "joint_angles_rad": fit.qpos[7:].copy(),
        "T_cam_pelvis": T_cam_pelvis,
    }


def _segment(
    name: str,
    rgb: np.ndarray,
    sim_rgb: np.ndarray,
    truth: dict[str, np.ndarray] | None,
    sim_mask: np.ndarray,
    boxes: tuple[tuple[int, int, int, int], tuple[int, int, int, int]] | None,
    cfg: MasksCfg,
    sam: SamSegmenter | None,
    where: str,
) -> tuple[np.ndarray, np.ndarray]:
    """Masks (R_g, R_s) from backend ``name``."""
    if name == "render":
        truth = _require_truth(
            truth,
            f"{where}: masks backend 'render' copies the true masks (grabcut or sam"
            " segment the image from a box)",
        )
        return truth["object_mask"].copy(), sim_mask.copy()
    if boxes is None:
        raise ConfigError(
            f"{where}: masks backend {name!r} is prompted with the object's box, and these "
            "images have none: the paper's open-vocabulary detector is not built; give the "
            "box as object_box_px in the folder backend's subtask_<i>.json"
        )
    if name == "grabcut":
        return (
            grabcut_mask(rgb, boxes[0], cfg.grabcut_iterations),
            grabcut_mask(sim_rgb, boxes[1], cfg.grabcut_iterations),
        )
    assert sam is not None
    return sam(rgb, boxes[0]), sam(sim_rgb, boxes[1])


def _summary(rows: list[dict[str, Any]], cfg: MasksCfg) -> dict[str, Any]:
    metrics: dict[str, Any] = {
        "backend": cfg.backend,
        "keypoint_backend": cfg.keypoints,
        "pose_backend": cfg.pose,
        "seconds_per_subtask": float(np.median([r["seconds"] for r in rows])),
    }
    scored = [r for r in rows if "mask_iou" in r]
    if scored:
        metrics["mask_iou"] = float(np.median([r["mask_iou"][cfg.backend] for r in scored]))
        metrics["mask_iou_min"] = float(min(r["mask_iou"][cfg.backend] for r in scored))
        metrics["sim_mask_iou"] = float(np.median([r["sim_mask_iou"][cfg.backend] for r in scored]))
        metrics["backends"] = {
            name: {
                "mask_iou_median": float(np.median([r["mask_iou"][name] for r in scored])),
                "mask_iou_min": float(min(r["mask_iou"][name] for r in scored)),
                "sim_mask_iou_median": float(np.median([r["sim_mask_iou"][name] for r in scored])),
            }
            for name in scored[0]["mask_iou"]
        }
        err = [r["keypoints"][cfg.keypoints] for r in scored]
        metrics["keypoint_error_median_px"] = median_or_none([e["median_px"] for e in err])
        metrics["keypoint_error_max_px"] = max(
            (e["max_px"] for e in err if e["max_px"] is not None), default=None
        )
        metrics["keypoint_backends"] = {
            name: {
                "median_px": median_or_none([r["keypoints"][name]["median_px"] for r in scored]),
                "detected_fraction": float(
                    np.mean([r["keypoints"][name]["detected_fraction"] for r in scored])
                ),
            }
            for name in scored[0]["keypoints"]
        }
    posed = [r for r in rows if "pose" in r]
    if posed:
        metrics["pose_backends"] = {
            name: {
                key: float(np.median([r["pose"][name][key] for r in posed]))
                for key in posed[0]["pose"][name]
            }
            for name in posed[0]["pose"]
        }
        headline = metrics["pose_backends"][cfg.pose]
        metrics["pose_mpjpe_pelvis_aligned_m"] = headline["mpjpe_pelvis_aligned_m"]
        metrics["pose_rotation_error_deg"] = headline["pelvis_rotation_error_deg"]
    metrics["per_subtask"] = rows
    return metrics


def median_or_none(values: list[float | None]) -> float | None:
    """Median of the values that exist, or None when none does."""
    found = [v for v in values if v is not None]
    return float(np.median(found)) if found else None
