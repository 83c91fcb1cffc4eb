"""Stage `generate`: per subtask, the augmented prompt, the image R_g and the sim view R_s, D_s.

Usage: python stages/generate.py <scenario>   (reads params.yaml and data/<scenario>/scene/,
writes data/<scenario>/generate/)
"""

from __future__ import annotations

from locoman.kernels import pin_kernels

pin_kernels()  # first: NumPy, OpenBLAS and OpenCV choose their CPU kernels when they load

import sys
from pathlib import Path

from locoman.config import load_params
from locoman.perception.generate import generate_scenario
from locoman.stage import DATA_DIR, StageOutputs, run_stage


def main(outputs: StageOutputs, scenario: str) -> Path:
    cfg = load_params()
    out = outputs.folder(scenario, "generate")
    generate_scenario(
        scenario,
        DATA_DIR / scenario / "scene",
        out,
        cfg.perception.generate,
        cfg.seed,
    )
    return out


if __name__ == "__main__":
    run_stage(main, sys.argv[1:])
