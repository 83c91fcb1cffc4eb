"""Issue 50: the ``folder`` image backend (the user's images) and the 3D pose fit.

The committed folder ``data/tiny/user_images`` (tiny's three subtasks, rendered once at 256 px
with annotations and depth) runs through the stage code from ``generate`` to ``contacts``;
bad folders stop with an :class:`InputError` that names the file; the pose fit's Jacobian is
checked against finite differences and the fit recovers a known pose.
"""

from __future__ import annotations

import dataclasses
import json
import shutil
from pathlib import Path

import cv2
import mujoco
import numpy as np
import pytest

from locoman.artifacts import read_json, read_npz
from locoman.config.perception import CloudsCfg, DepthErrorCfg, FolderCfg, GenerateCfg, MasksCfg
from locoman.contact.io import CONTACTS, subtask_file
from locoman.errors import ConfigError, InputError
from locoman.perception import camera, pose_fit
from locoman.perception.clouds import clouds_scenario
from locoman.perception.demonstrator import CROUCH, KEYPOINTS
from locoman.perception.generate import generate_scenario
from locoman.perception.io import MASKS, POSE, PROMPTS, PROMPTS_FILE, SUBTASKS_DIR, subtask_dir
from locoman.perception.masks import masks_scenario
from locoman.perception.user_images import USER_INPUT, USER_INPUT_FILE, read_user_image
from locoman.scene.io import load_objects

FOLDER = Path(__file__).resolve().parents[1] / "data" / "tiny" / "user_images"
SIZE = 256  # [px] the committed images


def _folder_cfg(images_dir: Path) -> GenerateCfg:
    return GenerateCfg(backend="folder", folder=FolderCfg(images_dir=str(images_dir)))


FOLDER_MASKS = MasksCfg(backend="grabcut", keypoints="annotated", pose="fit")


@pytest.fixture(scope="module")
def folder_run(tiny_scene, params, tmp_path_factory) -> Path:
    """generate -> masks -> clouds -> contacts on the committed folder."""
    from locoman.contact.pipeline import contacts_scenario

    out = tmp_path_factory.mktemp("folder_run")
    generate_scenario("tiny", tiny_scene, out / "generate", _folder_cfg(FOLDER), 0)
    masks_scenario("tiny", out / "generate", out / "masks", FOLDER_MASKS, 0)
    clouds_scenario(
        "tiny",
        out / "generate",
        out / "masks",
        out / "clouds",
        CloudsCfg(depth="provided"),
        DepthErrorCfg(),
        0,
    )
    contacts_scenario(
        "tiny",
        tiny_scene,
        out / "generate",
        out / "masks",
        out / "clouds",
        out / "contacts",
        params.contacts,
        0,
    )
    return out


def test_the_users_images_run_from_generate_to_contacts(folder_run, tiny_scene):
    prompts = read_json(folder_run / "generate" / PROMPTS_FILE, PROMPTS)
    assert prompts["backend"] == "folder" and len(prompts["subtasks"]) == 3
    generate = json.loads((folder_run / "generate" / "metrics.json").read_text())
    assert generate["ground_truth"] is False and "no ground truth" in generate["not_scored"]
    assert not any((folder_run / "generate" / "ground_truth").iterdir())
    # Provenance without a path: the hash of each subtask's files.
    details = json.loads((folder_run / "generate" / "details.json").read_text())
    assert all(len(r["source_sha256"]) == 64 for r in details["per_subtask"])
    assert str(FOLDER) not in (folder_run / "generate" / PROMPTS_FILE).read_text()
    objects = load_objects(tiny_scene)
    for entry in prompts["subtasks"]:
        i = entry["index"]
        user = read_npz(subtask_dir(folder_run / "generate", i) / USER_INPUT_FILE, USER_INPUT)
        assert bool(user["depth_given"]) and user["depth_m"].shape == (SIZE, SIZE)
        masks = read_npz(folder_run / "masks" / SUBTASKS_DIR / f"subtask_{i}.npz", MASKS)
        # grabcut inside the user's box: the mask lies within it.
        v, u = np.nonzero(masks["object_mask"])
        u0, _, u1, v1 = user["object_box_px"]
        assert len(u) > 100 and u.min() >= u0 and u.max() <= u1 and v.max() <= v1
        pose = read_npz(folder_run / "masks" / SUBTASKS_DIR / f"pose_{i}.npz", POSE)
        assert 1.0 < pose["T_cam_pelvis"][2, 3] < 6.0  # the person in front of the camera
        contacts = read_npz(subtask_file(folder_run / "contacts", i), CONTACTS)
        # Hands on the box (within 5 cm of its extents), feet on the floor.
        local = contacts["points_object_m"]
        size = np.asarray(objects[entry["object"]]["size_m"], float)
        if entry["object"] == "box":
            half = 0.5 * size[:2] + 0.05
            assert np.all(np.abs(local[:, :2]) <= half), local
            assert np.all((local[:, 2] > -0.05) & (local[:, 2] < size[2] + 0.05)), local
        else:
            assert np.all(np.abs(contacts["points_world_m"][:, 2]) < 0.02)
    metrics = json.loads((folder_run / "contacts" / "metrics.json").read_text())
    assert metrics["contact_error_median_m"] is None  # no truth to score against
    details = json.loads((folder_run / "contacts" / "details.json").read_text())
    assert all(0.0 < r["overlap"] <= 1.0 for r in details["per_subtask"])


