"""Perception front half: prompts, cameras, the posed demonstrator, masks, depth and clouds."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from locoman.config.perception import CloudsCfg, DepthErrorCfg, FluxCfg, GenerateCfg, TorchCfg
from locoman.errors import ModelError, SceneError
from locoman.perception import camera, demonstrator
from locoman.perception.clouds import (
    chamfer,
    lift_keypoints,
    object_cloud,
    remove_statistical_outliers,
    voxel_down_sample,
)
from locoman.perception.depth import depth_error_model
from locoman.perception.flux import load_flux_pipeline
from locoman.perception.prompts import augment_prompt, gerund
from locoman.perception.segment import SamSegmenter, check_mask, grabcut_mask, mask_iou
from locoman.scene import human
from locoman.scene.objects import object_geometry


@pytest.mark.parametrize(
    ("verb", "ing"),
    [
        ("pick", "picking"),
        ("place", "placing"),
        ("step", "stepping"),
        ("push", "pushing"),
        ("grab", "grabbing"),
        ("walk", "walking"),
        ("put", "putting"),
        ("take", "taking"),
        ("lift", "lifting"),
        ("open", "opening"),
        ("carry", "carrying"),
        ("lie", "lying"),
    ],
)
def test_gerund(verb, ing):
    assert gerund(verb) == ing


def test_augmented_prompt_is_the_papers_template():
    assert augment_prompt("pick up the box from the table") == (
        "A scene of person picking up the box from the table. The person has dark hair and is "
        "wearing casual clothes such a shirt, jeans, and sneakers."
    )


def test_heuristic_intrinsics_follow_the_paper():
    K = camera.heuristic_intrinsics(640, 480)
    assert np.allclose(K, [[640, 0, 320], [0, 480, 240], [0, 0, 1]])


@settings(max_examples=50, deadline=None)
@given(
    st.floats(0.3, 8.0),
    st.integers(0, 639),
    st.integers(0, 479),
    st.floats(np.deg2rad(20), np.deg2rad(90)),
)
def test_backprojection_inverts_projection(z, u, v, fovy):
    K = camera.intrinsics_from_fovy(640, 480, fovy)
    depth = np.zeros((480, 640))
    depth[v, u] = z
    mask = depth > 0
    point = camera.backproject(depth, mask, K)
    assert point.shape == (1, 3) and np.isclose(point[0, 2], z)
    assert np.allclose(camera.project(point, K) - 0.5, [[u, v]], atol=1e-9)


def test_look_at_puts_the_target_on_the_optical_axis():
    pose = camera.look_at(np.array([2.0, -1.0, 1.5]), np.array([0.0, 0.5, 0.8]))
    assert np.allclose(pose[:3, :3].T @ pose[:3, :3], np.eye(3))
    assert np.isclose(np.linalg.det(pose[:3, :3]), 1.0)
    target_cam = camera.to_camera(np.array([[0.0, 0.5, 0.8]]), pose)[0]
    assert np.allclose(target_cam[:2], 0.0) and target_cam[2] > 0
    assert pose[2, 0] == pytest.approx(0.0)  # no roll: image x stays horizontal


def test_contact_targets_pick_the_faces_the_paper_grasps():
    box = object_geometry("box", (0.3, 0.4, 0.2))
    hands = demonstrator.contact_targets(
        "box", box.patches, ["left_hand", "right_hand"], (0.3, 0.4, 0.2), 0.45, 0.72
    )
    assert [(t.effector, t.patch) for t in hands] == [
        ("left_hand", "left"),
        ("right_hand", "right"),
    ]
    assert hands[0].point[1] == pytest.approx(0.2) and hands[1].point[1] == pytest.approx(-0.2)
    # On a table a tenth above the faces' middle; on the floor near the top.
    assert hands[0].point[2] == pytest.approx(0.1 + 0.1 * 0.1)
    low = demonstrator.contact_targets(
        "box", box.patches, ["left_hand", "right_hand"], (0.3, 0.4, 0.2), 0.45, 0.0
    )
    assert all(t.point[2] == pytest.approx(0.1 + 0.6 * 0.1) for t in low)
    feet = demonstrator.contact_targets(
        "box", box.patches, ["left_foot", "right_foot"], (0.3, 0.4, 0.2), 0.45, 0.0
    )
    assert all(t.patch == "top" and t.point[2] == pytest.approx(0.2) for t in feet)
    trolley = object_geometry("trolley", (0.8, 0.5, 0.55))
    bar = demonstrator.contact_targets(
        "trolley", trolley.patches, ["left_hand", "right_hand"], (0.8, 0.5, 0.55), 0.45, 0.0
    )
    assert {t.patch for t in bar} == {"handle"}
    assert bar[0].point[1] > 0 > bar[1].point[1]  # left hand on the person's left
    table = object_geometry("table", (0.6, 0.8, 0.72))
    floor = demonstrator.contact_targets(
        "table", table.patches, ["left_foot"], (0.6, 0.8, 0.72), 0.45, 0.0
    )
    assert floor[0].patch == "floor" and floor[0].point[0] < -0.3
    with pytest.raises(SceneError, match="no left/right faces"):
        demonstrator.contact_targets(
            "table", table.patches, ["left_hand"], (0.6, 0.8, 0.72), 0.45, 0.0
        )


def test_demonstrator_ik_meets_reachable_targets():
    model = human.human_mjspec(prefix="").compile()
    targets = {
        "left_hand": (np.array([0.35, 0.2, 0.95]), np.array([0.0, 1.0, 0.0])),
        "right_hand": (np.array([0.35, -0.2, 0.95]), np.array([0.0, -1.0, 0.0])),
        "left_foot": (np.array([0.0, 0.11, 0.0]), np.array([0.0, 0.0, 1.0])),
        "right_foot": (np.array([0.0, -0.11, 0.0]), np.array([0.0, 0.0, 1.0])),
    }
    pose = demonstrator.pose_demonstrator(model, targets, np.zeros(2), 0.0)
    kp = demonstrator.keypoints_world(model, pose.qpos)
    names = list(demonstrator.KEYPOINTS)
    for name, (target, _) in targets.items():
        assert np.linalg.norm(kp[names.index(name)] - target) < 5e-3, name
    lo, hi = model.jnt_range[1:, 0], model.jnt_range[1:, 1]
    joints = pose.qpos[7:]
    assert np.all(joints >= lo - 1e-9) and np.all(joints <= hi + 1e-9)
    with pytest.raises(SceneError, match="cannot reach"):
        far = dict(targets, left_hand=(np.array([2.0, 0.2, 0.9]), np.array([0.0, 1.0, 0.0])))
        demonstrator.check_pose(
            demonstrator.pose_demonstrator(model, far, np.zeros(2), 0.0), 0.02, "subtask 0"
        )


@pytest.fixture(scope="module")
def rendered(params):
    """A rendered 'pick up the box from the table' of the tiny scenario."""
    from locoman.perception.render_backend import render_subtask
    from locoman.scene.builder import build_scene

    scene = build_scene("tiny", params.scenarios["tiny"])
    sub = scene.plan["subtasks"][1]
    obj = scene.objects[sub["object"]]
    height = obj["pos_m"][2]
    return render_subtask(obj, sub, height, params.perception.generate, np.random.default_rng(3))


def test_rendered_depth_lifts_onto_the_variants_surface(rendered):
    """Camera conventions agree with MuJoCo: true depth + true K land on the box's faces."""
    t = rendered.truth
    points = camera.transform(
        camera.backproject(t["depth_m"], t["object_mask"], t["K"]), t["T_world_cam"]
    )
    local = points - t["T_world_object"][:3, 3]
    half = t["variant_size_m"] / 2
    centre = np.array([0.0, 0.0, half[2]])
    inside = np.abs(local - centre) - half  # <= 0 inside; one coordinate ~0 on a face
    assert np.all(inside <= 2e-3)
    assert np.all(np.abs(inside.max(axis=1)) <= 2e-3)
    assert rendered.ik_residual_m < 0.01


