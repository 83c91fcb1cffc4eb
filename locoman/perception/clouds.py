"""Stage ``clouds``: depth and intrinsics of R_g, object point clouds, lifted keypoints.

Paper A, Sec. III-A.2, second step: the masked pixels of R_g are lifted with an estimated
metric depth and the heuristic intrinsics, those of R_s with the simulator's true depth and
intrinsics; statistical outlier removal cleans both clouds.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from locoman.artifacts import (
    read_json,
    read_npz,
    write_metrics,
    write_npz,
    write_png,
)
from locoman.config.perception import CloudsCfg, DepthErrorCfg
from locoman.errors import InputError, SceneError
from locoman.perception import camera
from locoman.perception.contact_sheet import contact_sheet
from locoman.perception.depth import DepthAnythingEstimator, depth_error_model
from locoman.perception.generate import subtask_rng
from locoman.perception.io import (
    CLOUDS,
    CONTACT_SHEETS_DIR,
    MASKS,
    PROMPTS,
    PROMPTS_FILE,
    SIM_VIEW,
    SUBTASKS_DIR,
    read_png,
)
from locoman.perception.masks import load_truth, median_or_none
from locoman.perception.user_images import load_user_input
from locoman.progress import progress

CLOUD_SEED_OFFSET = 2  # the clouds stage draws from its own stream
KEYPOINT_WINDOW_PX = 2  # half size of the window whose median depth lifts a keypoint
CONTACT_KEYPOINTS = ("left_hand", "right_hand", "left_foot", "right_foot")


def voxel_down_sample(points: np.ndarray, voxel_m: float) -> np.ndarray:
    """Centroid [m] of the points (N, 3) in each occupied cube of side ``voxel_m`` [m].

    The grid is Open3D's (``voxel_down_sample``: its origin half a voxel below the cloud's
    minimum), so the centroids are the same up to rounding. They come sorted by voxel index,
    each summed in sorted point order, so the output depends on the set of points only (Open3D's
    order is a hash map's).
    """
    points = points[np.lexsort(points.T[::-1])]
    origin = points.min(axis=0) - 0.5 * voxel_m
    index = np.floor((points - origin) / voxel_m).astype(np.int64)
    _, inverse, counts = np.unique(index, axis=0, return_inverse=True, return_counts=True)
    inverse = inverse.ravel()
    sums = np.stack(
        [np.bincount(inverse, weights=points[:, j], minlength=len(counts)) for j in range(3)],
        axis=1,
    )
    return sums / counts[:, None]


def remove_statistical_outliers(
    points: np.ndarray, neighbours: int, std_ratio: float
) -> np.ndarray:
    """The points (N, 3) [m] whose mean distance to their ``neighbours`` nearest points (the
    point itself among them, as in Open3D's ``remove_statistical_outlier``) is below the mean
    of those distances plus ``std_ratio`` standard deviations."""
    distance, _ = cKDTree(points).query(points, k=neighbours)
    mean = distance.mean(axis=1)
    return points[mean < mean.mean() + std_ratio * mean.std(ddof=1)]


def clean_cloud(points: np.ndarray, cfg: CloudsCfg) -> np.ndarray:
    """Voxel down-sampling, then statistical outlier removal (Sec. III-A.2)."""
    if cfg.voxel_m > 0.0 and len(points):
        points = voxel_down_sample(points, cfg.voxel_m)
    if len(points) > cfg.outlier_neighbours:
        points = remove_statistical_outliers(points, cfg.outlier_neighbours, cfg.outlier_std_ratio)
    return points


def object_cloud(
    depth: np.ndarray, mask: np.ndarray, K: np.ndarray, cfg: CloudsCfg, where: str
) -> np.ndarray:
    """Cleaned camera-frame cloud (N, 3) [m] of the masked pixels.

    Raises:
        SceneError: When the depth has no valid pixel under the mask, or too few points
            survive the cleaning; the message names ``where``.
    """
    valid = mask & (depth > 0.0)
    if not valid.any():
        raise SceneError(f"{where}: the depth map has no valid pixel under the object mask")
    points = clean_cloud(camera.backproject(depth, mask, K), cfg)
    if len(points) < cfg.min_points:
        raise SceneError(
            f"{where}: only {len(points)} object points after outlier removal "
            f"(need perception.clouds.min_points = {cfg.min_points})"
        )
    return points


def lift_keypoints(px: np.ndarray, depth: np.ndarray, K: np.ndarray) -> np.ndarray:
    """Camera-frame points (K, 3) [m] of keypoints: the median valid depth in a small window
    around each; NaN where the keypoint is missing or outside the image or has no depth."""
    h, w = depth.shape
    out = np.full((len(px), 3), np.nan)
    r = KEYPOINT_WINDOW_PX
    for k, (u, v) in enumerate(px):
        if not np.isfinite(u + v):
            continue
        iu, iv = round(float(u)), round(float(v))
        if not (0 <= iu < w and 0 <= iv < h):
            continue
        window = depth[max(iv - r, 0) : iv + r + 1, max(iu - r, 0) : iu + r + 1]
        window = window[window > 0.0]
        if window.size:
            out[k] = camera.pixel_rays(np.array([[u, v]]), K)[0] * float(np.median(window))
    return out


def chamfer(a: np.ndarray, b: np.ndarray) -> float:
    """Symmetric Chamfer distance [m]: the mean of both mean nearest-neighbour distances."""
    return 0.5 * float(cKDTree(b).query(a)[0].mean() + cKDTree(a).query(b)[0].mean())


def estimate_depth(
    rgb: np.ndarray,
    truth: dict[str, np.ndarray] | None,
    user: dict[str, np.ndarray] | None,
    cfg: CloudsCfg,
    error: DepthErrorCfg,
    rng: np.random.Generator,
    estimator: DepthAnythingEstimator | None,
) -> np.ndarray:
    """Depth D_g of a generated image [m] from the configured backend."""
    if estimator is not None:
        return estimator(rgb)
    if cfg.depth == "provided":
        if user is None or not bool(user["depth_given"]):
            raise InputError(
                "perception.clouds.depth = provided reads the depth map that came with a "
                "folder backend image (subtask_<i>_depth.png), and this image has none; use "
                "depth = depth_anything"
            )
        return user["depth_m"]
    if truth is None:
        raise SceneError(
            "perception.clouds.depth = error_model needs the render backend's true depth; "
            "with flux or folder images use depth = depth_anything (or provided)"
        )
    return depth_error_model(truth["depth_m"], error, rng)


def clouds_scenario(
    scenario: str,
    generate_dir: Path,
    masks_dir: Path,
    out_dir: Path,
    cfg: CloudsCfg,
    error: DepthErrorCfg,
    seed: int,
) -> dict[str, Any]:
    """Write depth, clouds, lifted keypoints and a contact sheet per subtask; return metrics."""
    prompts = read_json(generate_dir / PROMPTS_FILE, PROMPTS)
    estimator = (
        DepthAnythingEstimator(cfg.depth_weights_dir, cfg.depth_runtime)
        if cfg.depth == "depth_anything"
        else None
    )
    rows = []
    for entry in progress(prompts["subtasks"], f"clouds {scenario}"):
        i = entry["index"]
        where = f"subtask {i} ({entry['prompt']!r}, object {entry['object']!r})"
        t0 = time.perf_counter()
        rgb = read_png(generate_dir / entry["image"], "generate")
        sim_rgb = read_png(generate_dir / entry["sim_image"], "generate")
        sim = read_npz(generate_dir / entry["sim_view"], SIM_VIEW)
        masks = read_npz(masks_dir / SUBTASKS_DIR / f"subtask_{i}.npz", MASKS)
        truth = load_truth(generate_dir, i)
        rng = subtask_rng(seed + CLOUD_SEED_OFFSET, scenario, i)
        user = load_user_input(generate_dir, i)
        depth = estimate_depth(rgb, truth, user, cfg, error, rng, estimator)
        h, w = depth.shape
        if cfg.intrinsics == "heuristic":
            K = camera.heuristic_intrinsics(w, h)
        else:
            if truth is None:
                raise SceneError(f"{where}: intrinsics = true needs the render backend")
            K = truth["K"]
        gen = object_cloud(depth, masks["object_mask"], K, cfg, f"{where}, generated image")
        sim_cam = object_cloud(
            sim["depth_m"], masks["sim_object_mask"], sim["K"], cfg, f"{where}, simulated view"
        )
        sim_world = camera.transform(sim_cam, sim["T_world_cam"])
        kp3 = lift_keypoints(masks["keypoints_px"], depth, K)
        write_npz(
            out_dir / SUBTASKS_DIR / f"subtask_{i}.npz",
            CLOUDS,
            {
                "depth_m": depth,
                "K": K,
                "points_gen_m": gen,
                "points_sim_m": sim_world,
                "keypoint_names": masks["keypoint_names"],
                "keypoints_cam_m": kp3,
            },
        )
        names = list(masks["keypoint_names"])
        contacts = kp3[[names.index(n) for n in CONTACT_KEYPOINTS]]
        sheet = contact_sheet(
            rgb, sim_rgb, masks, gen, sim_cam, contacts, f"{scenario} #{i}: {entry['prompt']}"
        )
        write_png(out_dir / CONTACT_SHEETS_DIR / f"subtask_{i}.png", sheet)
        row: dict[str, Any] = {
            "index": i,
            "points_gen": len(gen),
            "points_sim": len(sim_world),
            "seconds": time.perf_counter() - t0,
        }
        if truth is not None:
            row |= _score(truth, gen, kp3, names, cfg)
        rows.append(row)
    metrics: dict[str, Any] = {
        "depth": cfg.depth,
        "intrinsics": cfg.intrinsics,
        "depth_scale": error.scale if cfg.depth == "error_model" else None,
        "seconds_per_subtask": float(np.median([r["seconds"] for r in rows])),
    }
    if all("chamfer_m" in r for r in rows):
        chamfers = [r["chamfer_m"] for r in rows]
        metrics |= {
            "chamfer_m": float(np.median(chamfers)),
            "chamfer_max_m": float(max(chamfers)),
            "chamfer_centred_m": float(np.median([r["chamfer_centred_m"] for r in rows])),
            "keypoint_lift_error_median_m": median_or_none(
                [r["keypoint_lift_error_median_m"] for r in rows]
            ),
        }
    metrics["per_subtask"] = rows
    write_metrics(out_dir, metrics)
    return metrics


def _score(
    truth: dict[str, np.ndarray],
    gen: np.ndarray,
    kp3: np.ndarray,
    names: list[str],
    cfg: CloudsCfg,
) -> dict[str, float | None]:
    """Chamfer distance of the R_g cloud to the true visible surface (the true depth lifted
    with the true intrinsics), as is and with both centroids at the origin, and the error of
    the lifted hand and foot points [m]."""
    surface = clean_cloud(
        camera.backproject(truth["depth_m"], truth["object_mask"], truth["K"]), cfg
    )
    true_kp = camera.to_camera(truth["keypoints_world_m"], truth["T_world_cam"])
    idx = [names.index(n) for n in CONTACT_KEYPOINTS]
    err = np.linalg.norm(kp3[idx] - true_kp[idx], axis=1)
    return {
        "chamfer_m": chamfer(gen, surface),
        # Shape alone: registration in contact transfer absorbs a translation.
        "chamfer_centred_m": chamfer(gen - gen.mean(axis=0), surface - surface.mean(axis=0)),
        "keypoint_lift_error_median_m": (
            float(np.nanmedian(err)) if np.isfinite(err).any() else None
        ),
    }
