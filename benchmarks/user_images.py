"""How far the ``folder`` path (the user's images) lands from the truth, beside the default.

Usage: python benchmarks/user_images.py [--seeds 0 1 2] [--size 512]
    [--scenarios tiny s1_basket s2_trolley] [--out benchmarks/results/user_images.json]

Per scenario and seed: the ``render`` backend draws the images with their ground truth; the
images go out as a user folder (``export_folder``: the image, the object's box plus 8 px and
the visible keypoints as annotations, the true depth in mm); the folder then runs the path a
user without the truth runs (``generate.backend=folder``, ``masks.backend=grabcut``,
``masks.keypoints=annotated``, ``masks.pose=fit``, ``clouds.depth=provided``) and contact
transfer. Its contacts are scored against the render run's truth, beside the default path on
the same images (render masks, jittered keypoints, the noisy true pose, the depth error model).
The two differ in the masks (grabcut against exact), the keypoints (exact against 3 px
jitter), the depth (exact against the error model) and the 3D pose (fitted against the truth
plus noise). Needs the scene stages (`dvc repro scene`). About 25 s per scenario and seed.
"""

from __future__ import annotations

import argparse
import dataclasses
import shutil
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
from common import write_benchmark

from locoman.artifacts import read_json, read_npz
from locoman.config import load_params
from locoman.config.perception import FolderCfg
from locoman.contact.pipeline import contacts_scenario
from locoman.perception import keypoints as kp
from locoman.perception.clouds import clouds_scenario
from locoman.perception.generate import generate_scenario
from locoman.perception.io import GROUND_TRUTH_DIR, POSE, PROMPTS, PROMPTS_FILE, SUBTASKS_DIR
from locoman.perception.masks import load_truth, masks_scenario
from locoman.perception.user_images import export_folder
from locoman.stage import DATA_DIR


def run(scenario: str, seed: int, size: int) -> dict[str, Any]:
    """Contact and pose errors of both paths for one scenario and seed."""
    cfg = load_params()
    p = cfg.perception
    scene = DATA_DIR / scenario / "scene"
    out: dict[str, Any] = {}
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        render = root / "render"
        generate_scenario(
            scenario, scene, render, dataclasses.replace(p.generate, width=size, height=size), seed
        )
        indices = [e["index"] for e in read_json(render / PROMPTS_FILE, PROMPTS)["subtasks"]]
        export_folder(render, root / "user", indices)
        folder = dataclasses.replace(
            p.generate, backend="folder", folder=FolderCfg(images_dir=str(root / "user"))
        )
        generate_scenario(scenario, scene, root / "folder", folder, seed)
        paths = {
            "default": (render, p.masks, p.clouds),
            "folder": (
                root / "folder",
                dataclasses.replace(p.masks, backend="grabcut", keypoints="annotated", pose="fit"),
                dataclasses.replace(p.clouds, depth="provided"),
            ),
        }
        for name, (gen, masks_cfg, clouds_cfg) in paths.items():
            msk, cld, con = (root / f"{name}_{s}" for s in ("masks", "clouds", "contacts"))
            masks_scenario(scenario, gen, msk, masks_cfg, seed)
            clouds_scenario(scenario, gen, msk, cld, clouds_cfg, p.depth_error, seed)
            if name == "folder":  # the truth, for scoring only: contact transfer ignores it
                shutil.copytree(
                    render / GROUND_TRUTH_DIR, gen / GROUND_TRUTH_DIR, dirs_exist_ok=True
                )
            contacts = contacts_scenario(scenario, scene, gen, msk, cld, con, cfg.contacts, seed)
            poses = [
                kp.pose_errors(
                    read_npz(msk / SUBTASKS_DIR / f"pose_{i}.npz", POSE), load_truth(render, i)
                )
                for i in indices
            ]
            out[name] = {
                "contact_errors_m": [
                    e for r in contacts["per_subtask"] for e in r["contact_errors_m"]
                ],
                "pose_mpjpe_pelvis_aligned_m": [r["mpjpe_pelvis_aligned_m"] for r in poses],
                "pose_rotation_error_deg": [r["pelvis_rotation_error_deg"] for r in poses],
            }
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--size", type=int, default=512, help="image side [px]")
    parser.add_argument("--scenarios", nargs="+", default=["tiny", "s1_basket", "s2_trolley"])
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/user_images.json"))
    args = parser.parse_args()
    t0 = time.perf_counter()
    runs = {f"{s}/{seed}": run(s, seed, args.size) for s in args.scenarios for seed in args.seeds}
    summary = {}
    for name in ("default", "folder"):
        errors = np.concatenate([r[name]["contact_errors_m"] for r in runs.values()])
        summary[name] = {
            "contacts": len(errors),
            "contact_error_median_m": float(np.median(errors)),
            "contact_error_p90_m": float(np.percentile(errors, 90)),
            "contact_error_max_m": float(errors.max()),
            "pose_mpjpe_pelvis_aligned_median_m": float(
                np.median(
                    [e for r in runs.values() for e in r[name]["pose_mpjpe_pelvis_aligned_m"]]
                )
            ),
            "pose_rotation_error_median_deg": float(
                np.median([e for r in runs.values() for e in r[name]["pose_rotation_error_deg"]])
            ),
        }
    result = {
        "what": __doc__.split("\n")[0],
        "command": "python benchmarks/user_images.py "
        + " ".join(
            [
                "--seeds",
                *map(str, args.seeds),
                "--size",
                str(args.size),
                "--scenarios",
                *args.scenarios,
            ]
        ),
        "seconds": time.perf_counter() - t0,
        "summary": summary,
        "runs": runs,
    }
    write_benchmark(args.out, result)
    print(result["summary"])


if __name__ == "__main__":
    main()
