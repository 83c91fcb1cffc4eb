"""A contact sheet per subtask: what a person checks at a glance.

Tiles, left to right: R_g with the object mask and the skeleton; R_s with its mask; the R_g
cloud with the lifted hands and feet; the R_s cloud. Clouds are drawn in their camera's frame,
turned about the image's vertical axis so that their depth shows, coloured by depth.
"""

from __future__ import annotations

import cv2
import numpy as np

from locoman.perception.demonstrator import SKELETON

TILE = 320  # [px]
MASK_RGB = np.array([255, 40, 40])
EFFECTOR_RGB = {
    "left_hand": (255, 220, 0),
    "right_hand": (0, 200, 255),
    "left_foot": (255, 120, 0),
    "right_foot": (0, 90, 255),
}
CLOUD_TURN = np.deg2rad(35.0)  # [rad] rotation of the cloud views about the image's y axis


def _tile(image: np.ndarray) -> np.ndarray:
    return cv2.resize(image, (TILE, TILE), interpolation=cv2.INTER_AREA)


def overlay(rgb: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """The image with the mask tinted red and outlined."""
    out = rgb.astype(float)
    out[mask] = 0.55 * out[mask] + 0.45 * MASK_RGB
    out = out.astype(np.uint8)
    contours, _ = cv2.findContours(mask.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    cv2.drawContours(out, contours, -1, (255, 0, 0), 2)
    return out


def draw_skeleton(rgb: np.ndarray, names: list[str], px: np.ndarray) -> np.ndarray:
    """Bones in white, hands and feet as coloured discs."""
    out = rgb.copy()
    index = {n: k for k, n in enumerate(names)}
    for a, b in SKELETON:
        pa, pb = px[index[a]], px[index[b]]
        if np.isfinite(pa).all() and np.isfinite(pb).all():
            cv2.line(out, tuple(int(v) for v in pa), tuple(int(v) for v in pb), (255, 255, 255), 2)
    for name, colour in EFFECTOR_RGB.items():
        p = px[index[name]]
        if np.isfinite(p).all():
            cv2.circle(out, tuple(int(v) for v in p), 6, colour, -1)
    return out


def cloud_view(points: np.ndarray, marks: np.ndarray | None = None) -> np.ndarray:
    """An orthographic picture (TILE, TILE, 3) of a camera-frame cloud, coloured by depth.

    Args:
        points: (N, 3) camera frame (x right, y down, z forward) [m].
        marks: Optional (M, 3) points drawn as discs in :data:`EFFECTOR_RGB` order.
    """
    image = np.full((TILE, TILE, 3), 30, np.uint8)
    c, s = np.cos(CLOUD_TURN), np.sin(CLOUD_TURN)
    turn = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])
    centre = points.mean(axis=0)
    p = (points - centre) @ turn.T
    extent = max(float(np.abs(p[:, :2]).max()), 1e-6)
    scale = 0.42 * TILE / extent

    def to_px(q: np.ndarray) -> np.ndarray:
        return (q[:, :2] * scale + 0.5 * TILE).astype(int)

    order = np.argsort(-p[:, 2])  # far points first, near ones drawn over them
    z = p[order, 2]
    shade = ((z - z.min()) / max(float(np.ptp(z)), 1e-6) * 255).astype(np.uint8)
    colours = cv2.applyColorMap(shade[:, None], cv2.COLORMAP_VIRIDIS)[:, 0, ::-1]
    for (u, v), col in zip(to_px(p[order]), colours, strict=True):
        if 0 <= u < TILE and 0 <= v < TILE:
            image[v, u] = col
    if marks is not None:
        for q, colour in zip(marks, EFFECTOR_RGB.values(), strict=True):
            if np.isfinite(q).all():
                u, v = to_px(((q - centre) @ turn.T)[None])[0]
                cv2.circle(image, (int(u), int(v)), 6, colour, -1)
    return image


def contact_sheet(
    rgb: np.ndarray,
    sim_rgb: np.ndarray,
    masks: dict[str, np.ndarray],
    gen_cloud: np.ndarray,
    sim_cloud_cam: np.ndarray,
    contact_points: np.ndarray,
    title: str,
) -> np.ndarray:
    """The sheet (H, W, 3) uint8; ``contact_points`` (4, 3) are the lifted hands and feet."""
    names = [str(n) for n in masks["keypoint_names"]]
    tiles = [
        _tile(draw_skeleton(overlay(rgb, masks["object_mask"]), names, masks["keypoints_px"])),
        _tile(overlay(sim_rgb, masks["sim_object_mask"])),
        cloud_view(gen_cloud, contact_points),
        cloud_view(sim_cloud_cam),
    ]
    labels = ("R_g: mask + keypoints", "R_s: mask", "R_g cloud + hands/feet", "R_s cloud")
    for tile, label in zip(tiles, labels, strict=True):
        cv2.putText(tile, label, (6, 18), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (255, 255, 255), 1)
    banner = np.full((28, TILE * len(tiles), 3), 255, np.uint8)
    cv2.putText(banner, title[:110], (6, 19), cv2.FONT_HERSHEY_SIMPLEX, 0.55, (0, 0, 0), 1)
    return np.vstack([banner, np.hstack(tiles)])
