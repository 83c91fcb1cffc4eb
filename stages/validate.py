"""Stage `validate`: the whole composed configuration, checked before any other stage runs.

Usage: python stages/validate.py   (reads params.yaml, writes data/params/validate/)

DVC reruns a stage only when one of its own parameters changes, so a misspelt key
(`dvc exp run -S +scenario.box_mas=5`) reached no stage's validation and the experiment
"succeeded". This stage depends on every key of params.yaml, and every root stage depends on
its output, whose content does not change with the parameters: a bad key fails here, naming
its path, and a good change reruns only what depends on it.
"""

from __future__ import annotations

from locoman.kernels import pin_kernels

pin_kernels()  # first: NumPy, OpenBLAS and OpenCV choose their CPU kernels when they load

import sys
from pathlib import Path

from locoman.artifacts import write_json_atomic
from locoman.config import load_params
from locoman.config.compose import check_scenario_files
from locoman.config.environment import check_environment
from locoman.stage import StageOutputs, run_stage


def main(outputs: StageOutputs) -> Path:
    check_environment(Path("requirements.lock"))  # the packages this Python has
    cfg = load_params()  # raises ConfigError naming the key
    check_scenario_files(cfg)  # a file of conf/scenario/ that params.yaml lacks
    out = outputs.folder("params", "validate")
    write_json_atomic(out / "validated.json", {"params.yaml": "valid"})
    return out


if __name__ == "__main__":
    run_stage(main, sys.argv[1:])
