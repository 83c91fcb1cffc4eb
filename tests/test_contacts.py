"""Contact transfer: SVD, ICP, surface projection, pose anchoring, pool and clear errors."""

from __future__ import annotations

import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import ndimage
from scipy.spatial.transform import Rotation

from locoman.config.contacts import ConfidenceCfg, ContactsCfg, PoolCfg, RegistrationCfg
from locoman.contact import semantic
from locoman.contact.confidence import cloud_moved, confidence
from locoman.contact.kabsch import apply, decompose_similarity, similarity_matrix, umeyama
from locoman.contact.lift import fit_anchor, support_up
from locoman.contact.registration import (
    Registration,
    Surface,
    View,
    _fit_yaw,
    draw_hypotheses,
    gates,
    icp,
    level,
    overlap_scores,
    refine_axes,
    seen_target,
    select,
    tilt_errors,
    turn_about_object,
)
from locoman.contact.surface import (
    closest_on_primitive,
    held_parts,
    project_to_support,
    project_to_surface,
    sample_surface,
    signed_distance,
)
from locoman.contact.transfer import contact_gaps, place_contacts
from locoman.errors import ModelError, SceneError
from locoman.perception import camera
from locoman.scene.objects import OBJECT_KINDS, Primitive, object_geometry

SIZES = {
    "box": (0.4, 0.3, 0.2),
    "cylinder": (0.05, 0.25),
    "table": (0.6, 0.8, 0.72),
    "shelf": (0.35, 0.8, 1.55),
    "basket": (0.35, 0.45, 0.22),
    "trolley": (0.8, 0.5, 0.55),
}


def _rotation(seed: int) -> np.ndarray:
    return Rotation.random(random_state=seed).as_matrix()


@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, 2**31 - 1),
    n=st.integers(3, 60),
    scale=st.floats(0.2, 5.0),
    with_scale=st.booleans(),
)
def test_umeyama_recovers_random_transforms_exactly(seed, n, scale, with_scale):
    rng = np.random.default_rng(seed)
    src = rng.normal(size=(n, 3))
    rot, trans = _rotation(seed), rng.normal(size=3) * 3.0
    s = scale if with_scale else 1.0
    dst = s * src @ rot.T + trans
    got_s, got_r, got_t = umeyama(src, dst, with_scale=with_scale)
    assert got_s == pytest.approx(s, rel=1e-9)
    np.testing.assert_allclose(got_r, rot, atol=1e-9)
    np.testing.assert_allclose(got_t, trans, atol=1e-8)
    np.testing.assert_allclose(np.linalg.det(got_r), 1.0, atol=1e-12)


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**31 - 1))
def test_umeyama_is_batched_and_ignores_zero_weight_outliers(seed):
    rng = np.random.default_rng(seed)
    src = rng.normal(size=(4, 20, 3))
    rots = np.stack([_rotation(seed + k) for k in range(4)])
    dst = np.einsum("hij,hnj->hni", rots, src) + 1.0
    weights = np.ones((4, 20))
    dst[:, :5] += rng.normal(size=(4, 5, 3)) * 10.0  # gross outliers, weighted out
    weights[:, :5] = 0.0
    _, got, trans = umeyama(src, dst, weights)
    np.testing.assert_allclose(got, rots, atol=1e-9)
    np.testing.assert_allclose(trans, np.ones((4, 3)), atol=1e-9)


def test_similarity_matrix_round_trips():
    rot = _rotation(3)
    matrix = similarity_matrix(1.3, rot, np.array([0.1, -0.2, 0.3]))
    s, r, t = decompose_similarity(matrix)
    assert s == pytest.approx(1.3)
    np.testing.assert_allclose(r, rot, atol=1e-12)
    np.testing.assert_allclose(apply(matrix, np.zeros((1, 3)))[0], t)


def _box_surface(rng: np.random.Generator) -> tuple[Surface, np.ndarray]:
    geometry = object_geometry("box", (0.4, 0.3, 0.2))
    pose = np.eye(4)
    pose[:3, :3] = Rotation.from_euler("z", 0.4).as_matrix()
    pose[:3, 3] = (1.0, 0.5, 0.7)
    local, normals = sample_surface(geometry.primitives, 3000, rng)
    return Surface(local @ pose[:3, :3].T + pose[:3, 3], normals @ pose[:3, :3].T, pose), pose


