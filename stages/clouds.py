"""Stage `clouds`: depth and intrinsics of R_g, object clouds of R_g and R_s, lifted keypoints.

Usage: python stages/clouds.py <scenario>   (reads params.yaml, data/<scenario>/generate/ and
masks/, writes data/<scenario>/clouds/)
"""

from __future__ import annotations

from locoman.kernels import pin_kernels

pin_kernels()  # first: NumPy, OpenBLAS and OpenCV choose their CPU kernels when they load

import sys
from pathlib import Path

from locoman.config import load_params
from locoman.perception.clouds import clouds_scenario
from locoman.stage import DATA_DIR, StageOutputs, run_stage


def main(outputs: StageOutputs, scenario: str) -> Path:
    cfg = load_params()
    out = outputs.folder(scenario, "clouds")
    clouds_scenario(
        scenario,
        DATA_DIR / scenario / "generate",
        DATA_DIR / scenario / "masks",
        out,
        cfg.perception.clouds,
        cfg.perception.depth_error,
        cfg.seed,
    )
    return out


if __name__ == "__main__":
    run_stage(main, sys.argv[1:])
