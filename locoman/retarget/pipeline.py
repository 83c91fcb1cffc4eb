"""Stage ``retarget`` for one scenario: one G1 keyframe per subtask, checked and scored."""

from __future__ import annotations

import logging
import time
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from locoman.artifacts import (
    read_json,
    read_npz,
    write_metrics,
    write_npz,
    write_png,
)
from locoman.artifacts.mcap_io import write_frame_transforms
from locoman.config.retarget import RetargetCfg
from locoman.contact.io import CONTACTS
from locoman.contact.io import subtask_file as contact_file
from locoman.contact.scoring import true_contacts
from locoman.errors import SceneError
from locoman.perception.io import POSE, PROMPTS, PROMPTS_FILE, read_png
from locoman.perception.io import SUBTASKS_DIR as PERCEPTION_SUBTASKS
from locoman.perception.masks import load_truth, median_or_none
from locoman.progress import progress
from locoman.retarget.checks import com_support_margin, joint_limit_violation, self_collision_pairs
from locoman.retarget.ik import IKProblem, IKResult, Retargeter, yaw_of
from locoman.retarget.io import KEYFRAME, MCAP_FILE, PLOTS_DIR, keyframe_file
from locoman.retarget.plot import keyframe_plot, render_keyframe
from locoman.retarget.problem import body_scale, build_problem, g1_stance_half_width
from locoman.retarget.robot import contact_frames
from locoman.scene import g1
from locoman.scene.io import load_objects, load_plan, load_scene_model
from locoman.scene.plan_state import plan_states

log = logging.getLogger(__name__)


def feet_left_standing(contacts: dict[str, Any], before: dict[str, np.ndarray]):
    """Where each foot stands after a subtask: on the object it stepped on, or, when the
    subtask did not move the feet, where they stood before (empty: on the floor)."""
    effectors = [str(e) for e in contacts["effectors"]]
    feet = [k for k, e in enumerate(effectors) if e.endswith("_foot")]
    if not feet:
        return before
    return {
        effectors[k]: contacts["points_world_m"][k]
        for k in feet
        if str(contacts["surfaces"][k]) == "object"
    }


def contact_points(problem: IKProblem, result: IKResult) -> np.ndarray:
    """Where the keyframe touches (E, 3) [m]: the palm's surface under its centre, along the
    contact normal, and the sole centre."""
    radius = contact_frames().palm_radius
    normals = [h.normal for h in problem.hands] + [f.normal for f in problem.feet]
    out = result.reached.copy()
    for k, effector in enumerate(result.effectors):
        if effector.endswith("_hand"):
            out[k] -= radius * normals[k]
    return out


def _scene_qpos(model: mujoco.MjModel, q: np.ndarray, poses: dict[str, np.ndarray]) -> np.ndarray:
    """The scene's qpos with the G1 at ``q`` and each movable object at its pose (4, 4)."""
    qpos = g1.pin_to_mujoco_qpos(q, model, model.key("home").qpos)
    for obj, T_obj in poses.items():
        joint = f"{obj}_free"
        if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, joint) >= 0:
            quat = np.zeros(4)
            mujoco.mju_mat2Quat(quat, T_obj[:3, :3].ravel())
            adr = model.joint(joint).qposadr[0]
            qpos[adr : adr + 7] = np.r_[T_obj[:3, 3], quat]
    return qpos