def test_rendered_ground_truth_is_consistent(rendered):
    t = rendered.truth
    names = list(t["keypoint_names"])
    hands = t["keypoints_world_m"][[names.index("left_hand"), names.index("right_hand")]]
    contacts = t["contact_points_variant_m"] + t["T_world_object"][:3, 3]
    assert np.allclose(hands, contacts, atol=0.01)
    h, w = t["depth_m"].shape
    assert np.all((t["keypoints_px"] >= 0) & (t["keypoints_px"] < [w, h]))
    assert t["object_mask"].sum() > 1000 and not np.any(t["object_mask"] & t["human_mask"])


def test_a_foot_contacts_truth_is_where_the_person_stepped(params):
    """The person steps aside (``view.lateral_jitter_m``) and their feet with them: the true
    contact is where the sole stands, not the unstepped target."""
    from locoman.perception.demonstrator import STANCE_HALF_WIDTH
    from locoman.perception.render_backend import render_subtask
    from locoman.scene.builder import build_scene

    scene = build_scene("tiny", params.scenarios["tiny"])
    sub = scene.plan["subtasks"][0]  # walk to the table: both feet
    obj = scene.objects[sub["object"]]
    t = render_subtask(
        obj, sub, obj["pos_m"][2], params.perception.generate, np.random.default_rng(4)
    ).truth
    names = list(t["keypoint_names"])
    soles = t["keypoints_world_m"][[names.index(e) for e in sub["contacts"]]]
    contacts = t["contact_points_variant_m"] + t["T_world_object"][:3, 3]
    np.testing.assert_allclose(soles, contacts, atol=0.005)
    stepped = contacts[:, 1] - np.array([STANCE_HALF_WIDTH, -STANCE_HALF_WIDTH])
    assert abs(stepped[0]) > 0.02 and stepped[0] == pytest.approx(stepped[1])


