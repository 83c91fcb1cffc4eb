"""Cost of a video frame at MuJoCo's default render quality against the media's.

Usage: python benchmarks/render_quality.py [--frames 15] [--repeats 3]
    [--scenarios tiny s2_trolley] [--out benchmarks/results/render_quality.json]

Renders each scenario's scene (``data/<scenario>/scene``, from `dvc repro`) at the robot's
first solved pose (``data/<scenario>/solve``) from the evaluation's camera, 640 x 480, at each
render quality: MuJoCo's defaults (the scene's shadow map and multisampling), the media's
(:mod:`locoman.sim.media`), and the two steps apart. Reports the median seconds per frame of
``--frames`` frames per repeat, and how far each quality's image is from the defaults' (mean
absolute difference per channel, 0-255).
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import mujoco
import numpy as np
from common import write_benchmark

from locoman.artifacts import read_npz
from locoman.scene.io import load_scene_model
from locoman.sim import camera
from locoman.sim.evaluate import scene_qpos
from locoman.sim.media import MULTISAMPLES, SHADOW_SIZE
from locoman.sim.pipeline import VIDEO_SIZE, object_names, view_option
from locoman.stage import DATA_DIR
from locoman.to.io import TRAJECTORY, TRAJECTORY_FILE


def frames(
    model: mujoco.MjModel, qpos: np.ndarray, q: np.ndarray, n: int
) -> tuple[float, np.ndarray]:
    """Median seconds per frame of ``n`` renders, and the last image."""
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_forward(model, data)
    width, height = VIDEO_SIZE
    times = []
    with mujoco.Renderer(model, height=height, width=width) as renderer:
        for _ in range(n + 1):
            tic = time.perf_counter()
            renderer.update_scene(data, camera=camera.follow(q, 30.0), scene_option=view_option())
            image = renderer.render()
            times.append(time.perf_counter() - tic)
    return float(np.median(times[1:])), image.astype(float)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=15)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--scenarios", nargs="+", default=["tiny", "s2_trolley"])
    parser.add_argument("--out", default="benchmarks/results/render_quality.json")
    parser.add_argument("--conditions", default="idle", help="what else ran, for the record")
    args = parser.parse_args()
    results = []
    for scenario in args.scenarios:
        model = load_scene_model(DATA_DIR / scenario / "scene")
        traj = read_npz(DATA_DIR / scenario / "solve" / TRAJECTORY_FILE, TRAJECTORY)
        q = traj["q"][0]
        qpos = scene_qpos(model, q, object_names(traj), traj["object_q"][0])
        defaults = (int(model.vis.quality.shadowsize), int(model.vis.quality.offsamples))
        qualities = {
            "defaults": defaults,
            "no_multisampling": (defaults[0], MULTISAMPLES),
            "smaller_shadow_map": (SHADOW_SIZE, defaults[1]),
            "media": (SHADOW_SIZE, MULTISAMPLES),
        }
        seconds: dict[str, list[float]] = {name: [] for name in qualities}
        images = {}
        # Interleaved repeats: a load that comes and goes touches every quality alike.
        for _ in range(args.repeats):
            for name, (shadow, samples) in qualities.items():
                model.vis.quality.shadowsize, model.vis.quality.offsamples = shadow, samples
                s, images[name] = frames(model, qpos, q, args.frames)
                seconds[name].append(s)
        for name, (shadow, samples) in qualities.items():
            results.append(
                {
                    "scenario": scenario,
                    "quality": name,
                    "shadow_size_px": shadow,
                    "multisamples": samples,
                    "seconds_per_frame_median": float(np.median(seconds[name])),
                    "seconds_per_frame": seconds[name],
                    "mean_abs_difference_from_defaults": float(
                        np.abs(images[name] - images["defaults"]).mean()
                    ),
                }
            )
            print(f"[render_quality] {scenario} {name}: {np.median(seconds[name]):.3f} s/frame")
    write_benchmark(
        args.out,
        {
            "machine": {"cpus": os.cpu_count(), "platform": platform.platform()},
            "conditions": args.conditions,
            "size_px": list(VIDEO_SIZE),
            "frames": args.frames,
            "repeats": args.repeats,
            "results": results,
        },
    )


if __name__ == "__main__":
    main()