def test_icp_converges_from_a_perturbed_start():
    rng = np.random.default_rng(0)
    surface, _ = _box_surface(rng)
    truth = similarity_matrix(1.1, _rotation(5), np.array([0.2, -0.1, 0.4]))
    camera_world = apply(truth, np.zeros((1, 3)))[0]
    # What a camera at the gen frame's origin sees: the faces turned towards it.
    facing = (surface.normals * (camera_world - surface.points)).sum(axis=1) > 0.0
    seen = surface.points[facing][::2]
    source = apply(np.linalg.inv(truth), seen) + rng.normal(0.0, 0.002, seen.shape)
    wrong = Rotation.from_rotvec(np.array([0.1, -0.12, 0.08])).as_matrix()  # about 10 deg
    start = similarity_matrix(1.0, wrong @ _rotation(5), np.array([0.25, -0.05, 0.43]))
    refined = icp(source, surface, start[None], 0.1, 40, True, (0.5, 2.0))[0]
    s, rot, _ = decompose_similarity(refined)
    assert s == pytest.approx(1.1, abs=0.02)
    angle = np.degrees(Rotation.from_matrix(rot @ _rotation(5).T).magnitude())
    assert angle < 1.5
    np.testing.assert_allclose(apply(refined, source), seen, atol=0.01)
    assert overlap_scores(source, surface, refined[None], 0.02)[0] > 0.9
    assert overlap_scores(source, surface, start[None], 0.02)[0] < 0.5


@settings(max_examples=30, deadline=None)
@given(
    yaw=st.floats(-3.0, 3.0),
    scale=st.floats(0.7, 1.4),
    shift=st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3),
)
def test_yaw_fit_recovers_a_turn_about_the_vertical(yaw, scale, shift):
    rng = np.random.default_rng(4)
    src = rng.normal(size=(1, 40, 3))
    rz = Rotation.from_euler("z", yaw).as_matrix()
    dst = scale * src @ rz.T + np.asarray(shift)
    fitted = _fit_yaw(src, dst, np.ones((1, 40)), True, (0.5, 2.0))[0]
    np.testing.assert_allclose(fitted[:3, :3], scale * rz, atol=1e-9)
    np.testing.assert_allclose(fitted[:3, 3], shift, atol=1e-9)


def test_upright_icp_keeps_the_start_tilt():
    rng = np.random.default_rng(5)
    surface, _ = _box_surface(rng)
    truth = similarity_matrix(1.0, _rotation(5), np.array([0.2, -0.1, 0.4]))
    camera_world = apply(truth, np.zeros((1, 3)))[0]
    facing = (surface.normals * (camera_world - surface.points)).sum(axis=1) > 0.0
    source = apply(np.linalg.inv(truth), surface.points[facing][::2])
    # Start at the true tilt, turned 8 deg about the vertical and shifted.
    turn = np.eye(4)
    turn[:3, :3] = Rotation.from_euler("z", 0.14).as_matrix()
    start = turn @ truth
    start[:3, 3] += [0.04, -0.03, 0.0]
    refined = icp(source, surface, start[None], 0.1, 40, True, (0.5, 2.0), upright=True)[0]
    # No tilt added: the world z row of the rotation is the start's (the scale may change).
    scale = np.cbrt(np.linalg.det(refined[:3, :3]))
    np.testing.assert_allclose(refined[2, :3] / scale, truth[2, :3], atol=1e-9)
    np.testing.assert_allclose(apply(refined, source), apply(truth, source), atol=0.01)


