"""Helpers for the PNG pictures that stages write for a person to look at."""

from __future__ import annotations

import cv2
import numpy as np


def fit_tile(image: np.ndarray, size: int) -> tuple[np.ndarray, float]:
    """The image scaled to fit a white ``size`` x ``size`` square (top-left aligned), and
    the scale applied."""
    h, w = image.shape[:2]
    scale = size / max(h, w)
    tile = cv2.resize(image, (round(w * scale), round(h * scale)))
    pad = ((0, size - tile.shape[0]), (0, size - tile.shape[1]), (0, 0))
    return np.pad(tile, pad, constant_values=255), scale
