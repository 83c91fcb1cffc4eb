"""Typed artifacts: round trips, determinism, and the errors for bad files."""

from __future__ import annotations

import json

import cv2
import mujoco
import numpy as np
import pytest

from locoman.artifacts import ArtifactSchema, Field, read_json, read_npz, write_json, write_npz
from locoman.artifacts.mcap_io import read_json_messages, write_frame_transforms
from locoman.artifacts.video import write_mp4
from locoman.errors import ArtifactError
from locoman.scene.frames import body_frames
from locoman.scene.io import OBJECTS_FILE, PLAN_FILE, load_objects, load_plan, load_scene_model
from locoman.sim.foxglove import scene_entities

TRAJ = ArtifactSchema(
    "test.trajectory",
    2,
    "solve",
    (
        Field("q", "float64", ("N", 3), "m"),
        Field("dt", "float64", ("N",), "s"),
        Field("names", "str", (3,)),
    ),
)
PLAN = ArtifactSchema("test.plan", 1, "scene", (Field("steps", "list"), Field("robot", "str")))


def _arrays(n: int = 4) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(0)
    return {
        "q": rng.normal(size=(n, 3)),
        "dt": np.full(n, 0.02),
        "names": np.array(["a", "b", "c"]),
    }


def test_npz_round_trip_is_exact_and_deterministic(tmp_path):
    a, b = tmp_path / "a.npz", tmp_path / "b.npz"
    write_npz(a, TRAJ, _arrays())
    write_npz(b, TRAJ, _arrays())
    assert a.read_bytes() == b.read_bytes()
    back = read_npz(a, TRAJ)
    for key, value in _arrays().items():
        np.testing.assert_array_equal(back[key], value)
    assert not list(tmp_path.glob("*.tmp"))


def test_missing_artifact_names_the_producer(tmp_path):
    with pytest.raises(ArtifactError, match=r"test.trajectory.*missing.*stage 'solve'"):
        read_npz(tmp_path / "none.npz", TRAJ)


def test_corrupt_artifact_is_reported(tmp_path):
    path = tmp_path / "bad.npz"
    write_npz(path, TRAJ, _arrays())
    path.write_bytes(path.read_bytes()[:50])
    with pytest.raises(ArtifactError, match="corrupt"):
        read_npz(path, TRAJ)
    js = tmp_path / "bad.json"
    js.write_text("{not json")
    with pytest.raises(ArtifactError, match="corrupt"):
        read_json(js, PLAN)


def test_a_value_that_is_not_finite_is_named_with_its_place(tmp_path):
    """Issue 53: a NaN in a keyframe ended as a raw ValueError three stages later; it is
    refused where the artifact is read, naming the field, the first bad entry and the stage
    to rerun. A field in which NaN means "none" keeps its NaN."""
    path = tmp_path / "nan.npz"
    arrays = _arrays()
    write_npz(path, TRAJ, arrays)
    with np.load(path, allow_pickle=False) as npz:  # the same file, a NaN written in
        written = {k: npz[k] for k in npz.files}
    written["q"] = np.where(np.eye(4, 3) > 0, np.nan, written["q"])
    np.savez(path, **written)
    with pytest.raises(ArtifactError, match=r"'q' is not finite at \(0, 0\).*stage 'solve'"):
        read_npz(path, TRAJ)
    arrays["dt"][2] = np.inf
    with pytest.raises(ArtifactError, match=r"'dt' is not finite at \(2,\): inf"):
        write_npz(tmp_path / "inf.npz", TRAJ, arrays)
    optional = ArtifactSchema(
        "test.goals", 1, "solve", (Field("goal", "float64", (2,), "m", nan_allowed=True),)
    )
    write_npz(tmp_path / "goal.npz", optional, {"goal": np.array([np.nan, 1.0])})
    assert np.isnan(read_npz(tmp_path / "goal.npz", optional)["goal"][0])


