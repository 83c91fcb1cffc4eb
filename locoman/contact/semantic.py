"""The semantic score pool: plausible matches between the object in R_g and in R_s.

Paper A, Sec. III-A.2: "we generate a semantic score pool for some sampled 2D points on the
objects' masks found in R_g, such that for each sampled point we obtain the top N most
plausible correspondences in the respective objects' masks found in R_s". The paper uses a
semantic-aware foundation model [24]. Two backends describe a pixel here:

- ``sift`` (CPU default): a SIFT descriptor on a patch whose size follows the object's size in
  the image (so both views describe the same part of the object at the same scale), plus the
  pixel's position in the object's bounding box, the layout cue ("top left corner") that
  semantic features carry.
- ``learned``: a TorchScript feature extractor (e.g. an exported DINOv2 or SD+DINO backbone)
  mapping an image (1, 3, H, W) in [0, 1] to a feature map (1, C, h, w), sampled bilinearly.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Protocol

import cv2
import numpy as np

from locoman.config.contacts import PoolCfg
from locoman.errors import ModelError, SceneError
from locoman.perception.weights import require_package

MIN_POOL_POINTS = 3  # an SVD needs three matches
OBJECT_SIZE_PX = 96.0  # [px] the object's box is resized to this geometric-mean size for SIFT


@dataclasses.dataclass(frozen=True)
class ScorePool:
    """For each of S points sampled in R_g, the top-N candidate pixels in R_s.

    Attributes:
        gen_px: (S, 2) sampled (u, v) pixel indices in R_g [px].
        sim_px: (S, N, 2) candidate pixel indices in R_s, best first [px].
        scores: (S, N) cosine similarities of the candidates, in [-1, 1].
    """

    gen_px: np.ndarray
    sim_px: np.ndarray
    scores: np.ndarray


class Describer(Protocol):
    """Dense descriptors (P, D), unit norm, of pixels (P, 2) on an object."""

    def __call__(self, rgb: np.ndarray, mask: np.ndarray, px: np.ndarray) -> np.ndarray: ...


def mask_box(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Lower (u, v) corner and size (w, h) of a mask's bounding box [px]."""
    vs, us = np.nonzero(mask)
    lo = np.array([us.min(), vs.min()], dtype=float)
    return lo, np.array([us.max(), vs.max()], dtype=float) - lo + 1.0


@dataclasses.dataclass(frozen=True)
class SiftDescriber:
    """Dense SIFT on a patch scaled to the object, concatenated with the box layout."""

    patch_fraction: float
    layout_weight: float

    def __call__(self, rgb: np.ndarray, mask: np.ndarray, px: np.ndarray) -> np.ndarray:
        lo, size = mask_box(mask)
        # Describe at a common object size: both views then see parts of the same size, and
        # SIFT's cost no longer grows with the object's size in the image.
        zoom = OBJECT_SIZE_PX / float(np.sqrt(size[0] * size[1]))
        gray = cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)
        gray = cv2.resize(gray, None, fx=zoom, fy=zoom, interpolation=cv2.INTER_AREA)
        patch = max(self.patch_fraction * OBJECT_SIZE_PX, 4.0)
        keypoints = [cv2.KeyPoint(float(u), float(v), patch, 0.0) for u, v in (px + 0.5) * zoom]
        _, desc = cv2.SIFT_create().compute(gray, keypoints)
        if desc is None or len(desc) != len(px):
            raise SceneError("SIFT dropped keypoints on the object mask; check the mask")
        desc = desc / np.maximum(np.linalg.norm(desc, axis=1, keepdims=True), 1e-9)
        layout = self.layout_weight * ((px - lo) / size - 0.5)
        out = np.hstack([desc, layout])
        return out / np.maximum(np.linalg.norm(out, axis=1, keepdims=True), 1e-9)


