"""Stage ``masks``: object masks in R_g and R_s, 2D keypoints and the 3D pose in R_g.

Every backend that can run is scored against the ground truth (mask IoU, keypoint error in
pixels), whichever one is selected, so one run gives the comparison table.
"""

from __future__ import annotations

import contextlib
import time
from pathlib import Path
from typing import Any

import numpy as np

from locoman.artifacts import read_json, read_npz, write_metrics, write_npz
from locoman.config.perception import MasksCfg
from locoman.errors import ConfigError, ModelError
from locoman.perception import keypoints as kp
from locoman.perception.generate import subtask_rng
from locoman.perception.io import (
    GROUND_TRUTH,
    GROUND_TRUTH_DIR,
    MASKS,
    POSE,
    PROMPTS,
    PROMPTS_FILE,
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
from locoman.progress import progress
from locoman.scene import human

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
    joint_names = [human.human_pinocchio_model().names[j] for j in range(2, 38)]
    rows = []
    for entry in progress(prompts["subtasks"], f"masks {scenario}"):
        i = entry["index"]
        where = f"subtask {i} ({entry['prompt']!r}, object {entry['object']!r})"
        t0 = time.perf_counter()
        rgb = read_png(generate_dir / entry["image"], "generate")
        sim_rgb = read_png(generate_dir / entry["sim_image"], "generate")
        truth = load_truth(generate_dir, i)
        segmenters = {"render": None, "grabcut": None}
        if sam is not None:
            segmenters["sam"] = sam
        results: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        for name in segmenters:
            if name != cfg.backend and truth is None:
                continue
            results[name] = _segment(name, rgb, sim_rgb, truth, cfg, sam, where)
        obj_mask, sim_mask = results[cfg.backend]
        check_mask(obj_mask, f"{where}, generated image")
        check_mask(sim_mask, f"{where}, simulated view")
        rng = subtask_rng(seed + MASK_SEED_OFFSET, scenario, i)
        names = np.array(list(kp.KEYPOINTS))
        if cfg.keypoints == "render":
            px, conf = kp.jittered_keypoints(
                _require_truth(
                    truth,
                    "perception.masks.keypoints=render jitters the true keypoints "
                    "(keypoints=mediapipe detects them)",
                ),
                cfg.keypoint_jitter_px,
                rng,
            )
        else:
            px, conf = kp.mediapipe_keypoints(rgb)
        write_npz(
            out_dir / SUBTASKS_DIR / f"subtask_{i}.npz",
            MASKS,
            {
                "object_mask": obj_mask,
                "sim_object_mask": sim_mask,
                "keypoint_names": names,
                "keypoints_px": px,
                "keypoint_confidence": conf,
            },
        )
        pose = kp.pose_estimate(
            _require_truth(
                truth,
                "the 3D human pose perturbs the true pose (a 3D pose estimator from images "
                "is not built)",
            ),
            joint_names,
            cfg.pose_noise_m,
            cfg.pose_noise_rad,
            rng,
        )
        write_npz(out_dir / SUBTASKS_DIR / f"pose_{i}.npz", POSE, pose)
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
        rows.append(row)
    metrics = _summary(rows, cfg)
    write_metrics(out_dir, metrics)
    return metrics


def _segment(
    name: str,
    rgb: np.ndarray,
    sim_rgb: np.ndarray,
    truth: dict[str, np.ndarray] | None,
    cfg: MasksCfg,
    sam: SamSegmenter | None,
    where: str,
) -> tuple[np.ndarray, np.ndarray]:
    """Masks (R_g, R_s) from backend ``name``."""
    truth = _require_truth(
        truth,
        f"{where}: masks backend {name!r} is prompted with a box around the true mask, "
        "standing in for the paper's open-vocabulary detector (not built)",
    )
    gen_true = check_mask(truth["object_mask"], f"{where}, generated image")
    sim_true = check_mask(truth["sim_object_mask"], f"{where}, simulated view")
    if name == "render":
        return gen_true.copy(), sim_true.copy()
    boxes = box_around(gen_true, cfg.box_margin_px), box_around(sim_true, cfg.box_margin_px)
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
    metrics["per_subtask"] = rows
    return metrics


def median_or_none(values: list[float | None]) -> float | None:
    """Median of the values that exist, or None when none does."""
    found = [v for v in values if v is not None]
    return float(np.median(found)) if found else None
