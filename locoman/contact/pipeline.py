"""Stage ``contacts`` for one scenario: load the perception artifacts, transfer, score, plot."""

from __future__ import annotations

import logging
import time
from pathlib import Path
from typing import Any

import numpy as np

from locoman.artifacts import (
    read_json,
    read_npz,
    write_metrics,
    write_npz,
    write_png,
)
from locoman.config.contacts import ContactsCfg
from locoman.contact import semantic
from locoman.contact.io import CONTACTS, PLOTS_DIR, subtask_file
from locoman.contact.kabsch import decompose_similarity
from locoman.contact.plot import contact_plot
from locoman.contact.scoring import score_subtask, summarise, true_contacts
from locoman.contact.surface import held_parts
from locoman.contact.transfer import SubtaskInputs, Transfer, primitives_of, transfer_subtask
from locoman.errors import ArtifactError, SceneError
from locoman.perception.generate import subtask_rng
from locoman.perception.io import CLOUDS, MASKS, POSE, PROMPTS, PROMPTS_FILE, SIM_VIEW, read_png
from locoman.perception.io import SUBTASKS_DIR as PERCEPTION_SUBTASKS
from locoman.perception.masks import load_truth, median_or_none
from locoman.perception.render_backend import object_patches
from locoman.progress import progress
from locoman.scene.io import load_objects

CONTACTS_SEED_OFFSET = 3  # the contacts stage draws from its own stream
log = logging.getLogger(__name__)


def load_inputs(
    entry: dict[str, Any],
    objects: dict[str, Any],
    generate_dir: Path,
    masks_dir: Path,
    clouds_dir: Path,
) -> SubtaskInputs:
    """Everything contact transfer reads for one subtask of ``prompts.json``."""
    i = entry["index"]
    where = f"subtask {i} ({entry['prompt']!r}, object {entry['object']!r})"
    if entry["object"] not in objects:
        raise ArtifactError(f"{where}: the scene has no object {entry['object']!r}")
    sim = read_npz(generate_dir / entry["sim_view"], SIM_VIEW)
    masks = read_npz(masks_dir / PERCEPTION_SUBTASKS / f"subtask_{i}.npz", MASKS)
    pose = read_npz(masks_dir / PERCEPTION_SUBTASKS / f"pose_{i}.npz", POSE)
    clouds = read_npz(clouds_dir / PERCEPTION_SUBTASKS / f"subtask_{i}.npz", CLOUDS)
    primitives = primitives_of(objects[entry["object"]])
    names = [str(n) for n in clouds["keypoint_names"]]
    if [str(n) for n in pose["keypoint_names"]] != names:
        raise ArtifactError(f"{where}: the pose and the clouds name different keypoints")
    return SubtaskInputs(
        where=where,
        effectors=list(entry["contacts"]),
        rgb=read_png(generate_dir / entry["image"], "generate"),
        sim_rgb=read_png(generate_dir / entry["sim_image"], "generate"),
        mask=masks["object_mask"],
        sim_mask=masks["sim_object_mask"],
        depth=clouds["depth_m"],
        K=clouds["K"],
        sim_depth=sim["depth_m"],
        sim_K=sim["K"],
        T_world_sim=sim["T_world_cam"],
        cloud=clouds["points_gen_m"],
        sim_cloud=clouds["points_sim_m"],
        keypoint_names=names,
        keypoints_px=masks["keypoints_px"],
        keypoints_lifted=clouds["keypoints_cam_m"],
        pose_keypoints=pose["keypoints_cam_m"],
        T_cam_pelvis=pose["T_cam_pelvis"],
        T_world_object=sim["T_world_object"],
        primitives=primitives,
        held=held_parts(primitives, list(object_patches(objects[entry["object"]]).values())),
    )


def write_transfer(
    path: Path, entry: dict[str, Any], inputs: SubtaskInputs, r: Transfer, method: str
) -> None:
    """The ``contact.transfer`` artifact of one subtask."""
    reg = r.registration
    T_object_world = np.linalg.inv(inputs.T_world_object)
    write_npz(
        path,
        CONTACTS,
        {
            "method": np.array(method),
            "object": np.array(entry["object"]),
            "effectors": np.array(inputs.effectors),
            "surfaces": np.array(r.surfaces),
            "points_world_m": r.points_world,
            "points_object_m": r.points_world @ T_object_world[:3, :3].T + T_object_world[:3, 3],
            "normals_world": r.normals_world,
            "raw_points_world_m": r.raw_points_world,
            "naive_points_object_m": r.naive_world @ T_object_world[:3, :3].T
            + T_object_world[:3, 3],
            "naive_normals_world": r.naive_normals_world,
            "T_world_object": inputs.T_world_object,
            "T_world_gen": reg.transform,
            "scale": np.array(decompose_similarity(reg.transform)[0]),
            "overlap": np.array(reg.overlap),
            "iteration": np.array(reg.iteration, dtype=np.int64),
            "runner_up": np.array(r.confidence.runner_up),
            "margin": np.array(r.confidence.margin),
            "silhouette_iou": np.array(r.confidence.silhouette_iou),
            "contact_gaps_m": np.array([r.confidence.contact_gaps_m[e] for e in inputs.effectors]),
            "doubtful": np.array(r.confidence.doubtful),
            "used": np.array(r.used),
            "T_world_pelvis": r.T_world_pelvis,
            "T_object_pelvis": T_object_world @ r.T_world_pelvis,
            "pool_gen_px": r.pool.gen_px,
            "pool_sim_px": r.pool.sim_px,
            "pool_scores": r.pool.scores,
        },
    )