def test_masks_metrics_name_the_fit_and_score_nothing(folder_run):
    metrics = json.loads((folder_run / "masks" / "metrics.json").read_text())
    assert metrics["pose_backend"] == "fit" and "pose_backends" not in metrics
    assert "mask_iou" not in metrics


def _copy(tmp_path: Path) -> Path:
    folder = tmp_path / "images"
    shutil.copytree(FOLDER, folder)
    return folder


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda f: (f / "subtask_1.png").unlink(), r"no image for subtask 1"),
        (lambda f: shutil.copy(f / "subtask_0.png", f / "subtask_7.png"), r"subtask_7\.png: not"),
        (lambda f: shutil.copy(f / "subtask_0.png", f / "subtask_0.jpg"), r"two images"),
        (lambda f: (f / "subtask_0.json").write_text("{"), r"not JSON"),
        (lambda f: (f / "subtask_0.json").write_text('{"box": [0, 0, 9, 9]}'), r"the keys"),
        (
            lambda f: (f / "subtask_0.json").write_text('{"object_box_px": [9, 0, 3, 9]}'),
            r"u0 < u1",
        ),
        (
            lambda f: (f / "subtask_0.json").write_text('{"keypoints_px": {"tail": [1, 2]}}'),
            r"keypoints_px maps names",
        ),
        (
            lambda f: (f / "subtask_0.json").write_text('{"keypoints_px": {"head": [1]}}'),
            r"keypoints_px\.head: needs 2 finite numbers",
        ),
        (
            lambda f: cv2.imwrite(str(f / "subtask_0_depth.png"), np.zeros((8, 8), np.uint16)),
            r"8 x 8 px; the image is 256 x 256",
        ),
        (
            lambda f: cv2.imwrite(str(f / "subtask_0_depth.png"), np.zeros((256, 256), np.uint8)),
            r"16-bit PNG in mm",
        ),
        (
            lambda f: cv2.imwrite(str(f / "subtask_2.png"), np.zeros((32, 32, 3), np.uint8)),
            r"32 x 32 px; each side must be 64-4096",
        ),
    ],
)
def test_a_bad_folder_is_an_input_error_naming_the_file(tiny_scene, tmp_path, change, message):
    folder = _copy(tmp_path)
    change(folder)
    with pytest.raises(InputError, match=message):
        generate_scenario("tiny", tiny_scene, tmp_path / "out", _folder_cfg(folder), 0)
    assert not (tmp_path / "out" / PROMPTS_FILE).exists()


def test_no_folder_is_an_input_error_and_no_path_a_config_error(tiny_scene, tmp_path):
    with pytest.raises(InputError, match="no folder"):
        generate_scenario("tiny", tiny_scene, tmp_path, _folder_cfg(tmp_path / "absent"), 0)
    assert "folder.images_dir" in dict(GenerateCfg(backend="folder").check())


def test_steps_that_need_what_the_folder_lacks_say_what_to_set(folder_run, tmp_path):
    generate = folder_run / "generate"
    for cfg, error, message in (
        (dataclasses.replace(FOLDER_MASKS, pose="truth_noise"), ConfigError, "pose=fit"),
        (dataclasses.replace(FOLDER_MASKS, keypoints="render"), ConfigError, "annotated"),
        (dataclasses.replace(FOLDER_MASKS, backend="render"), ConfigError, "grabcut or sam"),
    ):
        with pytest.raises(error, match=message):
            masks_scenario("tiny", generate, tmp_path / "masks", cfg, 0)
    for cfg, message in (
        (CloudsCfg(depth="error_model"), "depth_anything"),
        (CloudsCfg(depth="provided", intrinsics="true"), "render backend"),
    ):
        with pytest.raises((InputError, Exception), match=message):
            clouds_scenario(
                "tiny", generate, folder_run / "masks", tmp_path / "c", cfg, DepthErrorCfg(), 0
            )