def test_depth_error_model_scales_adds_noise_and_drops_edges():
    depth = np.full((60, 80), 2.0, np.float32)
    depth[20:40, 30:50] = 1.0
    depth[:5] = 0.0
    cfg = DepthErrorCfg(scale=1.1, noise_std_m=0.0, edge_dropout_px=2, edge_jump_m=0.05)
    out = depth_error_model(depth, cfg, np.random.default_rng(0))
    assert np.allclose(out[50, 5], 2.2) and np.allclose(out[30, 40], 1.1)
    assert np.all(out[:5] == 0.0)
    assert np.all(out[20:40, 28:32] == 0.0)  # the step at column 30 is dropped, 2 px around
    noisy = depth_error_model(depth, DepthErrorCfg(1.0, 0.01, 0, 0.05), np.random.default_rng(0))
    assert np.std(noisy[45:, :] - 2.0) == pytest.approx(0.01, rel=0.1)


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 2**31), st.floats(0.002, 0.05))
def test_voxel_down_sample_gives_each_occupied_voxels_centroid_in_any_input_order(seed, voxel):
    rng = np.random.default_rng(seed)
    points = rng.normal(size=(300, 3)) * 0.05
    out = voxel_down_sample(points, voxel)
    origin = points.min(axis=0) - 0.5 * voxel
    groups: dict[tuple[int, ...], list[np.ndarray]] = {}
    for p in points:
        groups.setdefault(tuple(np.floor((p - origin) / voxel).astype(int)), []).append(p)
    expected = np.array([np.mean(groups[k], axis=0) for k in sorted(groups)])
    assert np.allclose(out, expected, atol=1e-12)
    # The output is a function of the set of points: no hash-map order leaks into it.
    assert np.array_equal(voxel_down_sample(points[rng.permutation(len(points))], voxel), out)