def contacts_scenario(
    scenario: str,
    scene_dir: Path,
    generate_dir: Path,
    masks_dir: Path,
    clouds_dir: Path,
    out_dir: Path,
    cfg: ContactsCfg,
    seed: int,
) -> dict[str, Any]:
    """Transfer the contacts of every subtask; write artifacts, plots and metrics."""
    prompts = read_json(generate_dir / PROMPTS_FILE, PROMPTS)
    objects = load_objects(scene_dir)
    describer = semantic.make_describer(cfg.pool)
    rows: list[dict[str, Any]] = []
    for entry in progress(prompts["subtasks"], f"contacts {scenario}"):
        i = entry["index"]
        t0 = time.perf_counter()
        inputs = load_inputs(entry, objects, generate_dir, masks_dir, clouds_dir)
        result = transfer_subtask(
            inputs, cfg, describer, subtask_rng(seed + CONTACTS_SEED_OFFSET, scenario, i)
        )
        seconds = time.perf_counter() - t0
        write_transfer(subtask_file(out_dir, i), entry, inputs, result, cfg.method)
        truth = load_truth(generate_dir, i)
        truth_world = (
            None if truth is None else true_contacts(truth, inputs.effectors, inputs.T_world_object)
        )
        title = f"{scenario} #{i}: {entry['prompt']}"
        write_png(
            out_dir / PLOTS_DIR / f"subtask_{i}.png",
            contact_plot(inputs, result, truth_world, title),
        )
        trust = result.confidence
        if trust.doubtful:
            why = "; ".join(trust.reasons)
            what = f"{scenario} {inputs.where}: the registration is doubtful ({why})"
            if cfg.on_doubt == "fail":
                raise SceneError(
                    f"{what}; contacts.on_doubt is fail. Check its image and masks, or set "
                    "contacts.on_doubt to warn or fallback (the naive contacts)"
                )
            log.warning(
                "%s; its contacts are the %s ones (contacts.on_doubt: %s)",
                what,
                result.used,
                cfg.on_doubt,
            )
        row: dict[str, Any] = {
            "index": i,
            "effectors": inputs.effectors,
            "surfaces": result.surfaces,
            "iterations_to_best": result.registration.iteration,
            **trust.as_dict(),
            "used": result.used,
            "scale": decompose_similarity(result.registration.transform)[0],
            "seconds": seconds,
        }
        if truth is not None:
            row |= score_subtask(truth, inputs, result)
        rows.append(row)
    metrics = _aggregate(rows, cfg)
    write_metrics(out_dir, metrics)
    return metrics


def _aggregate(rows: list[dict[str, Any]], cfg: ContactsCfg) -> dict[str, Any]:
    scored = [r for r in rows if "contact_errors_m" in r]
    ours = [e for r in scored for e in r["contact_errors_m"]]
    naive = [e for r in scored for e in r["naive_contact_errors_m"]]
    if cfg.method == "naive":
        ours = naive
    metrics: dict[str, Any] = {
        "method": cfg.method,
        "lift": cfg.lift,
        "descriptor": cfg.pool.descriptor,
        **summarise(ours, "contact_error"),
        **summarise(naive, "naive_contact_error"),
        "rotation_error_deg": median_or_none([r.get("rotation_error_deg") for r in scored]),
        "translation_error_m": median_or_none([r.get("translation_error_m") for r in scored]),
        "pelvis_position_error_m": median_or_none(
            [r.get("pelvis_position_error_m") for r in scored]
        ),
        "iterations_to_best": float(np.median([r["iterations_to_best"] for r in rows])),
        # Subtasks whose registration is doubtful (locoman.contact.confidence), and whose
        # contacts the naive ones replaced (contacts.on_doubt: fallback).
        "doubtful_subtasks": [r["index"] for r in rows if r["doubtful"]],
        "fallback_subtasks": [
            r["index"] for r in rows if r["used"] == "naive" and cfg.method != "naive"
        ],
        "seconds_per_subtask": float(np.median([r["seconds"] for r in rows])),
        "per_subtask": rows,
    }
    return metrics
