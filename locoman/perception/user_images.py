"""The ``folder`` image backend: R_g from a folder of the user's images.

For images generated elsewhere (a diffusion model on a GPU machine, an online service) or
photographed. ``perception.generate.folder.images_dir`` (relative to the repository root)
holds, per subtask ``i`` of the
scenario's plan (``data/<scenario>/scene/plan.json``, indices from 0)::

    subtask_<i>.png | subtask_<i>.jpg   R_g: RGB, RGBA or grey, 8 or 16 bits a channel (taken
                                        as 8-bit RGB: alpha dropped), 64-4096 px a side
    subtask_<i>.json                    optional annotations, any of:
        {"object_box_px": [u0, v0, u1, v1],            the object's box, pixel indices
         "keypoints_px": {"left_hand": [u, v], ...}}   2D keypoints, any of KEYPOINTS
    subtask_<i>_depth.png               optional metric depth: 16-bit [mm], 0 = unknown, the
                                        image's size (an RGB-D camera, or a depth network run
                                        elsewhere)

Every subtask needs its image and nothing else may be named ``subtask_*``. The camera is paper
A's assumption for a generated image: focal length = image resolution, principal point at the
centre (``perception.clouds.intrinsics = heuristic``); pixel (u, v) is the pixel's index.

What the steps downstream take from the folder: the box prompts ``grabcut`` / ``sam``
(``perception.masks.backend``), standing in for paper A's open-vocabulary detector;
``keypoints_px`` with ``perception.masks.keypoints = annotated``; the depth maps with
``perception.clouds.depth = provided``. Nothing is scored: there is no ground truth.
"""

from __future__ import annotations

import hashlib
import json
import re
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from locoman.artifacts import ArtifactSchema, Field, read_npz, write_png
from locoman.artifacts.io import write_bytes_atomic
from locoman.errors import InputError
from locoman.perception.demonstrator import KEYPOINTS
from locoman.perception.io import GROUND_TRUTH, GROUND_TRUTH_DIR, KEYPOINTS_PX, subtask_dir
from locoman.perception.segment import box_around

USER_INPUT_FILE = "user_input.npz"
USER_INPUT = ArtifactSchema(
    "perception.user_input",
    1,
    "generate",
    (
        Field(
            "object_box_px",
            "float64",
            (4,),
            "px",
            "(u0, v0, u1, v1) of the object in R_g; NaN when not given",
            nan_allowed=True,
        ),
        Field("keypoint_names", "str", ("K",)),
        KEYPOINTS_PX,
        Field("depth_m", "float32", ("H", "W"), "m", "depth of R_g, 0 = unknown or not given"),
        Field("depth_given", "bool", (), "-", "a depth map came with the image"),
    ),
)
ANNOTATION_KEYS = ("object_box_px", "keypoints_px")
MIN_SIDE_PX, MAX_SIDE_PX = 64, 4096
NAME = re.compile(r"subtask_(\d+)(?:\.png|\.jpg|\.json|_depth\.png)")


def load_user_input(generate_dir: Path, index: int) -> dict[str, np.ndarray] | None:
    """What came with subtask ``index``'s image, or None when the backend was not ``folder``."""
    path = subtask_dir(generate_dir, index) / USER_INPUT_FILE
    return read_npz(path, USER_INPUT) if path.is_file() else None


def resolve_images_dir(images_dir: str) -> Path:
    """The folder (a relative path is taken from the working directory: the repository root
    under ``dvc repro``), or an :class:`InputError`."""
    path = Path(images_dir).expanduser()
    if not path.is_dir():
        raise InputError(
            f"perception.generate.folder.images_dir: no folder {path}; put one image per "
            "subtask there (subtask_<i>.png, see docs/perception.md)"
        )
    return path