VALUES = ArtifactSchema(
    "test.values",
    1,
    "demos",
    (
        Field("time_s", "float64", ("N",), "s", "sample times", values="increasing"),
        Field("quat", "float64", ("N", 4), "-", "orientations", values="unit_quaternion"),
        Field("pick", "int64", ("S",), "-", "picked samples", values="index:N"),
        Field("goal", "int64", ("S",), "-", "sample or -1", values="index:N|-1"),
    ),
)


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("time_s", [0.0, 1.0, 1.0], r"'time_s' is not increasing at \(2,\): 1.0"),
        (
            "quat",
            [[1, 0, 0, 0], [0.9, 0, 0, 0], [0, 1, 0, 0]],
            r"'quat' is not of unit norm at \(1, 0\)",
        ),
        ("pick", [0, 3], r"'pick' is outside \[0, N = 3\) at \(1,\): 3"),
        ("goal", [-2, 0], r"'goal' is outside \[-1, N = 3\) at \(0,\): -2"),
    ],
)
def test_times_quaternions_and_indices_are_checked_where_they_are_read(
    tmp_path, field, value, message
):
    """Issue 53: an artifact's content beyond finiteness: times increase, quaternions have
    unit norm, indices point inside the arrays they index."""
    good = {
        "time_s": np.array([0.0, 0.5, 1.0]),
        "quat": np.array([[1.0, 0, 0, 0], [0, 0, 0, 1.0], [0, 1.0, 0, 0]]),
        "pick": np.array([0, 2]),
        "goal": np.array([-1, 2]),
    }
    write_npz(tmp_path / "good.npz", VALUES, good)
    bad = good | {field: np.array(value, dtype=good[field].dtype)}
    with pytest.raises(ArtifactError, match=message + r".*stage 'demos'"):
        write_npz(tmp_path / "bad.npz", VALUES, bad)


def test_bytes_flipped_inside_an_npz_are_a_corrupt_artifact(tmp_path):
    path = tmp_path / "flipped.npz"
    write_npz(path, TRAJ, _arrays(200))
    data = bytearray(path.read_bytes())
    start = data.index(b"q.npy") + 80
    data[start : start + 40] = bytes(40)
    path.write_bytes(bytes(data))
    with pytest.raises(ArtifactError, match="corrupt"):
        read_npz(path, TRAJ)


def test_wrong_schema_version_is_reported(tmp_path):
    path = tmp_path / "t.npz"
    old = ArtifactSchema("test.trajectory", 1, "solve", TRAJ.fields)
    write_npz(path, old, _arrays())
    with pytest.raises(ArtifactError, match="version 1, this code reads 2"):
        read_npz(path, TRAJ)


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"q": np.zeros((4, 2))}, "field 'q' has shape"),
        ({"dt": np.zeros(5)}, "field 'dt' has N = 5"),
        ({"q": np.zeros((4, 3), dtype=np.int64)}, "field 'q' has dtype"),
        ({"extra": np.zeros(1)}, "unexpected fields"),
    ],
)
def test_wrong_fields_are_named(tmp_path, change, message):
    with pytest.raises(ArtifactError, match=message):
        write_npz(tmp_path / "t.npz", TRAJ, {**_arrays(), **change})


def test_missing_field_on_read_is_named(tmp_path):
    path = tmp_path / "t.npz"
    fewer = ArtifactSchema("test.trajectory", 2, "solve", TRAJ.fields[:2])
    write_npz(path, fewer, {k: v for k, v in _arrays().items() if k != "names"})
    with pytest.raises(ArtifactError, match="field 'names' is missing"):
        read_npz(path, TRAJ)


def test_npz_never_unpickles(tmp_path):
    path = tmp_path / "obj.npz"
    np.savez(path, q=np.array([object()], dtype=object))
    with pytest.raises(ArtifactError, match="corrupt"):
        read_npz(path, TRAJ)


