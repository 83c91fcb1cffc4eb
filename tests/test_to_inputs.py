"""What the TO takes from the stages' artifacts: the naive baseline (paper A, Sec. V-B) swaps
every contact it takes from contact transfer, the feet on an object included."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from locoman.artifacts import write_npz
from locoman.config.to import ScheduleCfg
from locoman.contact.io import CONTACTS, subtask_file
from locoman.scene import g1
from locoman.to.problem.inputs import Keyframe, TOInputs, sole_points
from locoman.to.problem.layout import NodeLayout
from locoman.to.problem.loading import _feet_on_object
from locoman.to.problem.numbers import node_parameters
from locoman.to.problem.objects import ObjectModel
from locoman.to.problem.schedule import build_schedule
from locoman.to.terms.supports import Surface

BOX_AT = np.array([1.5, 0.2, 0.0])  # [m] the stepped-on box's origin in the world
OURS = np.array([[0.0, 0.12, 0.3], [0.0, -0.12, 0.3]])  # [m] object frame
NAIVE = np.array([[0.1, -0.15, 0.3], [0.08, -0.2, 0.3]])


def _contacts(folder: Path, surfaces: tuple[str, str]) -> Path:
    """A subtask's contacts with both feet, ours and naive, in a box at BOX_AT."""
    T = np.eye(4)
    T[:3, 3] = BOX_AT
    pose = np.eye(4)
    arrays = {
        "method": "registration",
        "object": "box",
        "effectors": np.array(["left_foot", "right_foot"]),
        "surfaces": np.array(surfaces),
        "points_world_m": OURS + BOX_AT,
        "points_object_m": OURS,
        "normals_world": np.tile([0.0, 0.0, 1.0], (2, 1)),
        "raw_points_world_m": OURS + BOX_AT,
        "naive_points_object_m": NAIVE,
        "naive_normals_world": np.tile([0.0, 0.0, 1.0], (2, 1)),
        "T_world_object": T,
        "T_world_gen": pose,
        "scale": 1.0,
        "overlap": 0.9,
        "iteration": 1,
        "runner_up": 0.0,
        "margin": 0.9,
        "silhouette_iou": 0.8,
        "contact_gaps_m": np.zeros(2),
        "doubtful": False,
        "used": "registration",
        "T_world_pelvis": pose,
        "T_object_pelvis": pose,
        "pool_gen_px": np.zeros((1, 2)),
        "pool_sim_px": np.zeros((1, 1, 2)),
        "pool_scores": np.zeros((1, 1)),
    }
    path = subtask_file(folder, 2)
    path.parent.mkdir(parents=True)
    write_npz(path, CONTACTS, arrays)
    return folder


def test_the_naive_baseline_takes_the_semantic_models_feet_on_an_object(tmp_path):
    folder = _contacts(tmp_path, ("object", "object"))
    feet = _feet_on_object(folder, 2, "naive")
    np.testing.assert_allclose(feet, (NAIVE + BOX_AT)[:, :2])
    assert _feet_on_object(folder, 2, "registration") is None  # ours: the keyframe's soles


def test_feet_on_the_floor_are_no_semantic_match_and_keep_the_keyframes_soles(tmp_path):
    assert _feet_on_object(_contacts(tmp_path, ("floor", "floor")), 2, "naive") is None


def _foot_reference(kf: Keyframe) -> np.ndarray:
    """(10)'s reference (2, nodes) [m] on the stance nodes it is switched on for one walk."""
    box = ObjectModel.box("box", np.array([0.4, 0.4, 0.3]), 5.0, 0.8)
    inputs = TOInputs(
        g1.standing_q35(),
        (box,),
        np.array([[2.0, 0.0, 0.15, 0.0, 0.0, 0.0]]),
        (Surface(),),
        np.zeros(1),
        [kf],
        np.zeros((1, 2, 3)),
        np.tile(np.eye(3), (1, 2, 1, 1)),
    )
    schedule = build_schedule(inputs, ScheduleCfg())
    P = node_parameters(inputs, schedule, keyframe_base=True, keyframe_foot=True)
    par = NodeLayout.of(1).parameters
    on = P[par["kf_foot_on"]].ravel() > 0
    assert on.any()
    return P[par["kf_foot"]][:, on]


def test_the_keyframe_foot_cost_aims_at_the_feet_it_is_given():
    """(10) aims at the keyframe soles' midpoint, or at the given feet's where the baseline
    replaced them."""
    q = g1.standing_q35()
    soles = sole_points(q)[:, :2].mean(axis=0)
    walk = _foot_reference(Keyframe("walk", q, None, np.zeros((1, 6))))
    np.testing.assert_allclose(walk, np.tile(soles[:, None], walk.shape[1]))
    feet = np.array([[0.6, 0.1], [0.7, -0.3]])
    moved = _foot_reference(Keyframe("walk", q, None, np.zeros((1, 6)), feet_xy=feet))
    np.testing.assert_allclose(moved, np.tile([[0.65], [-0.1]], moved.shape[1]))
