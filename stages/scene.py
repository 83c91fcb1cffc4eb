"""Stage `scene`: build, validate and render one scenario's scene.

Usage: python stages/scene.py <scenario>   (reads params.yaml, writes data/<scenario>/scene/)
"""

from __future__ import annotations

from locoman.kernels import pin_kernels

pin_kernels()  # first: NumPy, OpenBLAS and OpenCV choose their CPU kernels when they load

import sys
from pathlib import Path

from locoman.artifacts import write_json_atomic, write_png
from locoman.config import load_params
from locoman.errors import ConfigError
from locoman.scene.builder import build_scene
from locoman.scene.checks import check_scene
from locoman.scene.io import write_scene
from locoman.scene.render import render_camera
from locoman.stage import StageOutputs, run_stage


def main(outputs: StageOutputs, scenario: str) -> Path:
    cfg = load_params()
    sc = cfg.scenarios.get(scenario)
    if sc is None:
        raise ConfigError(f"unknown scenario {scenario!r}; known: {sorted(cfg.scenarios)}")
    out = outputs.folder(scenario, "scene")
    scene = build_scene(scenario, sc, (cfg.scene.render_width, cfg.scene.render_height))
    model, qpos = write_scene(out, scene)
    report = check_scene(
        model, qpos, sc.robot, cfg.scene.penetration_tol, cfg.scene.foot_ground_tol
    )
    image = render_camera(model, qpos, "overview", cfg.scene.render_width, cfg.scene.render_height)
    write_png(out / "overview.png", image)
    write_json_atomic(
        out / "metrics.json",
        {
            "n_bodies": model.nbody,
            "n_geoms": model.ngeom,
            "nq": model.nq,
            "n_subtasks": len(sc.plan),
            "max_initial_penetration_m": report.max_penetration_m,
            "sole_gap_max_m": max((abs(g) for g in report.sole_gaps_m), default=0.0),
            "settle_displacement_max_m": max(report.settle_displacement_m.values(), default=0.0),
        },
    )
    return out


if __name__ == "__main__":
    run_stage(main, sys.argv[1:])
