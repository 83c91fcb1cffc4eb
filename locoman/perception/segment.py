"""Object masks (paper A, Sec. III-A.2, first step).

The paper detects the object with an open-vocabulary VLM (a box) and refines the box into a
per-pixel mask with SAM 2. Here the box comes from the object's true extent in the image plus
a margin (standing in for the detector), and the refinement is GrabCut (OpenCV, runs
anywhere) or a SAM checkpoint loaded from a local folder.
"""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np

from locoman.config.perception import TorchCfg
from locoman.errors import SceneError
from locoman.perception.weights import load_transformers, require_package


def mask_iou(a: np.ndarray, b: np.ndarray) -> float:
    """Intersection over union of two boolean masks [-] (1 when both are empty)."""
    union = np.logical_or(a, b).sum()
    return 1.0 if union == 0 else float(np.logical_and(a, b).sum() / union)


def check_mask(mask: np.ndarray, where: str, min_pixels: int = 1) -> np.ndarray:
    """Return ``mask``; raise naming ``where`` when it has fewer than ``min_pixels`` pixels."""
    if int(mask.sum()) < min_pixels:
        raise SceneError(
            f"{where}: the object mask is empty ({int(mask.sum())} pixels); the object is not "
            "in the image or the segmenter missed it"
        )
    return mask


def box_around(mask: np.ndarray, margin: int) -> tuple[int, int, int, int]:
    """(x0, y0, x1, y1) [px] of the mask's bounding box grown by ``margin``, in the image."""
    v, u = np.nonzero(mask)
    h, w = mask.shape
    return (
        max(int(u.min()) - margin, 0),
        max(int(v.min()) - margin, 0),
        min(int(u.max()) + margin, w - 1),
        min(int(v.max()) + margin, h - 1),
    )


def grabcut_mask(rgb: np.ndarray, box: tuple[int, int, int, int], iterations: int) -> np.ndarray:
    """GrabCut foreground (H, W) bool inside ``box`` (x0, y0, x1, y1) [px].

    OpenCV's GrabCut draws from ``cv2.theRNG``, which is seeded here so masks are reproducible.
    """
    cv2.setRNGSeed(0)
    x0, y0, x1, y1 = box
    labels = np.zeros(rgb.shape[:2], np.uint8)
    bgd, fgd = np.zeros((1, 65), np.float64), np.zeros((1, 65), np.float64)
    bgr = np.ascontiguousarray(rgb[:, :, ::-1])
    cv2.grabCut(
        bgr, labels, (x0, y0, x1 - x0 + 1, y1 - y0 + 1), bgd, fgd, iterations, cv2.GC_INIT_WITH_RECT
    )
    return (labels == cv2.GC_FGD) | (labels == cv2.GC_PR_FGD)


class SamSegmenter:
    """A Segment Anything checkpoint (transformers ``SamModel``) prompted with a box.

    Args:
        weights_dir: Folder with ``config.json``, the weights and the processor's
            ``preprocessor_config.json`` (written by ``save_pretrained``).
        runtime: Device and precision.
    """

    def __init__(self, weights_dir: str | None, runtime: TorchCfg) -> None:
        self.model, self.processor, self.device, self.dtype = load_transformers(
            weights_dir,
            "perception.masks.sam",
            runtime,
            ("SamModel", "SamProcessor"),
            "the SAM checkpoint",
        )

    def __call__(self, rgb: np.ndarray, box: tuple[int, int, int, int]) -> np.ndarray:
        """The best-scoring mask (H, W) bool for ``box`` (x0, y0, x1, y1) [px]."""
        torch: Any = require_package("torch")
        inputs = self.processor(
            images=rgb, input_boxes=[[[float(c) for c in box]]], return_tensors="pt"
        ).to(self.device, self.dtype)  # BatchFeature.to casts the floating tensors only
        with torch.no_grad():
            out = self.model(**inputs, multimask_output=True)
        masks = self.processor.image_processor.post_process_masks(
            out.pred_masks.float().cpu(),
            inputs["original_sizes"].cpu(),
            inputs["reshaped_input_sizes"].cpu(),
        )[0][0]
        best = int(out.iou_scores[0, 0].argmax())
        return masks[best].numpy().astype(bool)