def test_icp_excuses_the_surface_a_nearer_thing_hides():
    rng = np.random.default_rng(0)
    surface, pose = _box_surface(rng)
    centre = pose[:3, 3] + [0.0, 0.0, 0.1]
    truth = camera.look_at(centre + np.array([1.0, -0.7, 0.6]), centre)
    K = camera.intrinsics_from_fovy(512, 512, np.radians(45.0))
    facing = seen_target(surface.points, surface.normals, truth[None], None)[0]
    local = apply(np.linalg.inv(pose), surface.points)
    hidden = facing & (local[:, 1] > 0.0)
    # An arm 0.3 m in front of the camera covers the half of the box with y > 0.
    in_cam = camera.to_camera(surface.points, truth)
    depth = np.zeros((512, 512))
    for u, v in np.floor(camera.project(in_cam[hidden], K)).astype(int):
        depth[max(v - 3, 0) : v + 4, max(u - 3, 0) : u + 4] = 0.3
    view = View(depth, K, np.ones(3), np.zeros(3), 0.05)
    seen = seen_target(surface.points, surface.normals, truth[None], view)[0]
    assert np.mean(seen == (facing & ~hidden)) > 0.97
    visible = in_cam[facing & ~hidden][::2]
    source = visible + rng.normal(0.0, 0.002, visible.shape)
    turn = np.eye(4)
    turn[:3, :3] = Rotation.from_euler("z", 0.14).as_matrix()
    start = turn @ truth
    start[:3, 3] += [0.04, -0.03, 0.0]
    for v, max_angle in ((view, 1.0), (None, None)):
        refined = icp(source, surface, start[None], 0.1, 40, True, (0.5, 2.0), view=v)[0]
        s, rot, _ = decompose_similarity(refined)
        angle = np.degrees(Rotation.from_matrix(rot @ truth[:3, :3].T).magnitude())
        if max_angle is not None:
            assert angle < max_angle and s == pytest.approx(1.0, abs=0.01)
        else:  # asked for points on the hidden half too, ICP stretches the cloud over it
            assert angle > 5.0 and s > 1.1


def test_axis_refinement_recovers_a_stretched_variant():
    rng = np.random.default_rng(3)
    surface, pose = _box_surface(rng)
    stretch = np.array([1.08, 0.93, 1.05])  # the variant's extents, relative to the object's
    similarity = similarity_matrix(1.0, _rotation(5), np.array([0.2, -0.1, 0.4]))
    # The variant's visible faces, seen from the gen frame's origin, in the gen frame.
    variant = stretch[:, None] * np.eye(3)
    T_stretch = pose @ np.block([[variant, np.zeros((3, 1))], [0, 0, 0, 1]]) @ np.linalg.inv(pose)
    camera_world = apply(similarity, np.zeros((1, 3)))[0]
    facing = (surface.normals * (camera_world - surface.points)).sum(axis=1) > 0.0
    seen = apply(T_stretch, surface.points[facing][::2])
    source = apply(np.linalg.inv(similarity), seen)
    before = np.linalg.norm(apply(similarity, source) - surface.points[facing][::2], axis=1)
    affine, factors = refine_axes(source, surface, similarity, 0.1, 40, 0.15, 0.0)
    after = np.linalg.norm(apply(affine, source) - surface.points[facing][::2], axis=1)
    np.testing.assert_allclose(factors, 1.0 / stretch, atol=0.02)
    assert np.median(after) < 0.2 * np.median(before)
    # A prior that outweighs the data keeps the similarity.
    _, stiff = refine_axes(source, surface, similarity, 0.1, 40, 0.15, 100.0)
    np.testing.assert_allclose(stiff, 1.0, atol=1e-3)


def test_turns_and_levelling_keep_the_object_upright():
    rng = np.random.default_rng(1)
    _, pose = _box_surface(rng)
    tilted = similarity_matrix(0.9, _rotation(11), np.array([0.3, 0.2, 1.0]))
    up_gen = np.array([0.0, -1.0, 0.2]) / np.linalg.norm([0.0, -1.0, 0.2])
    pivot = np.array([0.0, 0.1, 2.5])
    levelled = level(tilted[None], up_gen, pivot)
    assert tilt_errors(levelled, up_gen)[0] < 1e-6
    np.testing.assert_allclose(apply(levelled, pivot[None]), apply(tilted[None], pivot[None]))
    turned = turn_about_object(levelled, pose, 4)
    assert turned.shape == (1, 4, 4, 4)
    assert np.all(tilt_errors(turned[0], up_gen) < 1e-6)


def test_selection_takes_the_best_overlap_that_is_upright_and_faces_the_person():
    cfg = RegistrationCfg(max_facing_deg=45.0, max_tilt_deg=20.0)
    overlaps = np.array([0.9, 0.7, 0.8, 0.95])
    tilts = np.array([2.0, 3.0, 1.0, 80.0])  # the best overlap is lying on its side
    facing = np.array([90.0, 5.0, 30.0, 0.0])  # the next best turns its side to the person
    assert select(overlaps, gates(tilts, facing, cfg)) == 2
    # No facing known, or nobody passes a gate: that gate is dropped.
    assert select(overlaps, gates(tilts, np.full(4, np.nan), cfg)) == 0
    assert select(overlaps, gates(tilts, np.full(4, 90.0), cfg)) == 0
    assert select(overlaps, gates(np.full(4, 90.0), facing, cfg)) == 3


