"""The picture of one subtask's contact transfer, for a person to check.

Left: R_g with the points sampled for the score pool and the 2D hands and feet. Right: R_s
with the registered R_g cloud projected into it (small cyan dots: where registration put the
generated object) and the contacts drawn on the simulated object: true (green ring), the
registration method (blue disc) and the naive baseline (red cross), each labelled LH, RH, LF,
RF. The footer gives each contact's error per method when the ground truth is known.
"""

from __future__ import annotations

import cv2
import numpy as np

from locoman.artifacts.pictures import fit_tile
from locoman.contact.kabsch import apply
from locoman.contact.transfer import SubtaskInputs, Transfer
from locoman.perception import camera

TILE = 420  # [px]
TRUE_RGB = (40, 200, 40)
OURS_RGB = (30, 90, 255)
NAIVE_RGB = (230, 30, 30)
CLOUD_RGB = (0, 220, 220)
POOL_RGB = (255, 230, 0)


def _label(effector: str) -> str:
    side, part = effector.split("_")
    return f"{side[0]}{part[0]}".upper()


def _project(points_world: np.ndarray, inputs: SubtaskInputs, scale: float) -> np.ndarray:
    cam = camera.to_camera(points_world, inputs.T_world_sim)
    px = camera.project(cam, inputs.sim_K) * scale
    px[cam[:, 2] <= 0.0] = np.nan
    return px


def _inside(p: np.ndarray) -> bool:
    return bool(np.isfinite(p).all() and 0 <= p[0] < TILE and 0 <= p[1] < TILE)


def contact_plot(
    inputs: SubtaskInputs, result: Transfer, truth_world: np.ndarray | None, title: str
) -> np.ndarray:
    """The picture (H, W, 3) uint8 of a subtask."""
    left, g_scale = fit_tile(inputs.rgb, TILE)
    for u, v in result.pool.gen_px * g_scale:
        cv2.circle(left, (int(u), int(v)), 2, POOL_RGB, -1)
    names = inputs.keypoint_names
    for e in inputs.effectors:
        p = inputs.keypoints_px[names.index(e)] * g_scale
        if np.isfinite(p).all():
            cv2.circle(left, (int(p[0]), int(p[1])), 6, OURS_RGB, 2)
            cv2.putText(
                left,
                _label(e),
                (int(p[0]) + 7, int(p[1]) - 5),
                cv2.FONT_HERSHEY_SIMPLEX,
                0.45,
                OURS_RGB,
                1,
            )
    right, s_scale = fit_tile(inputs.sim_rgb, TILE)
    cloud = _project(
        apply(result.registration.affine, result.anchor.undo(inputs.cloud[::3])), inputs, s_scale
    )
    for p in cloud:
        if _inside(p):
            right[int(p[1]), int(p[0])] = CLOUD_RGB
    footer = []
    for k, e in enumerate(inputs.effectors):
        label = _label(e)
        if truth_world is not None:
            p = _project(truth_world[k : k + 1], inputs, s_scale)[0]
            if _inside(p):
                cv2.circle(right, (int(p[0]), int(p[1])), 9, TRUE_RGB, 2)
        p = _project(result.points_world[k : k + 1], inputs, s_scale)[0]
        if _inside(p):
            cv2.circle(right, (int(p[0]), int(p[1])), 5, OURS_RGB, -1)
            cv2.putText(
                right,
                label,
                (int(p[0]) + 8, int(p[1]) - 6),
                cv2.FONT_HERSHEY_SIMPLEX,
                0.45,
                OURS_RGB,
                1,
            )
        p = _project(result.naive_world[k : k + 1], inputs, s_scale)[0]
        if _inside(p):
            c = (int(p[0]), int(p[1]))
            cv2.drawMarker(right, c, NAIVE_RGB, cv2.MARKER_TILTED_CROSS, 12, 2)
            cv2.putText(
                right, label, (c[0] + 8, c[1] + 14), cv2.FONT_HERSHEY_SIMPLEX, 0.45, NAIVE_RGB, 1
            )
        if truth_world is not None:
            ours = np.linalg.norm(result.points_world[k] - truth_world[k]) * 100
            naive = np.linalg.norm(result.naive_world[k] - truth_world[k]) * 100
            footer.append(f"{label}: {ours:.1f} / {naive:.1f} cm")
    cv2.putText(
        left, "R_g: pool points, hands/feet", (6, 18), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (0, 0, 0), 1
    )
    cv2.putText(
        right,
        "R_s: registered cloud, contacts",
        (6, 18),
        cv2.FONT_HERSHEY_SIMPLEX,
        0.5,
        (0, 0, 0),
        1,
    )
    banner = np.full((28, 2 * TILE, 3), 255, np.uint8)
    cv2.putText(banner, title[:90], (6, 19), cv2.FONT_HERSHEY_SIMPLEX, 0.55, (0, 0, 0), 1)
    legend = np.full((48, 2 * TILE, 3), 255, np.uint8)
    x = 6
    keys = [("registration", OURS_RGB), ("naive", NAIVE_RGB)]
    # Images without ground truth (flux, folder) have nothing to draw in green: say so.
    keys = (
        [("true", TRUE_RGB), *keys] if truth_world is not None else [*keys, ("no truth", (0, 0, 0))]
    )
    for text, colour in keys:
        cv2.putText(legend, text, (x, 18), cv2.FONT_HERSHEY_SIMPLEX, 0.5, colour, 2)
        x += 14 * len(text) + 20
    if footer:
        cv2.putText(
            legend,
            "error registration / naive: " + ",  ".join(footer),
            (6, 40),
            cv2.FONT_HERSHEY_SIMPLEX,
            0.45,
            (0, 0, 0),
            1,
        )
    return np.vstack([banner, np.hstack([left, right]), legend])
