"""The results gallery the README shows: each humanoid scenario's filmstrip and a short, small
animation of its motion, and paper A's figures, copied from the pipeline's outputs into
``docs/gallery/`` so that a fresh clone has pictures true to the code.

Usage: python -m locoman.gallery   (after ``dvc repro``; ``make gallery``)
"""

from __future__ import annotations

import sys
from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np

from locoman.artifacts.io import write_bytes_atomic
from locoman.artifacts.video import write_mp4
from locoman.errors import ArtifactError

GALLERY = Path("docs") / "gallery"
SCENARIOS = ("tiny", "s1_basket", "s2_trolley")
FIGURES = (
    Path("data/tiny/figures/fig5.png"),
    Path("data/tiny/figures/fig6.png"),
    *sorted(Path("benchmarks/results").glob("*_fig[56]/fig[56].png")),
)
# The animation: every other frame of the evaluation's 30 fps MP4, at half its size.
STRIDE, SCALE = 2, 0.5


def _frames(video: Path) -> Iterator[np.ndarray]:
    """Every ``STRIDE``-th frame of ``video``, RGB, scaled by ``SCALE``."""
    capture = cv2.VideoCapture(str(video))
    index = 0
    try:
        while True:
            ok, bgr = capture.read()
            if not ok:
                return
            if index % STRIDE == 0:
                small = cv2.resize(bgr, None, fx=SCALE, fy=SCALE, interpolation=cv2.INTER_AREA)
                yield cv2.cvtColor(small, cv2.COLOR_BGR2RGB)
            index += 1
    finally:
        capture.release()


def build(out: Path = GALLERY) -> list[Path]:
    """Copy the filmstrips and figures, shrink the animations; the files written."""
    sources = [Path("data") / s / "evaluate" for s in SCENARIOS]
    missing = [str(p) for p in sources if not (p / "motion.mp4").is_file()] + [
        str(f) for f in FIGURES if not f.is_file()
    ]
    if missing:
        raise ArtifactError(f"the gallery needs {missing}: run `dvc repro` first")
    written = []
    for scenario, source in zip(SCENARIOS, sources, strict=True):
        strip = out / f"{scenario}_filmstrip.png"
        write_bytes_atomic(strip, (source / "plots" / "filmstrip.png").read_bytes())
        video = out / f"{scenario}.mp4"
        write_mp4(video, _frames(source / "motion.mp4"), 30.0 / STRIDE)
        written += [strip, video]
    for figure in FIGURES:
        name = figure.parent.name if figure.parent.name != "figures" else "tiny_figures"
        target = out / f"{name}_{figure.name}"
        write_bytes_atomic(target, figure.read_bytes())
        written.append(target)
    return written


def main() -> int:
    written = build()
    size = sum(p.stat().st_size for p in written) / 1e6
    print(f"[gallery] wrote {len(written)} files ({size:.1f} MB) to {GALLERY}/")
    return 0


if __name__ == "__main__":
    sys.exit(main())