def test_first_hypothesis_is_top1_and_draws_stay_valid():
    rng = np.random.default_rng(2)
    valid = rng.random((30, 5)) > 0.3
    valid[:, 1] = True
    choice = draw_hypotheses(valid, 12, rng)
    assert choice.shape == (12, 30)
    assert np.all(valid[np.arange(30), choice[1:]])
    np.testing.assert_array_equal(choice[0], valid.argmax(axis=1))


@pytest.mark.parametrize("kind", sorted(OBJECT_KINDS))
def test_surface_projection_lands_on_or_outside_every_primitive(kind):
    primitives = object_geometry(kind, SIZES[kind]).primitives
    rng = np.random.default_rng(4)
    lo = np.min([np.asarray(p.pos) - 0.6 for p in primitives], axis=0)
    hi = np.max([np.asarray(p.pos) + 0.6 for p in primitives], axis=0)
    points = rng.uniform(lo, hi, size=(400, 3))
    # Points deep inside each primitive too, the hard case.
    points = np.vstack(
        [points, *[np.asarray(p.pos) + rng.normal(0, 0.005, (20, 3)) for p in primitives]]
    )
    projected, normals = project_to_surface(points, primitives)
    depth = np.stack([signed_distance(projected, p) for p in primitives])
    assert depth.min() >= -1e-9
    assert np.abs(depth.min(axis=0)).max() < 1e-9  # on the surface of some primitive
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0, atol=1e-9)
    outside = np.stack([signed_distance(points, p) for p in primitives]).min(axis=0) > 1e-3
    gap = np.linalg.norm(projected - points, axis=1)
    np.testing.assert_allclose(
        gap[outside],
        np.stack([signed_distance(points, p) for p in primitives]).min(axis=0)[outside],
        atol=1e-9,
    )


def test_a_hand_goes_onto_the_parts_that_carry_a_patch():
    """A trolley is held by its handle bar (or its platform), never by the posts that carry
    the bar, though a hand the registration put 8 cm below the bar is nearer a post."""
    geometry = object_geometry("trolley", SIZES["trolley"])
    held = held_parts(geometry.primitives, geometry.patches)
    assert sorted(p.name for p in held) == ["handle", "platform"]
    table = object_geometry("table", SIZES["table"])
    assert [p.name for p in held_parts(table.primitives, table.patches)] == ["top"]
    box = object_geometry("box", SIZES["box"])
    assert held_parts(box.primitives, ()) == box.primitives  # no patches: every part
    bar = next(p for p in geometry.patches if p.name == "handle")
    post = next(p for p in geometry.primitives if p.name == "post_left")
    hand = np.array([[bar.centre[0] - 0.01, post.pos[1] - 0.04, bar.centre[2] - 0.08]])
    on_post, _ = project_to_surface(hand, geometry.primitives)
    on_bar, _ = project_to_surface(hand, geometry.primitives, held)
    assert abs(signed_distance(on_post, post)[0]) < 1e-9
    handle = next(p for p in held if p.name == "handle")
    assert abs(signed_distance(on_bar, handle)[0]) < 1e-9
    assert on_bar[0, 2] == pytest.approx(bar.centre[2] - handle.size[2])
    assert min(signed_distance(on_bar, p)[0] for p in geometry.primitives) > -1e-9


@settings(max_examples=60, deadline=None)
@given(
    shape=st.sampled_from(["box", "cylinder", "sphere"]),
    point=st.tuples(*[st.floats(-0.5, 0.5)] * 3),
)
def test_closest_point_on_a_primitive_is_on_its_surface(shape, point):
    size = {"box": (0.2, 0.1, 0.15), "cylinder": (0.1, 0.2), "sphere": (0.12,)}[shape]
    prim = Primitive(shape, size, (0.05, -0.02, 0.1), "p")
    q, n = closest_on_primitive(np.array([point]), prim)
    assert abs(signed_distance(q, prim)[0]) < 1e-9
    assert np.linalg.norm(n) == pytest.approx(1.0)


