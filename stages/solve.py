"""Stage `solve`: paper A's whole-body trajectory optimisation of one scenario.

Usage: python stages/solve.py <scenario>   (reads params.yaml, data/<scenario>/scene/,
contacts/ and retarget/, writes data/<scenario>/solve/)
"""

from __future__ import annotations

from locoman.kernels import pin_kernels

pin_kernels()  # first: NumPy, OpenBLAS and OpenCV choose their CPU kernels when they load

import sys
from pathlib import Path

from locoman.config import load_params
from locoman.config.to import scenario_solve
from locoman.stage import DATA_DIR, StageOutputs, run_stage
from locoman.to.pipeline import solve_scenario


def main(outputs: StageOutputs, scenario: str) -> Path:
    cfg = load_params()
    out = outputs.folder(scenario, "solve")
    root = DATA_DIR / scenario
    solve_scenario(
        root / "scene",
        root / "contacts",
        root / "retarget",
        out,
        scenario_solve(cfg.solve, scenario),
    )
    return out


if __name__ == "__main__":
    run_stage(main, sys.argv[1:])
