"""Stage `execute`: the G1 carries out the TO's trajectory in MuJoCo's forward dynamics.

Usage: python stages/execute.py <scenario>   (reads params.yaml, data/<scenario>/scene/ and
solve/, writes data/<scenario>/execute/)
"""

from __future__ import annotations

from locoman.kernels import pin_kernels

pin_kernels()  # first: NumPy, OpenBLAS and OpenCV choose their CPU kernels when they load

import sys
from pathlib import Path

from locoman.config import load_params
from locoman.execute.pipeline import execute_scenario
from locoman.stage import DATA_DIR, StageOutputs, run_stage


def main(outputs: StageOutputs, scenario: str) -> Path:
    cfg = load_params()
    out = outputs.folder(scenario, "execute")
    root = DATA_DIR / scenario
    execute_scenario(root / "scene", root / "solve", out, cfg.execute)
    return out


if __name__ == "__main__":
    run_stage(main, sys.argv[1:])