def test_feet_go_on_the_floor_or_the_top_never_on_a_side():
    primitives = object_geometry("box", (0.4, 0.4, 0.2)).primitives
    feet = np.array([[-0.5, 0.1, 0.03], [0.05, -0.1, 0.25], [-0.21, 0.0, 0.1]])
    q, n = project_to_support(feet, primitives, floor_z=0.0)
    np.testing.assert_allclose(q[0], [-0.5, 0.1, 0.0])
    np.testing.assert_allclose(q[1], [0.05, -0.1, 0.2])
    assert q[2, 2] in (0.0, 0.2)  # beside the box's face: floor or top, not the face
    np.testing.assert_allclose(n, np.tile([0.0, 0.0, 1.0], (3, 1)))


def test_anchor_undoes_the_heuristic_intrinsics_and_depth_scale():
    rng = np.random.default_rng(5)
    pose = rng.normal(0.0, 0.4, size=(21, 3)) + np.array([0.0, 0.0, 3.0])
    k_xy, k_z = 1.3 * 1.05, 1.05  # focal ratio 1.3, depth scale 1.05
    lifted = pose * np.array([k_xy, k_xy, k_z])
    lifted[:4] *= 0.8  # four keypoints hidden behind something: nearer along their ray
    anchor = fit_anchor(pose, lifted, np.ones(21, dtype=bool), quantile=0.9)
    np.testing.assert_allclose(anchor.scale, [k_xy, k_xy, k_z], rtol=1e-9)
    np.testing.assert_allclose(anchor(pose[4:]), lifted[4:], atol=1e-9)
    np.testing.assert_allclose(anchor.undo(anchor(pose)), pose, atol=1e-12)
    with pytest.raises(ValueError, match="usable keypoints"):
        fit_anchor(pose, lifted, np.arange(21) < 3, 0.9)


def test_support_up_points_from_the_soles_to_the_pelvis():
    soles = np.array([[0.0, 1.0, 3.0], [0.1, 1.0, 3.1], [0.2, 1.0, 3.0], [0.3, 1.0, 3.2]])
    up = support_up(soles, np.array([0.1, 0.1, 3.0]))  # camera y points down
    np.testing.assert_allclose(up, [0.0, -1.0, 0.0], atol=1e-12)
    assert support_up(np.full((4, 3), np.nan), np.zeros(3)) is None


def _striped(h: int = 64, w: int = 64) -> tuple[np.ndarray, np.ndarray]:
    rgb = np.zeros((h, w, 3), np.uint8)
    rgb[:, :, 0] = (np.arange(w) * 4)[None, :]
    rgb[::8] = 255
    mask = np.zeros((h, w), bool)
    mask[10:50, 12:52] = True
    return rgb, mask


def test_sift_pool_matches_an_image_to_itself():
    rgb, mask = _striped()
    describe = semantic.make_describer(PoolCfg())
    px = semantic.mask_pixels(mask, np.ones_like(mask), 2)
    desc = describe(rgb, mask, px)
    np.testing.assert_allclose(np.linalg.norm(desc, axis=1), 1.0, atol=1e-6)
    pool = semantic.score_pool(desc[::7], desc, px, px[::7], top_n=3)
    assert pool.sim_px.shape == (len(px[::7]), 3, 2)
    assert np.all(pool.scores[:, 0] >= pool.scores[:, 1])
    np.testing.assert_array_equal(pool.sim_px[:, 0], px[::7])


def test_a_mask_with_too_few_points_gets_a_clear_error():
    mask = np.zeros((32, 32), bool)
    mask[5, 5:7] = True
    with pytest.raises(SceneError, match=r"subtask 3.*2 pixels with depth.*at least 3"):
        semantic.sample_pixels(mask, np.ones_like(mask), 64, np.random.default_rng(0), "subtask 3")


def test_learned_descriptor_loads_torchscript_and_fails_clearly(tmp_path):
    torch = pytest.importorskip("torch")
    with pytest.raises(ModelError, match="weights_file"):
        semantic.LearnedDescriber(None)
    with pytest.raises(ModelError, match="does not exist"):
        semantic.LearnedDescriber(str(tmp_path / "missing.pt"))
    junk = tmp_path / "junk.pt"
    junk.write_bytes(b"not a model")
    with pytest.raises(ModelError, match="not a TorchScript module"):
        semantic.LearnedDescriber(str(junk))
    torch.manual_seed(0)
    backbone = torch.nn.Sequential(torch.nn.Conv2d(3, 8, 3, stride=2, padding=1), torch.nn.ReLU())
    path = tmp_path / "backbone.pt"
    torch.jit.save(torch.jit.trace(backbone, torch.rand(1, 3, 32, 32)), str(path))
    describe = semantic.make_describer(PoolCfg(descriptor="learned", weights_file=str(path)))
    rgb, mask = _striped()
    desc = describe(rgb, mask, np.array([[20.0, 20.0], [40.0, 30.0]]))
    assert desc.shape == (2, 8)
    np.testing.assert_allclose(np.linalg.norm(desc, axis=1), 1.0, atol=1e-6)


