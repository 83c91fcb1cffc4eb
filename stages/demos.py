"""Stage `demos`: record (synthesise) or load the human demonstrations of paper B.

Usage: python stages/demos.py   (reads params.yaml and data/<demos.scenario>/scene/,
writes data/<demos.scenario>/demos/)
"""

from __future__ import annotations

from locoman.kernels import pin_kernels

pin_kernels()  # first: NumPy, OpenBLAS and OpenCV choose their CPU kernels when they load

import sys
from pathlib import Path

import numpy as np

from locoman.artifacts import write_json_atomic, write_npz
from locoman.config import load_params
from locoman.kmp.demos import task_points
from locoman.kmp.io import DEMOS
from locoman.kmp.sources import collect_demos
from locoman.scene.io import load_objects, load_plan
from locoman.stage import DATA_DIR, StageOutputs, run_stage


def main(outputs: StageOutputs) -> Path:
    cfg = load_params()
    d = cfg.demos
    scene = DATA_DIR / d.scenario / "scene"
    _, task = task_points(load_objects(scene), load_plan(scene), d.grasp_height)
    demos, selected, miss = collect_demos(d, task, cfg.seed)
    out = outputs.folder(d.scenario, "demos")
    write_npz(
        out / "demos.npz",
        DEMOS,
        {
            "time_s": demos.time_s,
            "wrist_pos": demos.wrist_pos,
            "wrist_vel": demos.wrist_vel,
            "pelvis": demos.pelvis,
            "selected": selected.astype(np.int64),
            "grasp_miss_m": miss,
        },
    )
    k = int(np.argmin(np.abs(demos.time_s - d.grasp_time_s)))
    speed = np.linalg.norm(demos.wrist_vel[selected, k], axis=1)
    worst = float(miss[selected].max())
    # A selected demonstration whose wrist misses the bottle did not show the task: learning
    # from it would teach the miss.
    failed = ["grasp_miss"] if worst > d.grasp_miss_max_m else []
    write_json_atomic(
        out / "metrics.json",
        {
            "success": not failed,
            "failed_checks": failed,
            "n_recorded": len(miss),
            "n_selected": len(selected),
            "duration_s": float(demos.time_s[-1]),
            "grasp_miss_selected_max_m": worst,
            "grasp_miss_rejected_min_m": float(np.delete(miss, selected).min(initial=np.inf))
            if len(selected) < len(miss)
            else 0.0,
            "grasp_speed_mean_mps": float(speed.mean()),
        },
    )
    return out


if __name__ == "__main__":
    run_stage(main, sys.argv[1:])