def test_json_round_trip_and_type_check(tmp_path):
    path = tmp_path / "plan.json"
    write_json(path, PLAN, {"steps": [1, 2], "robot": "g1"})
    assert read_json(path, PLAN) == {"steps": [1, 2], "robot": "g1"}
    with pytest.raises(ArtifactError, match="field 'robot' is a int, expected str"):
        write_json(path, PLAN, {"steps": [], "robot": 3})


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda d: d["objects"]["box"].pop("size_m"), r"entry 'box': key 'size_m' is missing"),
        (
            lambda d: d["objects"]["box"].update(mass_kg="heavy"),
            r"entry 'box': 'mass_kg' is a str, expected number\?",
        ),
        (lambda d: d["objects"].update(box=[1, 2]), r"entry 'box' is a list, expected object"),
        (lambda d: d["objects"]["box"].update(movable=1), r"'movable' is a int, expected bool"),
    ],
)
def test_a_nested_json_field_missing_or_mistyped_is_named(tiny_scene, tmp_path, edit, message):
    """A hand-edited objects.json fails on read with the entry and key, not a KeyError
    deep in a stage."""
    data = json.loads((tiny_scene / OBJECTS_FILE).read_text())
    edit(data)
    (tmp_path / OBJECTS_FILE).write_text(json.dumps(data))
    with pytest.raises(ArtifactError, match=message):
        load_objects(tmp_path)


def test_a_plan_subtask_without_a_predicate_is_named(tiny_scene, tmp_path):
    data = json.loads((tiny_scene / PLAN_FILE).read_text())
    del data["subtasks"][1]["predicate"]
    (tmp_path / PLAN_FILE).write_text(json.dumps(data))
    with pytest.raises(ArtifactError, match=r"entry 1: key 'predicate' is missing"):
        load_plan(tmp_path)


def test_frame_transforms_mcap_round_trip(tmp_path):
    path = tmp_path / "traj.mcap"
    t = np.array([0.0, 0.02, 0.04])
    pos = np.c_[t, 2 * t, 3 * t]
    quat = np.tile([1.0, 0.0, 0.0, 0.0], (3, 1))
    write_frame_transforms(path, t, {"pelvis": (pos, quat), "box": (pos + 1, quat)})
    messages = read_json_messages(path, "/tf")
    assert [m[0] for m in messages] == ["foxglove.FrameTransforms"] * 3
    assert messages[1][1] == 20_000_000
    second = messages[2][2]["transforms"]
    assert [tr["child_frame_id"] for tr in second] == ["pelvis", "box"]
    assert second[1]["translation"] == pytest.approx({"x": 1.04, "y": 1.08, "z": 1.12})
    assert second[0]["rotation"] == {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}
    copy = tmp_path / "again.mcap"
    write_frame_transforms(copy, t, {"pelvis": (pos, quat), "box": (pos + 1, quat)})
    assert copy.read_bytes() == path.read_bytes()


def test_robot_trajectory_mcap_holds_every_link_pose(tmp_path):
    import mujoco

    from locoman.scene import g1
    from locoman.scene.frames import write_trajectory_mcap

    model = g1.g1_mjmodel()
    q0 = g1.pin_to_mujoco_qpos(g1.q35_to_pin(g1.standing_q35()), model, np.zeros(model.nq))
    q1 = q0.copy()
    q1[0] += 0.1
    path = tmp_path / "traj.mcap"
    write_trajectory_mcap(path, model, np.array([0.0, 0.5]), np.stack([q0, q1]))
    messages = read_json_messages(path, "/tf")
    assert len(messages) == 2
    frames = {t["child_frame_id"]: t for t in messages[1][2]["transforms"]}
    assert len(frames) == model.nbody - 1
    data = mujoco.MjData(model)
    data.qpos[:] = q1
    mujoco.mj_kinematics(model, data)
    hand = frames["left_rubber_hand"]["translation"]
    np.testing.assert_allclose(
        [hand["x"], hand["y"], hand["z"]], data.body("left_rubber_hand").xpos, atol=1e-12
    )


