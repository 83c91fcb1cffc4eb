"""Stage `masks`: object masks in R_g and R_s, 2D human keypoints and the 3D pose in R_g.

Usage: python stages/masks.py <scenario>   (reads params.yaml and data/<scenario>/generate/,
writes data/<scenario>/masks/)
"""

from __future__ import annotations

from locoman.kernels import pin_kernels

pin_kernels()  # first: NumPy, OpenBLAS and OpenCV choose their CPU kernels when they load

import sys
from pathlib import Path

from locoman.config import load_params
from locoman.perception.masks import masks_scenario
from locoman.stage import DATA_DIR, StageOutputs, run_stage


def main(outputs: StageOutputs, scenario: str) -> Path:
    cfg = load_params()
    out = outputs.folder(scenario, "masks")
    masks_scenario(
        scenario,
        DATA_DIR / scenario / "generate",
        out,
        cfg.perception.masks,
        cfg.seed,
    )
    return out


if __name__ == "__main__":
    run_stage(main, sys.argv[1:])