def retarget_scenario(
    scenario: str,
    scene_dir: Path,
    generate_dir: Path,
    masks_dir: Path,
    contacts_dir: Path,
    out_dir: Path,
    cfg: RetargetCfg,
) -> dict[str, Any]:
    """Solve, check, score, draw and write every subtask's keyframe; return the metrics."""
    prompts = read_json(generate_dir / PROMPTS_FILE, PROMPTS)
    model = load_scene_model(scene_dir)
    states = {
        s.index: s for s in plan_states(load_objects(scene_dir), load_plan(scene_dir)["subtasks"])
    }
    retargeter = Retargeter(cfg)
    half_width, scale = g1_stance_half_width(), body_scale()
    standing: dict[str, np.ndarray] = {}
    rows, seconds, frames = [], [], []
    for entry in progress(prompts["subtasks"], f"retarget {scenario}"):
        i = entry["index"]
        contacts = read_npz(contact_file(contacts_dir, i), CONTACTS)
        pose = read_npz(masks_dir / PERCEPTION_SUBTASKS / f"pose_{i}.npz", POSE)
        problem = build_problem(contacts, pose, half_width, scale, standing)
        t0 = time.perf_counter()
        result = retargeter.solve(problem)
        seconds.append(time.perf_counter() - t0)
        standing = feet_left_standing(contacts, standing)
        points = contact_points(problem, result)
        # The plan state's poses, with the subtask's object where contact transfer saw it.
        poses = dict(states[i].poses)
        if entry["object"] in poses:
            poses[entry["object"]] = contacts["T_world_object"]
        row = _check(i, entry, result, points, contacts, generate_dir, cfg)
        # Whose contacts the keyframe reaches for: a doubtful registration's, or the naive
        # ones that replaced them (contacts.on_doubt), said where it matters.
        row["contacts_used"] = str(contacts["used"])
        row["contacts_doubtful"] = bool(contacts["doubtful"])
        if row["contacts_doubtful"]:
            log.warning(
                "subtask %d (%r): its contacts come from a doubtful registration; the keyframe "
                "uses the %s ones",
                i,
                entry["prompt"],
                row["contacts_used"],
            )
        rows.append(row)
        in_contact = [t.in_contact for t in (*problem.hands, *problem.feet)]
        surfaces = [str(s) for s in contacts["surfaces"]]
        by_effector = dict(zip([str(e) for e in contacts["effectors"]], surfaces, strict=True))
        write_npz(
            keyframe_file(out_dir, i),
            KEYFRAME,
            {
                "q35": result.q35,
                "object": entry["object"],
                "effectors": np.array(result.effectors),
                "in_contact": np.array(in_contact),
                "surfaces": np.array([by_effector.get(e, "support") for e in result.effectors]),
                "contact_points_m": points,
                "contact_normals": np.array(
                    [t.normal for t in (*problem.hands, *problem.feet)]
                ).reshape(-1, 3),
                "targets_m": result.targets,
                "reached_m": result.reached,
                "residual_m": result.residual_m,
                "reachable": result.residual_m <= cfg.reach_tolerance_m,
                "T_world_object": contacts["T_world_object"],
                "movable_objects": np.array(sorted(poses), dtype=str),
                "T_world_movable": np.array([poses[n] for n in sorted(poses)]).reshape(-1, 4, 4),
                "stands_on": states[i].stands_on or "floor",
                "com_m": np.array(row["com_m"]),
                "iterations": np.array(result.iterations),
            },
        )
        frames.append(g1.link_poses(result.q))
        robot = render_keyframe(
            model,
            _scene_qpos(model, result.q, poses),
            result,
            in_contact,
            yaw_of(problem.R_world_base),
        )
        footer = "residual [mm]: " + ", ".join(
            f"{e} {1e3 * r:.1f}" for e, r in zip(result.effectors, result.residual_m, strict=True)
        )
        write_png(
            out_dir / PLOTS_DIR / f"subtask_{i}.png",
            keyframe_plot(
                read_png(generate_dir / entry["image"], "generate"),
                robot,
                f"{scenario} #{i}: {entry['prompt']}",
                footer,
            ),
        )
    names = list(frames[0]) if frames else []
    write_frame_transforms(
        out_dir / MCAP_FILE,
        np.arange(len(frames), dtype=float),
        {
            n: (np.array([f[n][0] for f in frames]), np.array([f[n][1] for f in frames]))
            for n in names
        },
    )
    metrics = _aggregate(rows, seconds, out_dir)
    check_reached(rows, cfg.max_contact_miss_m)
    return metrics


