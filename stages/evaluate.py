"""Stage `evaluate`: MuJoCo replay of the TO's trajectory, penetration and independent checks.

Usage: python stages/evaluate.py <scenario>   (reads params.yaml, data/<scenario>/scene/ and
solve/, writes data/<scenario>/evaluate/)
"""

from __future__ import annotations

from locoman.kernels import pin_kernels

pin_kernels()  # first: NumPy, OpenBLAS and OpenCV choose their CPU kernels when they load

import sys
from pathlib import Path

from locoman.config import load_params
from locoman.sim.pipeline import evaluate_scenario
from locoman.stage import DATA_DIR, StageOutputs, run_stage


def main(outputs: StageOutputs, scenario: str) -> Path:
    cfg = load_params()
    out = outputs.folder(scenario, "evaluate")
    root = DATA_DIR / scenario
    evaluate_scenario(root / "scene", root / "solve", out, cfg.evaluate)
    return out


if __name__ == "__main__":
    run_stage(main, sys.argv[1:])