def test_learned_descriptor_without_torch_says_which_extra_installs_it(tmp_path, monkeypatch):
    """issue 53: a raw ModuleNotFoundError, where the other learned backends named the extra."""
    weights = tmp_path / "backbone.pt"
    weights.write_bytes(b"")
    monkeypatch.setitem(sys.modules, "torch", None)  # import torch raises ImportError
    with pytest.raises(ModelError, match=r"pip install -e \.\[learned\]"):
        semantic.LearnedDescriber(str(weights))


def test_contacts_config_rejects_bad_values():
    from locoman.config.schema import walk_checks

    bad = ContactsCfg(method="guess", lift="psychic")
    bad.registration.scale_range = [2.0, 1.0]
    bad.pool.top_n = 0
    keys = {key for key, _ in walk_checks(bad)}
    assert {"method", "lift", "registration.scale_range", "pool.points"} <= keys


def _viewed_box(rng: np.random.Generator):
    """A box's surface, a camera looking at it, what the camera sees of it (its cloud in
    the camera frame) and its silhouette in the image."""
    surface, pose = _box_surface(rng)
    centre = pose[:3, 3] + [0.0, 0.0, 0.1]
    truth = camera.look_at(centre + np.array([1.0, -0.7, 0.6]), centre)
    K = camera.intrinsics_from_fovy(256, 256, np.radians(45.0))
    view = View(np.zeros((256, 256)), K, np.ones(3), np.zeros(3), 0.05)
    facing = seen_target(surface.points, surface.normals, truth[None], None)[0]
    source = camera.to_camera(surface.points[facing][::2], truth)
    # The mask is the silhouette the true pose draws (what a perfect segmentation gives).
    mask = np.zeros((256, 256), dtype=bool)
    for u, v in np.floor(camera.project(camera.to_camera(surface.points, truth), K)).astype(int):
        if 0 <= u < 256 and 0 <= v < 256:
            mask[v, u] = True
    mask = ndimage.binary_fill_holes(ndimage.binary_dilation(mask, iterations=3))
    return surface, truth, view, source, mask


def _registration(candidates: np.ndarray, overlaps: np.ndarray, best: int) -> Registration:
    h = len(candidates)
    return Registration(
        transform=candidates[best],
        affine=candidates[best],
        stretch=np.ones(3),
        overlap=float(overlaps[best]),
        iteration=best + 1,
        turn=0,
        overlaps=overlaps.reshape(h, 1),
        scales=np.ones((h, 1)),
        tilt_deg=np.zeros((h, 1)),
        facing_error_deg=np.zeros((h, 1)),
        candidates=candidates.reshape(h, 1, 4, 4),
        gated=np.ones((h, 1), dtype=bool),
    )


def test_a_registration_in_a_wrong_basin_is_flagged_and_a_right_one_is_not():
    """ICP started a quarter turn off converges in another basin: its silhouette in the
    image is not the object's, and another pose fits the cloud as well; from near the truth
    it converges there and every signal is high."""
    rng = np.random.default_rng(2)
    surface, truth, view, source, mask = _viewed_box(rng)
    near = truth.copy()
    near[:3, 3] += [0.02, -0.01, 0.0]
    turn = np.eye(4)
    turn[:3, :3] = Rotation.from_euler("z", np.pi / 2).as_matrix()
    pivot = surface.T_world_object[:3, 3]
    turn[:3, 3] = pivot - turn[:3, :3] @ pivot
    starts = np.stack([near, turn @ truth])
    refined = icp(source, surface, starts, 0.1, 40, False, (1.0, 1.0), upright=True, view=view)
    overlaps = overlap_scores(source, surface, refined, 0.01, view)
    cfg = ConfidenceCfg()
    right = confidence(_registration(refined, overlaps, 0), surface, source, view, mask, cfg, {})
    assert not right.doubtful, right
    assert right.silhouette_iou > 0.8 and right.margin > cfg.min_margin
    wrong = confidence(_registration(refined, overlaps, 1), surface, source, view, mask, cfg, {})
    assert wrong.doubtful
    assert any("silhouette" in r or "margin" in r for r in wrong.reasons), wrong.reasons
    assert wrong.silhouette_iou < right.silhouette_iou