def check_reached(rows: list[dict[str, Any]], max_miss_m: float) -> None:
    """Every contact the keyframes leave unreached is missed by at most ``max_miss_m``.

    Raises:
        SceneError: Naming each subtask, end effector and miss beyond it: the TO would start
            from a keyframe that does not touch what the subtask acts on.
    """
    misses = [
        f"subtask {row['index']} ({row['prompt']!r}): {effector} by {miss:.3f} m"
        for row in rows
        for effector, miss in row["unreachable"].items()
        if miss > max_miss_m
    ]
    if misses:
        raise SceneError(
            f"the G1 cannot reach its contacts (the keyframe IK leans as far as it can "
            f"without lifting the feet): {'; '.join(misses)}, beyond "
            f"retarget.max_contact_miss_m ({max_miss_m} m). Bring the object or its target "
            "within reach (docs/scenarios.md: what the G1 reaches)"
        )


def _check(
    i: int,
    entry: dict[str, Any],
    result: IKResult,
    points: np.ndarray,
    contacts: dict[str, Any],
    generate_dir: Path,
    cfg: RetargetCfg,
) -> dict[str, Any]:
    """Metrics of one keyframe, recomputed outside the IK (and against ground truth)."""
    plan_contacts = [str(e) for e in contacts["effectors"]]
    soles = [result.reached[k] for k, e in enumerate(result.effectors) if e.endswith("_foot")]
    com, margin = com_support_margin(result.q, soles)
    residual = dict(zip(result.effectors, result.residual_m.tolist(), strict=True))
    row: dict[str, Any] = {
        "index": i,
        "prompt": entry["prompt"],
        "residual_m": residual,
        "unreachable": {
            **result.unreachable,
            **{
                e: r
                for e, r in residual.items()
                if r > cfg.reach_tolerance_m and e in plan_contacts and e.endswith("_foot")
            },
        },
        "joint_limit_violation_rad": joint_limit_violation(result.q),
        "base_roll_pitch_rad": float(np.max(np.abs(result.q35[3:5]))),
        "self_collisions": [list(p) for p in self_collision_pairs(result.q)],
        "com_m": com.tolist(),
        "com_support_margin_m": margin,
        "iterations": result.iterations,
    }
    truth = load_truth(generate_dir, i)
    if truth is not None:
        true_world = true_contacts(truth, plan_contacts, contacts["T_world_object"])
        row["truth_error_m"] = {
            e: float(np.linalg.norm(points[result.effectors.index(e)] - true_world[k]))
            for k, e in enumerate(plan_contacts)
        }
    return row


def _aggregate(rows: list[dict[str, Any]], seconds: list[float], out_dir: Path) -> dict[str, Any]:
    def worst(kind: str, reachable_only: bool) -> float | None:
        values = [
            r
            for row in rows
            for e, r in row["residual_m"].items()
            if e.endswith(kind) and not (reachable_only and e in row["unreachable"])
        ]
        return max(values) if values else None

    truth = [v for row in rows for v in row.get("truth_error_m", {}).values()]
    metrics: dict[str, Any] = {
        "keyframes": len(rows),
        "hand_contact_residual_max_m": worst("_hand", False),
        "foot_contact_residual_max_m": worst("_foot", False),
        "reachable_hand_residual_max_m": worst("_hand", True),
        "unreachable_contacts": sum(len(row["unreachable"]) for row in rows),
        "doubtful_contacts_subtasks": [r["index"] for r in rows if r["contacts_doubtful"]],
        "joint_limit_violation_max_rad": max(r["joint_limit_violation_rad"] for r in rows),
        # Within retarget.base_tilt_max_rad, or the TO cannot take the keyframe.
        "base_roll_pitch_max_rad": max(r["base_roll_pitch_rad"] for r in rows),
        "self_collision_pairs": sum(len(r["self_collisions"]) for r in rows),
        "com_support_margin_min_m": min(r["com_support_margin_m"] for r in rows),
        "keyframes_per_second": 1.0 / float(np.median(seconds)),
        "seconds_per_keyframe": float(np.median(seconds)),
        "truth_contact_error_median_m": median_or_none(truth),
        "truth_contact_error_max_m": max(truth) if truth else None,
        "per_subtask": rows,
    }
    write_metrics(out_dir, metrics)
    return metrics
