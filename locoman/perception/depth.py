"""Depth of a generated image (paper A: a zero-shot metric-depth model, Metric3D v2).

``error_model`` passes the true depth through the mistakes such a model makes: a global scale
error, additive noise and missing pixels along depth discontinuities. ``depth_anything`` loads
a transformers depth-estimation checkpoint from a local folder.
"""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np

from locoman.config.perception import DepthErrorCfg, TorchCfg
from locoman.perception.weights import load_transformers, require_package


def depth_edges(depth: np.ndarray, jump_m: float) -> np.ndarray:
    """(H, W) bool: pixels whose right or lower neighbour differs by more than ``jump_m``."""
    edges = np.zeros(depth.shape, bool)
    dx = np.abs(np.diff(depth, axis=1)) > jump_m
    dy = np.abs(np.diff(depth, axis=0)) > jump_m
    edges[:, :-1] |= dx
    edges[:, 1:] |= dx
    edges[:-1, :] |= dy
    edges[1:, :] |= dy
    return edges


def depth_error_model(
    depth: np.ndarray, cfg: DepthErrorCfg, rng: np.random.Generator
) -> np.ndarray:
    """Corrupted depth (H, W) float32 [m]: scale * d + N(0, noise^2), 0 near discontinuities.

    Missing pixels (0) stay missing.
    """
    valid = depth > 0.0
    out = cfg.scale * depth + rng.normal(0.0, cfg.noise_std_m, depth.shape)
    drop = depth_edges(depth, cfg.edge_jump_m)
    if cfg.edge_dropout_px > 0:
        size = 2 * cfg.edge_dropout_px + 1
        drop = cv2.dilate(drop.astype(np.uint8), np.ones((size, size), np.uint8)) > 0
    keep = valid & ~drop & (out > 0.0)
    return np.where(keep, out, 0.0).astype(np.float32)


class DepthAnythingEstimator:
    """A metric depth-estimation checkpoint (transformers ``AutoModelForDepthEstimation``,
    e.g. Depth Anything V2 Metric) from a local folder.

    Args:
        weights_dir: Folder with ``config.json``, weights and ``preprocessor_config.json``.
        runtime: Device and precision.
    """

    def __init__(self, weights_dir: str | None, runtime: TorchCfg) -> None:
        self.model, self.processor, self.device, self.dtype = load_transformers(
            weights_dir,
            "perception.clouds.depth",
            runtime,
            ("AutoModelForDepthEstimation", "AutoImageProcessor"),
            "the depth model",
        )

    def __call__(self, rgb: np.ndarray) -> np.ndarray:
        """Depth (H, W) float32 [m] of an RGB image, resized to the image."""
        torch: Any = require_package("torch")
        inputs = self.processor(images=rgb, return_tensors="pt").to(self.device, self.dtype)
        with torch.no_grad():
            pred = self.model(**inputs).predicted_depth.float()
        pred = torch.nn.functional.interpolate(
            pred[:, None], size=rgb.shape[:2], mode="bicubic", align_corners=False
        )
        return pred[0, 0].clamp(min=0.0).cpu().numpy().astype(np.float32)