def check_folder(folder: Path, indices: list[int]) -> None:
    """Every subtask has one image; no file named ``subtask_*`` belongs to no subtask."""
    expected = sorted(indices)
    for path in sorted(folder.glob("subtask_*")):
        match = NAME.fullmatch(path.name)
        if match is None or int(match.group(1)) not in expected:
            raise InputError(
                f"{path}: not a file of this plan's subtasks {expected} (expected "
                "subtask_<i>.png or .jpg, subtask_<i>.json, subtask_<i>_depth.png)"
            )
    for i in expected:
        found = [folder / f"subtask_{i}{ext}" for ext in (".png", ".jpg")]
        found = [p for p in found if p.is_file()]
        if len(found) != 1:
            what = "no image" if not found else "two images"
            raise InputError(
                f"{folder}: {what} for subtask {i}; the plan's subtasks {expected} need "
                "one subtask_<i>.png or subtask_<i>.jpg each"
            )


def read_user_image(folder: Path, index: int) -> tuple[np.ndarray, dict[str, np.ndarray], str]:
    """R_g (H, W, 3) uint8, the ``perception.user_input`` arrays of subtask ``index`` and the
    SHA-256 of its files (what DVC cannot see: the folder is outside the pipeline)."""
    image_path = next(
        p for p in (folder / f"subtask_{index}{e}" for e in (".png", ".jpg")) if p.is_file()
    )
    digest = hashlib.sha256(image_path.read_bytes())
    rgb = _as_rgb8(image_path, cv2.imread(str(image_path), cv2.IMREAD_UNCHANGED))
    h, w = rgb.shape[:2]
    if not (MIN_SIDE_PX <= h <= MAX_SIDE_PX and MIN_SIDE_PX <= w <= MAX_SIDE_PX):
        raise InputError(
            f"{image_path}: {w} x {h} px; each side must be {MIN_SIDE_PX}-{MAX_SIDE_PX} px: "
            "scale the image (and the pixels of its annotations and depth) to fit"
        )
    names = list(KEYPOINTS)
    box, keypoints = np.full(4, np.nan), np.full((len(names), 2), np.nan)
    notes = folder / f"subtask_{index}.json"
    if notes.is_file():
        digest.update(notes.read_bytes())
        box, keypoints = _annotations(notes, names, w, h)
    depth = np.zeros((h, w), np.float32)
    depth_path = folder / f"subtask_{index}_depth.png"
    if depth_path.is_file():
        digest.update(depth_path.read_bytes())
        depth = _depth(depth_path, w, h)
    arrays = {
        "object_box_px": box,
        "keypoint_names": np.array(names),
        "keypoints_px": keypoints,
        "depth_m": depth,
        "depth_given": np.array(depth_path.is_file()),
    }
    return rgb, arrays, digest.hexdigest()


def _as_rgb8(path: Path, raw: np.ndarray | None) -> np.ndarray:
    """An image as read by OpenCV (grey, BGR or BGRA, which is how it reads a grey PNG with
    alpha; 8 or 16 bits) as 8-bit RGB (H, W, 3): grey spread over the channels, alpha
    dropped, 16 bits to their high byte.

    Raises:
        InputError: It is no image OpenCV reads, or of a kind none of these is.
    """
    if raw is None:
        raise InputError(f"{path}: not an image OpenCV can read (a PNG or JPEG is)")
    if raw.dtype == np.uint16:
        raw = (raw >> 8).astype(np.uint8)
    if raw.dtype != np.uint8:
        raise InputError(f"{path}: {raw.dtype} pixels; save it with 8 or 16 bits a channel")
    if raw.ndim == 2:
        return np.ascontiguousarray(np.repeat(raw[..., None], 3, axis=2))
    if raw.ndim == 3 and raw.shape[2] in (3, 4):
        return np.ascontiguousarray(cv2.cvtColor(raw[..., :3], cv2.COLOR_BGR2RGB))
    raise InputError(f"{path}: an image of shape {raw.shape}; save it as RGB, RGBA or grey")