def test_a_pose_that_places_the_cloud_alike_is_no_rival():
    """Two hypotheses a millimetre apart are the same pose: no margin is asked between
    them; one that moves the cloud by a tenth of the object is another."""
    rng = np.random.default_rng(3)
    source = rng.normal(size=(200, 3))
    a = np.eye(4)
    b = np.eye(4)
    b[:3, 3] = [0.001, 0.0, 0.0]
    c = np.eye(4)
    c[:3, 3] = [0.2, 0.0, 0.0]
    moved = cloud_moved(np.stack([a, b, c]), a, source)
    np.testing.assert_allclose(moved, [0.0, 0.001, 0.2], atol=1e-12)


def test_a_hand_that_lands_off_the_object_makes_the_registration_doubtful():
    """The same right registration: a hand placed a handspan off the object it holds is
    named, and a foot's drop to the floor is not a gap."""
    rng = np.random.default_rng(2)
    surface, truth, view, source, mask = _viewed_box(rng)
    refined = icp(source, surface, truth[None], 0.1, 40, False, (1.0, 1.0), upright=True)
    reg = _registration(refined, np.array([0.9]), 0)
    cfg = ConfidenceCfg()
    close = confidence(reg, surface, source, view, mask, cfg, {"left_hand": 0.01})
    assert not close.doubtful, close
    far = confidence(reg, surface, source, view, mask, cfg, {"left_hand": 0.01, "right_hand": 0.08})
    assert far.doubtful
    assert far.reasons == ("right_hand lands 8.0 cm off the object > 0.06 m",)
    raw = np.array([[0.0, 0.0, 0.08], [0.3, 0.0, 0.5]])
    projected = np.array([[0.0, 0.0, 0.0], [0.3, 0.04, 0.5]])
    gaps = contact_gaps(raw, projected, ["left_foot", "right_hand"])
    np.testing.assert_allclose(gaps, [0.0, 0.04])


@settings(max_examples=40, deadline=None)
@given(
    stretch=st.tuples(*[st.floats(0.8, 1.25)] * 3),
    yaw=st.floats(-np.pi, np.pi),
    standoff=st.floats(0.1, 0.8),
    side=st.floats(-0.3, 0.3),
)
def test_a_foot_keeps_its_offset_from_the_approach_face_and_a_hand_is_stretched_with_it(
    stretch, yaw, standoff, side
):
    """Under an affine map A = [R D | t] (a turn R, a per-axis stretch D), a hand on the
    object and a foot on its top go where A puts them; a foot on the floor ``standoff``
    metres in front of the approach face and ``side`` metres off its centre line stays there
    whatever the stretch (the person does not move with the variant's size)."""
    table = (Primitive("box", (0.3, 0.4, 0.02), (0.0, 0.0, 0.7), "top"),)
    T_world_object = np.eye(4)
    T_world_object[:3, :3] = Rotation.from_euler("z", 0.4).as_matrix()
    T_world_object[:3, 3] = [1.0, -2.0, 0.0]
    rot = Rotation.from_euler("z", yaw).as_matrix() @ T_world_object[:3, :3]
    affine = np.eye(4)
    affine[:3, :3] = rot @ np.diag(stretch)
    affine[:3, 3] = [0.5, 0.2, -0.1]
    undo = np.linalg.inv(affine)
    world = lambda p: camera.transform(np.array([p]), T_world_object)[0]  # noqa: E731
    face_centre = world([-0.3, 0.0, 0.0])
    floor_foot = world([-0.3 - standoff, side, 0.0])
    top_foot, hand = world([0.1, 0.11, 0.72]), world([0.05, 0.4, 0.7])
    gen_face = apply(undo, face_centre[None])[0]
    lifted = np.stack(
        [
            apply(undo, hand[None])[0],
            gen_face + rot.T @ (floor_foot - face_centre),  # the person's offset in R_g
            apply(undo, top_foot[None])[0],
        ]
    )
    effectors = ["left_hand", "left_foot", "right_foot"]
    placed = place_contacts(affine, lifted, effectors, table, T_world_object)
    np.testing.assert_allclose(placed, [hand, floor_foot, top_foot], atol=1e-9)
