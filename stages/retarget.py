"""Stage `retarget`: one G1 keyframe (35-D) per subtask from the human pose and the
transferred contacts, with placo IK.

Usage: python stages/retarget.py <scenario>   (reads params.yaml, data/<scenario>/scene/,
generate/, masks/ and contacts/, writes data/<scenario>/retarget/)
"""

from __future__ import annotations

from locoman.kernels import pin_kernels

pin_kernels()  # first: NumPy, OpenBLAS and OpenCV choose their CPU kernels when they load

import sys
from pathlib import Path

from locoman.config import load_params
from locoman.retarget.pipeline import retarget_scenario
from locoman.stage import DATA_DIR, StageOutputs, run_stage


def main(outputs: StageOutputs, scenario: str) -> Path:
    cfg = load_params()
    out = outputs.folder(scenario, "retarget")
    root = DATA_DIR / scenario
    retarget_scenario(
        scenario,
        root / "scene",
        root / "generate",
        root / "masks",
        root / "contacts",
        out,
        cfg.retarget,
    )
    return out


if __name__ == "__main__":
    run_stage(main, sys.argv[1:])