def test_statistical_outlier_removal_drops_far_points_and_keeps_the_surface():
    rng = np.random.default_rng(0)
    g = np.stack(np.meshgrid(np.linspace(0, 0.3, 40), np.linspace(0, 0.2, 30)), -1).reshape(-1, 2)
    surface = np.c_[g, 0.001 * rng.normal(size=len(g))]
    strays = rng.uniform(-0.5, 0.5, size=(12, 3)) + np.array([0.0, 0.0, 0.6])
    kept = remove_statistical_outliers(np.r_[surface, strays], 20, 2.0)
    assert len(kept) == len(surface)
    assert np.array_equal(kept, surface)
    # The mean distance counts the point itself (Open3D's convention): a point with 19
    # coincident copies has a mean distance of 0 to its 20 neighbours and stays.
    cluster = np.r_[np.zeros((20, 3)), rng.normal(size=(200, 3))]
    kept = remove_statistical_outliers(cluster, 20, 2.0)
    assert np.sum(~kept.any(axis=1)) == 20


def test_chamfer_of_a_shifted_plane_is_the_shift():
    g = np.stack(np.meshgrid(np.linspace(0, 1, 30), np.linspace(0, 1, 30)), -1).reshape(-1, 2)
    a = np.c_[g, np.zeros(len(g))]
    assert chamfer(a, a) == 0.0
    assert chamfer(a, a + np.array([0.0, 0.0, 0.02])) == pytest.approx(0.02)


def test_lifted_keypoints_sit_at_their_depth():
    K = camera.intrinsics_from_fovy(64, 48, 1.0)
    depth = np.full((48, 64), 1.5, np.float32)
    out = lift_keypoints(np.array([[10.0, 20.0], [np.nan, 1.0], [100.0, 5.0]]), depth, K)
    assert out[0, 2] == pytest.approx(1.5)
    assert np.allclose(camera.project(out[:1], K) - 0.5, [[10.0, 20.0]])
    assert np.isnan(out[1:]).all()


def test_bad_masks_and_depth_get_clear_errors():
    with pytest.raises(SceneError, match=r"subtask 2.*mask is empty"):
        check_mask(np.zeros((4, 4), bool), "subtask 2 ('x', object 'box')")
    mask = np.ones((10, 10), bool)
    K = camera.heuristic_intrinsics(10, 10)
    with pytest.raises(SceneError, match="no valid pixel"):
        object_cloud(np.zeros((10, 10)), mask, K, CloudsCfg(), "subtask 0")
    with pytest.raises(SceneError, match="min_points"):
        object_cloud(np.ones((10, 10)), np.eye(10, dtype=bool), K, CloudsCfg(min_points=50), "s")


def test_grabcut_segments_a_plain_object_from_a_box():
    rng = np.random.default_rng(0)
    rgb = (rng.uniform(0, 60, (120, 160, 3))).astype(np.uint8)
    rgb[40:90, 50:120] = (220, 120, 40)
    truth = np.zeros((120, 160), bool)
    truth[40:90, 50:120] = True
    assert mask_iou(grabcut_mask(rgb, (40, 30, 130, 100), 5), truth) > 0.95


def test_learned_backends_fail_clearly_without_weights(tmp_path):
    with pytest.raises(ModelError, match="weights_dir is not set"):
        load_flux_pipeline(FluxCfg())
    with pytest.raises(ModelError, match=r"model_index\.json"):
        load_flux_pipeline(FluxCfg(weights_dir=str(tmp_path)))
    with pytest.raises(ModelError, match=r"config\.json"):
        SamSegmenter(str(tmp_path), TorchCfg())
    (tmp_path / "model_index.json").write_text("{}")
    with pytest.raises(ModelError, match=r"diffusers|cannot load"):
        load_flux_pipeline(FluxCfg(weights_dir=str(tmp_path)))


def test_perception_config_rejects_bad_values():
    errors = GenerateCfg(backend="dalle").check()
    assert errors and errors[0][0] == "backend"