class LearnedDescriber:
    """Features of a TorchScript backbone, sampled at the pixels.

    Raises:
        ModelError: When no file is configured, the file is missing, or it does not load.
    """

    def __init__(self, weights_file: str | None) -> None:
        if weights_file is None:
            raise ModelError(
                "contacts.pool.descriptor = learned needs contacts.pool.weights_file: a "
                "TorchScript feature extractor (torch.jit.save of a traced backbone, e.g. "
                "DINOv2) mapping (1, 3, H, W) in [0, 1] to (1, C, h, w); or use descriptor = sift"
            )
        path = Path(weights_file)
        if not path.is_file():
            raise ModelError(
                f"contacts.pool.weights_file {path} does not exist (nothing is "
                "downloaded; copy the exported backbone there)"
            )
        torch = require_package("torch")
        try:
            self._model = torch.jit.load(str(path), map_location="cpu").eval()
        except (RuntimeError, ValueError) as err:
            raise ModelError(f"{path} is not a TorchScript module: {err}") from err
        self._torch = torch

    def __call__(self, rgb: np.ndarray, mask: np.ndarray, px: np.ndarray) -> np.ndarray:
        torch = self._torch
        image = torch.from_numpy(np.ascontiguousarray(rgb)).permute(2, 0, 1)[None].float() / 255
        with torch.no_grad():
            features = self._model(image)
        if features.ndim != 4:
            raise ModelError(f"the backbone returned shape {tuple(features.shape)}, not (1,C,h,w)")
        h, w = rgb.shape[:2]
        # align_corners=False: pixel index u sits at normalised (2u + 1) / w - 1.
        grid = torch.from_numpy(
            np.stack([(2 * px[:, 0] + 1) / w - 1, (2 * px[:, 1] + 1) / h - 1], axis=1)
        ).float()[None, :, None, :]
        sampled = torch.nn.functional.grid_sample(features, grid, align_corners=False)
        desc = sampled[0, :, :, 0].T.numpy().astype(float)
        return desc / np.maximum(np.linalg.norm(desc, axis=1, keepdims=True), 1e-9)


def make_describer(cfg: PoolCfg) -> Describer:
    """The configured descriptor backend."""
    if cfg.descriptor == "learned":
        return LearnedDescriber(cfg.weights_file)
    return SiftDescriber(cfg.patch_fraction, cfg.layout_weight)


def mask_pixels(mask: np.ndarray, valid: np.ndarray, step: int) -> np.ndarray:
    """(u, v) pixel indices (P, 2) on a grid of spacing ``step`` where mask and valid hold."""
    keep = mask & valid
    grid = np.zeros_like(keep)
    grid[::step, ::step] = True
    vs, us = np.nonzero(keep & grid)
    return np.column_stack([us, vs]).astype(float)


def sample_pixels(
    mask: np.ndarray, valid: np.ndarray, count: int, rng: np.random.Generator, where: str
) -> np.ndarray:
    """``count`` distinct pixels (u, v) spread over a mask by farthest-point sampling.

    Raises:
        SceneError: When the mask has fewer usable pixels than an SVD needs.
    """
    vs, us = np.nonzero(mask & valid)
    if len(us) < MIN_POOL_POINTS:
        raise SceneError(
            f"{where}: the object mask has {len(us)} pixels with depth; contact transfer "
            f"needs at least {MIN_POOL_POINTS} (is the object visible and segmented?)"
        )
    px = np.column_stack([us, vs]).astype(float)
    chosen = [int(rng.integers(len(px)))]
    dist = np.linalg.norm(px - px[chosen[0]], axis=1)
    for _ in range(min(count, len(px)) - 1):
        chosen.append(int(dist.argmax()))
        dist = np.minimum(dist, np.linalg.norm(px - px[chosen[-1]], axis=1))
    return px[chosen]


def score_pool(
    gen_desc: np.ndarray, sim_desc: np.ndarray, sim_px: np.ndarray, gen_px: np.ndarray, top_n: int
) -> ScorePool:
    """Top-N candidates in R_s for each described point of R_g, by cosine similarity."""
    scores = gen_desc @ sim_desc.T
    n = min(top_n, scores.shape[1])
    top = np.argsort(-scores, axis=1, kind="stable")[:, :n]
    return ScorePool(gen_px, sim_px[top], np.take_along_axis(scores, top, axis=1))
