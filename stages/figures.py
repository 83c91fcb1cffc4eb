"""Stage `figures`: paper A's Fig. 5 and Fig. 6 of one scenario, from grids of TO cells.

Usage: python stages/figures.py <scenario>   (reads params.yaml and data/<scenario>/{scene,
contacts,retarget}/; runs the cells into data/<scenario>/grid/ through Hydra's launcher,
skipping those up to date; writes data/<scenario>/figures/)
"""

from __future__ import annotations

import sys
from pathlib import Path

from locoman.config import load_params
from locoman.errors import ConfigError
from locoman.grid.report import figures_scenario
from locoman.stage import run_stage, stage_dir


def main(scenario: str) -> Path:
    cfg = load_params()
    if scenario not in cfg.figures.scenarios:
        raise ConfigError(f"{scenario!r} is not in figures.scenarios {cfg.figures.scenarios}")
    out = stage_dir(scenario, "figures")
    figures_scenario(cfg, scenario, out)
    return out


if __name__ == "__main__":
    run_stage(main, sys.argv[1:])
