"""Stage `solve`: paper A's whole-body trajectory optimisation of one scenario.

Usage: python stages/solve.py <scenario>   (reads params.yaml, data/<scenario>/scene/,
contacts/ and retarget/, writes data/<scenario>/solve/)
"""

from __future__ import annotations

import sys
from pathlib import Path

from locoman.config import load_params
from locoman.stage import DATA_DIR, run_stage, stage_dir
from locoman.to.pipeline import solve_scenario


def main(scenario: str) -> Path:
    cfg = load_params()
    out = stage_dir(scenario, "solve")
    root = DATA_DIR / scenario
    solve_scenario(
        root / "scene",
        root / "contacts",
        root / "retarget",
        out,
        cfg.solve,
    )
    return out


if __name__ == "__main__":
    run_stage(main, sys.argv[1:])
