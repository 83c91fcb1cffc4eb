"""Stage ``generate``: an image R_g per subtask, the sim views R_s, D_s and the ground truth."""

from __future__ import annotations

import time
import zlib
from pathlib import Path
from typing import Any

import numpy as np

from locoman.artifacts import write_json, write_metrics, write_npz, write_png
from locoman.config.perception import GenerateCfg
from locoman.perception import flux, user_images
from locoman.perception.demonstrator import ContactTarget, map_to_object
from locoman.perception.io import (
    GROUND_TRUTH,
    GROUND_TRUTH_DIR,
    PROMPTS,
    PROMPTS_FILE,
    SIM_VIEW,
    subtask_dir,
)
from locoman.perception.prompts import augment_prompt
from locoman.perception.render_backend import StandOn, object_patches, render_subtask
from locoman.perception.sim_view import render_sim_view
from locoman.progress import progress
from locoman.scene.io import load_objects, load_plan
from locoman.scene.objects import ContactPatch
from locoman.scene.plan_state import plan_states, world_pose

# What a backend without ground truth leaves unscored, in its metrics.
NO_TRUTH = (
    "the images have no ground truth (object masks, keypoints, depth, contacts): the "
    "stages downstream cannot score their outputs against anything"
)


def subtask_rng(seed: int, scenario: str, index: int) -> np.random.Generator:
    """Independent, reproducible random stream of one subtask."""
    return np.random.default_rng(
        np.random.SeedSequence([seed, zlib.crc32(scenario.encode()), index])
    )


def generate_scenario(
    scenario: str, scene_dir: Path, out_dir: Path, cfg: GenerateCfg, seed: int
) -> dict[str, Any]:
    """Write every subtask's images, sim view and (``render`` backend) ground truth.

    Backends: ``render`` (with ground truth), ``flux`` (a diffusion model) and ``folder``
    (the user's images, with what came with them in ``user_input.npz``).

    Returns:
        The stage's metrics: per-subtask seconds and the demonstrator's contact miss.
    """
    objects, plan = load_objects(scene_dir), load_plan(scene_dir)
    generator = flux.load_flux_pipeline(cfg.flux) if cfg.backend == "flux" else None
    user_folder = None
    if cfg.backend == "folder":
        assert cfg.folder.images_dir is not None  # GenerateCfg.check
        user_folder = user_images.resolve_images_dir(cfg.folder.images_dir)
        user_images.check_folder(user_folder, [s["index"] for s in plan["subtasks"]])
    entries, per_subtask = [], []
    states = plan_states(objects, plan["subtasks"])
    ordered = sorted(plan["subtasks"], key=lambda s: s["index"])
    for sub, state in progress(
        zip(ordered, states, strict=True), f"generate {scenario}", len(ordered)
    ):
        i, name = sub["index"], sub["object"]
        t0 = time.perf_counter()
        prompt = augment_prompt(sub["prompt"])
        folder = subtask_dir(out_dir, i)
        T_obj = world_pose(objects, state, name)
        sim = render_sim_view(scene_dir, name, objects[name], T_obj, cfg.sim_view, state.poses)
        write_png(folder / "sim_rgb.png", sim.rgb)
        write_npz(
            folder / "sim_view.npz",
            SIM_VIEW,
            {
                "depth_m": sim.depth_m,
                "object_mask": sim.object_mask,
                "K": sim.K,
                "T_world_cam": sim.T_world_cam,
                "T_world_object": sim.T_world_object,
            },
        )
        record: dict[str, Any] = {"index": i}
        if generator is not None:
            write_png(folder / "image.png", flux.generate_image(generator, prompt, cfg, seed + i))
        elif user_folder is not None:
            rgb, user_input, record["source_sha256"] = user_images.read_user_image(user_folder, i)
            write_png(folder / "image.png", rgb)
            write_npz(folder / user_images.USER_INPUT_FILE, user_images.USER_INPUT, user_input)
        else:
            stand_on = None
            if state.stands_on is not None and state.stands_on != name:
                T_stand = np.linalg.solve(T_obj, state.pose(state.stands_on))
                stand_on = StandOn(objects[state.stands_on], T_stand)
            rendered = render_subtask(
                objects[name],
                sub,
                float(T_obj[2, 3]),
                cfg,
                subtask_rng(seed, scenario, i),
                stand_on,
            )
            write_png(folder / "image.png", rendered.rgb)
            truth = dict(rendered.truth)
            patches = object_patches(objects[name])
            truth["contact_points_object_m"] = _contacts_on_object(truth, patches, objects[name])
            truth["object_size_m"] = np.asarray(objects[name]["size_m"], float)
            truth["sim_object_mask"] = sim.object_mask
            write_npz(out_dir / GROUND_TRUTH_DIR / f"subtask_{i}.npz", GROUND_TRUTH, truth)
            record["ik_residual_m"] = rendered.ik_residual_m
        record["seconds"] = time.perf_counter() - t0
        per_subtask.append(record)
        entries.append(
            {
                "index": i,
                "prompt": sub["prompt"],
                "augmented_prompt": prompt,
                "object": name,
                "contacts": sub["contacts"],
                "image": str((folder / "image.png").relative_to(out_dir)),
                "sim_image": str((folder / "sim_rgb.png").relative_to(out_dir)),
                "sim_view": str((folder / "sim_view.npz").relative_to(out_dir)),
            }
        )
    # Empty without truth: DVC's output stays declared whichever backend ran.
    (out_dir / GROUND_TRUTH_DIR).mkdir(parents=True, exist_ok=True)
    write_json(out_dir / PROMPTS_FILE, PROMPTS, {"backend": cfg.backend, "subtasks": entries})
    metrics: dict[str, Any] = {
        "backend": cfg.backend,
        "subtasks": len(entries),
        "seconds_per_subtask": float(np.median([r["seconds"] for r in per_subtask])),
        "per_subtask": per_subtask,
    }
    truth = cfg.backend == "render"
    if truth:
        metrics["ik_residual_max_m"] = max(r["ik_residual_m"] for r in per_subtask)
    metrics["ground_truth"] = truth
    if not truth:
        metrics["not_scored"] = NO_TRUTH
    write_metrics(out_dir, metrics)
    return metrics


def _contacts_on_object(
    truth: dict[str, np.ndarray], patches: dict[str, ContactPatch], obj: dict[str, Any]
) -> np.ndarray:
    points = []
    for name, patch, uv, p in zip(
        truth["contact_names"],
        truth["contact_patches"],
        truth["contact_uv"],
        truth["contact_points_variant_m"],
        strict=True,
    ):
        target = ContactTarget(str(name), str(patch), p, np.zeros(3), (float(uv[0]), float(uv[1])))
        points.append(map_to_object(target, patches, truth["variant_size_m"], obj["size_m"]))
    return np.array(points, dtype=float).reshape(-1, 3)
