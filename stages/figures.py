"""Stage `figures`: paper A's Fig. 5 and Fig. 6 of one scenario, from grids of TO cells.

Usage: python stages/figures.py <scenario>   (reads params.yaml and data/<scenario>/{scene,
contacts,retarget}/; runs the cells into data/<scenario>/grid/ through Hydra's launcher,
skipping those up to date; writes data/<scenario>/figures/)
"""

from __future__ import annotations

from locoman.kernels import pin_kernels

pin_kernels()  # first: NumPy, OpenBLAS and OpenCV choose their CPU kernels when they load

import sys
from pathlib import Path

from locoman.config import load_params
from locoman.errors import ConfigError
from locoman.grid.report import figures_scenario
from locoman.stage import StageOutputs, run_stage


def main(outputs: StageOutputs, scenario: str) -> Path:
    cfg = load_params()
    if scenario not in cfg.figures.scenarios:
        raise ConfigError(f"{scenario!r} is not in figures.scenarios {cfg.figures.scenarios}")
    out = outputs.folder(scenario, "figures")
    figures_scenario(cfg, scenario, out)
    return out


if __name__ == "__main__":
    run_stage(main, sys.argv[1:])