def test_a_folder_without_boxes_or_depth_stops_where_they_are_needed(
    folder_run, tiny_scene, tmp_path
):
    folder = _copy(tmp_path)
    for i in range(3):
        notes = json.loads((folder / f"subtask_{i}.json").read_text())
        del notes["object_box_px"]
        (folder / f"subtask_{i}.json").write_text(json.dumps(notes))
        (folder / f"subtask_{i}_depth.png").unlink()
    generate_scenario("tiny", tiny_scene, tmp_path / "g", _folder_cfg(folder), 0)
    with pytest.raises(ConfigError, match="object_box_px"):
        masks_scenario("tiny", tmp_path / "g", tmp_path / "m", FOLDER_MASKS, 0)
    # Depth: with the run's masks (the same images), provided depth is missing.
    with pytest.raises(InputError, match=r"subtask_<i>_depth\.png"):
        clouds_scenario(
            "tiny",
            tmp_path / "g",
            folder_run / "masks",
            tmp_path / "c",
            CloudsCfg(depth="provided"),
            DepthErrorCfg(),
            0,
        )


# --- The pose fit ---------------------------------------------------------------------


@pytest.fixture(scope="module")
def human_model() -> mujoco.MjModel:
    return pose_fit.human_model()


def _posed(model: mujoco.MjModel) -> np.ndarray:
    """A crouched person 2.5 m in front of the camera, turned 40 deg from it."""
    q = pose_fit._seed_qpos(model, pose_fit._seed_rotation(np.deg2rad(40.0)), [0.1, 0.2, 2.5], {})
    for name, value in CROUCH.items():
        q[model.jnt_qposadr[model.joint(name).id]] = 0.6 * value
    q[model.jnt_qposadr[model.joint("left_elbow_Z").id]] = 0.9
    return q


def test_the_reprojection_jacobian_matches_finite_differences(human_model):
    model, data = human_model, mujoco.MjData(human_model)
    K = camera.heuristic_intrinsics(512, 512)
    q = _posed(model)
    keypoints = [(model.body(b).id, off) for b, off in KEYPOINTS.values()]
    px = np.zeros((len(keypoints), 2))
    err, jac = pose_fit._reprojection(model, data, q, keypoints, px, K)
    eps, numeric = 1e-6, np.zeros_like(jac)
    for k in range(model.nv):
        dq = np.zeros(model.nv)
        dq[k] = eps
        qp = q.copy()
        mujoco.mj_integratePos(model, qp, dq, 1.0)
        err_p, _ = pose_fit._reprojection(model, data, qp, keypoints, px, K)
        numeric[:, k] = -(err_p - err) / eps  # err = px - uv
    assert np.allclose(jac, numeric, atol=1e-3 * np.abs(jac).max())


def test_the_fit_recovers_a_known_pose_from_its_keypoints(human_model):
    model = human_model
    K = camera.heuristic_intrinsics(512, 512)
    q = _posed(model)
    true_kp = pose_fit.keypoints_world(model, q)
    px = camera.project(true_kp, K) - 0.5  # pixel indices
    fit = pose_fit.fit_pose(model, px, np.ones(len(px)), K)
    est = pose_fit.keypoints_world(model, fit.qpos)
    assert fit.rms_px < 2.0
    posture = np.linalg.norm((est - est[0]) - (true_kp - true_kp[0]), axis=1).mean()
    # [m] mean keypoint error with the pelvises aligned: 62 mm here, limbs towards or away
    # from the camera project alike (monocular methods report 50-80 mm on real datasets)
    assert posture < 0.08
    assert abs(est[0, 2] - true_kp[0, 2]) < 0.15  # the limb lengths give the depth


def test_the_fit_needs_enough_keypoints(human_model):
    px = np.full((len(KEYPOINTS), 2), np.nan)
    px[:5] = 100.0
    with pytest.raises(InputError, match="at least 6 2D keypoints, found 5"):
        pose_fit.fit_pose(human_model, px, np.ones(len(px)), camera.heuristic_intrinsics(64, 64))