def _annotations(path: Path, names: list[str], w: int, h: int) -> tuple[np.ndarray, np.ndarray]:
    try:
        notes = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: not JSON ({exc})") from None
    if not isinstance(notes, dict) or set(notes) - set(ANNOTATION_KEYS):
        raise InputError(f"{path}: an object with the keys {list(ANNOTATION_KEYS)} (any of them)")
    box = np.full(4, np.nan)
    if "object_box_px" in notes:
        box = _numbers(notes["object_box_px"], 4, f"{path}: object_box_px")
        if not (0 <= box[0] < box[2] <= w and 0 <= box[1] < box[3] <= h):
            raise InputError(
                f"{path}: object_box_px {box.tolist()} must be [u0, v0, u1, v1] with "
                f"0 <= u0 < u1 <= {w} and 0 <= v0 < v1 <= {h}"
            )
    keypoints = np.full((len(names), 2), np.nan)
    given = notes.get("keypoints_px", {})
    if not isinstance(given, dict) or set(given) - set(names):
        raise InputError(f"{path}: keypoints_px maps names among {names} to [u, v]")
    for name, uv in given.items():
        keypoints[names.index(name)] = _numbers(uv, 2, f"{path}: keypoints_px.{name}")
    return box, keypoints


def _numbers(value: Any, n: int, where: str) -> np.ndarray:
    try:
        out = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        out = np.empty(0)
    if out.shape != (n,) or not np.all(np.isfinite(out)):
        raise InputError(f"{where}: needs {n} finite numbers, got {value!r}")
    return out


def _depth(path: Path, w: int, h: int) -> np.ndarray:
    raw = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if raw is None or raw.dtype != np.uint16 or raw.ndim != 2:
        raise InputError(f"{path}: the depth must be a one-channel 16-bit PNG in mm")
    if raw.shape != (h, w):
        raise InputError(f"{path}: {raw.shape[1]} x {raw.shape[0]} px; the image is {w} x {h}")
    return (raw.astype(np.float32) / 1000.0).astype(np.float32)


def export_folder(generate_dir: Path, out: Path, indices: list[int], margin_px: int = 8) -> None:
    """Write a ``render`` run's images as a user folder: each image, annotations from its
    truth (the object's box plus ``margin_px``, the visible keypoints) and its true depth in
    mm. How ``data/tiny/user_images`` was made; the truth is not copied."""
    out.mkdir(parents=True, exist_ok=True)
    for i in indices:
        truth = read_npz(generate_dir / GROUND_TRUTH_DIR / f"subtask_{i}.npz", GROUND_TRUTH)
        rgb = cv2.imread(str(subtask_dir(generate_dir, i) / "image.png"), cv2.IMREAD_COLOR)
        write_png(out / f"subtask_{i}.png", cv2.cvtColor(rgb, cv2.COLOR_BGR2RGB))
        u0, v0, u1, v1 = box_around(truth["object_mask"], margin_px)
        visible = {
            str(n): [round(float(u), 1), round(float(v), 1)]
            for n, (u, v), seen in zip(
                truth["keypoint_names"],
                truth["keypoints_px"],
                truth["keypoints_visible"],
                strict=True,
            )
            if seen
        }
        # One keypoint per line: the file is meant to be read and edited by hand.
        lines = [f'  "{n}": {json.dumps(uv)}' for n, uv in visible.items()]
        text = (
            f'{{\n "object_box_px": {json.dumps([u0, v0, u1, v1])},\n "keypoints_px": {{\n'
            + ",\n".join(lines)
            + "\n }\n}\n"
        )
        write_bytes_atomic(out / f"subtask_{i}.json", text.encode())
        depth_mm = np.round(truth["depth_m"] * 1000.0).clip(0, 65535).astype(np.uint16)
        write_bytes_atomic(
            out / f"subtask_{i}_depth.png", cv2.imencode(".png", depth_mm)[1].tobytes()
        )