def test_the_mcap_draws_every_body_of_the_scene(tiny_scene, tmp_path):
    """An MCAP with the scene's geometry carries one foxglove.SceneUpdate on /scene: an
    entity per body with visible geometry, frame-locked to its /tf frame when it moves, in
    world otherwise (the solve stage's trajectory.mcap: tests/test_pipeline_e2e.py)."""
    model = load_scene_model(tiny_scene)
    qpos = model.key("home").qpos
    moving = {"pelvis", "left_knee_link", "torso_link", "box"}
    frames = {k: v for k, v in body_frames(model, np.stack([qpos, qpos])).items() if k in moving}
    path = tmp_path / "t.mcap"
    entities = scene_entities(model, qpos, moving=set(frames))
    write_frame_transforms(path, np.array([0.0, 0.1]), frames, entities=entities)
    (schema, _, update), *rest = read_json_messages(path, "/scene")
    assert schema == "foxglove.SceneUpdate" and not rest
    visible = {
        model.body(model.geom_bodyid[g]).name
        for g in range(model.ngeom)
        if model.geom_group[g] <= 2 and model.geom_type[g] != mujoco.mjtGeom.mjGEOM_PLANE
    }
    by_id = {e["id"]: e for e in update["entities"]}
    assert set(by_id) == visible and moving <= visible and "table" in visible
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_kinematics(model, data)
    for name, entity in by_id.items():
        assert entity["frame_locked"] == (name in moving)
        assert entity["frame_id"] == (name if name in moving else "world")
        shapes = entity.get("cubes", []) + entity.get("spheres", []) + entity.get("cylinders", [])
        assert shapes and all(min(s["size"].values()) > 0.0 for s in shapes)
    # A fixed body's box sits where MuJoCo puts the geom; a moving one in its frame.
    for name in ("table", "box"):
        b = model.body(name).id
        g = next(i for i in range(model.ngeom) if model.geom_bodyid[i] == b)
        p = by_id[name]["cubes"][0]["pose"]["position"]
        expected = data.geom_xpos[g] if name == "table" else model.geom_pos[g]
        np.testing.assert_allclose([p["x"], p["y"], p["z"]], expected, atol=1e-9)


def test_an_mp4_holds_every_frame_and_the_same_frames_give_the_same_bytes(tmp_path):
    frames = [np.full((48, 64, 3), 5 * i, np.uint8) for i in range(20)]
    assert write_mp4(tmp_path / "a.mp4", frames, 30.0) == 20
    write_mp4(tmp_path / "b.mp4", frames, 30.0)
    assert (tmp_path / "a.mp4").read_bytes() == (tmp_path / "b.mp4").read_bytes()
    video = cv2.VideoCapture(str(tmp_path / "a.mp4"))
    assert video.get(cv2.CAP_PROP_FRAME_COUNT) == 20 and video.get(cv2.CAP_PROP_FPS) == 30.0
    with pytest.raises(ArtifactError, match="no frame"):
        write_mp4(tmp_path / "c.mp4", [], 30.0)
    with pytest.raises(ArtifactError, match="frame 1"):
        write_mp4(tmp_path / "c.mp4", [frames[0], frames[0][:, :32]], 30.0)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.mp4", "b.mp4"]


@pytest.mark.parametrize("keep", [0.0, 0.001, 0.1, 0.7])
def test_a_truncated_mcap_is_a_message(tmp_path, keep):
    frames = {"box": (np.zeros((500, 3)), np.tile([1.0, 0.0, 0.0, 0.0], (500, 1)))}
    write_frame_transforms(tmp_path / "whole.mcap", np.arange(500) * 0.01, frames)
    data = (tmp_path / "whole.mcap").read_bytes()
    (tmp_path / "t.mcap").write_bytes(data[: int(keep * len(data))])
    with pytest.raises(ArtifactError, match="truncated or corrupt"):
        read_json_messages(tmp_path / "t.mcap", "/tf")
    with pytest.raises(ArtifactError, match="missing"):
        read_json_messages(tmp_path / "none.mcap", "/tf")


def test_every_field_whose_doc_gives_nan_a_meaning_allows_it():
    """A KMP reference's via points hold NaN for a free output: with the finiteness check
    the kmp_fit stage refused its own output. A field's doc saying what NaN means is the
    field allowing it."""
    import importlib

    schemas = []
    for module in ("contact.io", "kmp.io", "perception.io", "retarget.io", "scene.io", "to.io"):
        mod = importlib.import_module(f"locoman.{module}")
        schemas += [v for v in vars(mod).values() if isinstance(v, ArtifactSchema)]
    assert len(schemas) >= 10
    for schema in schemas:
        for f in schema.fields:
            if "NaN" in f.doc:
                assert f.nan_allowed, f"{schema.name}.{f.name}: {f.doc}"