def _formats(bgr: np.ndarray) -> dict[str, np.ndarray]:
    grey = cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY)
    return {
        "grey": grey,
        "grey, 16-bit": grey.astype(np.uint16) * 257,
        "RGBA": cv2.cvtColor(bgr, cv2.COLOR_BGR2BGRA),
        "RGB, 16-bit": bgr.astype(np.uint16) * 257,
    }


@pytest.mark.parametrize("kind", ["grey", "grey, 16-bit", "RGBA", "RGB, 16-bit"])
def test_a_users_image_of_another_format_is_read_as_8_bit_rgb(tmp_path, kind):
    folder = _copy(tmp_path)
    bgr = cv2.imread(str(folder / "subtask_0.png"), cv2.IMREAD_COLOR)
    image = _formats(bgr)[kind]
    assert cv2.imwrite(str(folder / "subtask_0.png"), image)
    rgb, arrays, _ = read_user_image(folder, 0)
    assert rgb.dtype == np.uint8 and rgb.shape == (SIZE, SIZE, 3)
    expected = cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)
    if kind.startswith("grey"):
        expected = np.repeat(cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY)[..., None], 3, axis=2)
    np.testing.assert_array_equal(rgb, expected)
    assert arrays["depth_given"]


def test_a_grey_16_bit_image_runs_through_masks(tiny_scene, tmp_path):
    """A photograph saved as 16-bit grey reaches masks as any image does."""
    folder = _copy(tmp_path)
    for i in range(3):
        bgr = cv2.imread(str(folder / f"subtask_{i}.png"), cv2.IMREAD_COLOR)
        cv2.imwrite(str(folder / f"subtask_{i}.png"), _formats(bgr)["grey, 16-bit"])
    out = tmp_path / "out"
    generate_scenario("tiny", tiny_scene, out / "generate", _folder_cfg(folder), 0)
    masks = masks_scenario("tiny", out / "generate", out / "masks", FOLDER_MASKS, 0)
    assert masks is not None and (out / "masks" / "metrics.json").is_file()


@pytest.mark.parametrize(
    ("image", "message"),
    [
        (np.zeros((256, 256), np.float32), r"float32 pixels|not an image OpenCV can read"),
        (np.zeros((5000, 80, 3), np.uint8), r"80 x 5000 px; each side must be 64-4096 px: scale"),
    ],
)
def test_an_image_it_cannot_take_says_what_to_do(tiny_scene, tmp_path, image, message):
    folder = _copy(tmp_path)
    ext = ".png" if image.dtype == np.uint8 else ".tiff"
    (folder / "subtask_0.png").unlink()
    path = folder / f"subtask_0{ext}"
    cv2.imwrite(str(path), image)
    if ext != ".png":  # a TIFF under a PNG's name: OpenCV reads its content, not its name
        path.rename(folder / "subtask_0.png")
    with pytest.raises(InputError, match=message):
        generate_scenario("tiny", tiny_scene, tmp_path / "out", _folder_cfg(folder), 0)


def test_a_doubtful_registration_stops_the_stage_or_falls_back_as_on_doubt_says(
    folder_run, tiny_scene, params, tmp_path
):
    """``contacts.on_doubt``: ``fail`` stops at the first doubtful subtask and names it;
    ``fallback`` puts the naive contacts in its place and says so. A registration is made
    doubtful here by asking for a perfect overlap."""
    from locoman.contact.pipeline import contacts_scenario
    from locoman.errors import SceneError

    strict = dataclasses.replace(
        params.contacts,
        confidence=dataclasses.replace(params.contacts.confidence, min_overlap=1.0),
    )

    def run(on_doubt: str) -> dict:
        return contacts_scenario(
            "tiny",
            tiny_scene,
            folder_run / "generate",
            folder_run / "masks",
            folder_run / "clouds",
            tmp_path / on_doubt,
            dataclasses.replace(strict, on_doubt=on_doubt),
            0,
        )

    with pytest.raises(SceneError, match=r"subtask 0 .*doubtful \(overlap .*on_doubt is fail"):
        run("fail")
    metrics = run("fallback")
    rows = metrics["per_subtask"]
    assert [r["used"] for r in rows] == ["naive"] * 3 and all(r["doubtful"] for r in rows)
    for r in rows:
        contacts = read_npz(subtask_file(tmp_path / "fallback", r["index"]), CONTACTS)
        np.testing.assert_array_equal(
            contacts["points_object_m"], contacts["naive_points_object_m"]
        )
