"""Stage `contacts`: contact locations L on the simulated objects, object transforms, human
placement, and their errors against ground truth.

Usage: python stages/contacts.py <scenario>   (reads params.yaml, data/<scenario>/scene/,
generate/, masks/ and clouds/, writes data/<scenario>/contacts/)
"""

from __future__ import annotations

from locoman.kernels import pin_kernels

pin_kernels()  # first: NumPy, OpenBLAS and OpenCV choose their CPU kernels when they load

import sys
from pathlib import Path

from locoman.config import load_params
from locoman.contact.pipeline import contacts_scenario
from locoman.stage import DATA_DIR, StageOutputs, run_stage


def main(outputs: StageOutputs, scenario: str) -> Path:
    cfg = load_params()
    out = outputs.folder(scenario, "contacts")
    root = DATA_DIR / scenario
    contacts_scenario(
        scenario,
        root / "scene",
        root / "generate",
        root / "masks",
        root / "clouds",
        out,
        cfg.contacts,
        cfg.seed,
    )
    return out


if __name__ == "__main__":
    run_stage(main, sys.argv[1:])
