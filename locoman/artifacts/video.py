"""Videos of a motion: MP4 written by OpenCV's bundled encoder (no ffmpeg install needed)."""

from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path

import cv2
import numpy as np

from locoman.errors import ArtifactError


def write_mp4(path: str | Path, frames: Iterable[np.ndarray], fps: float) -> int:
    """Write RGB frames (H, W, 3) uint8 as an MPEG-4 video (``mp4v``), atomically; return how
    many were written. The same frames give the same bytes (no time stamp in the file).

    Raises:
        ArtifactError: If there is no frame, the frames differ in size, or the encoder
            cannot open the file.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    # OpenCV picks the container by the extension, so the temporary name ends in .mp4 too.
    tmp = path.with_name(f".{path.stem}.{os.getpid()}.tmp.mp4")
    writer, size, count = None, None, 0
    try:
        for frame in frames:
            if writer is None:
                size = (frame.shape[1], frame.shape[0])
                writer = cv2.VideoWriter(str(tmp), cv2.VideoWriter_fourcc(*"mp4v"), fps, size)
                if not writer.isOpened():
                    raise ArtifactError(f"the MP4 encoder cannot open {tmp}")
            if (frame.shape[1], frame.shape[0]) != size:
                raise ArtifactError(f"{path}: frame {count} is {frame.shape}, the first {size}")
            writer.write(cv2.cvtColor(np.ascontiguousarray(frame), cv2.COLOR_RGB2BGR))
            count += 1
        if writer is None:
            raise ArtifactError(f"{path}: no frame to write")
        writer.release()
        writer = None
        os.replace(tmp, path)
    finally:
        if writer is not None:
            writer.release()
        tmp.unlink(missing_ok=True)
    return count
