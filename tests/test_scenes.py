"""Every scenario builds a valid scene; the robot models load; invalid scenes fail clearly."""

from __future__ import annotations

import copy
import shutil

import mujoco
import numpy as np
import pytest

from locoman.errors import SceneError
from locoman.scene import human, mobile_manipulator
from locoman.scene.builder import build_scene
from locoman.scene.checks import check_scene
from locoman.scene.io import load_objects, load_plan, load_scene_model, load_state, write_scene

SCENARIOS = ("tiny", "s1_basket", "s2_trolley", "mm_pick_place")


@pytest.mark.parametrize("name", SCENARIOS)
def test_scenario_scene_is_valid_and_round_trips(name, params, tmp_path):
    cfg = params.scenarios[name]
    scene = build_scene(name, cfg, (64, 48))
    model, qpos = write_scene(tmp_path, scene)
    report = check_scene(
        model, qpos, cfg.robot, params.scene.penetration_tol, params.scene.foot_ground_tol
    )
    assert report.max_penetration_m <= params.scene.penetration_tol
    if cfg.robot == "g1":
        assert max(abs(g) for g in report.sole_gaps_m) <= params.scene.foot_ground_tol
    reloaded = load_scene_model(tmp_path)
    assert (reloaded.nq, reloaded.nbody, reloaded.ngeom) == (model.nq, model.nbody, model.ngeom)
    np.testing.assert_array_equal(load_state(tmp_path)["qpos"], qpos)
    objects, plan = load_objects(tmp_path), load_plan(tmp_path)
    assert set(objects) == set(cfg.objects)
    assert [s["prompt"] for s in plan["subtasks"]] == [s.prompt for s in cfg.plan]
    for sub in plan["subtasks"]:
        if sub["target"] is not None:
            assert objects[sub["object"]]["movable"]


def test_box_mass_knob_reaches_the_scene(params):
    scene = build_scene("tiny", params.scenarios["tiny"], (64, 48))
    model = scene.spec.compile()
    assert model.body("box").mass[0] == pytest.approx(params.scenario.box_mass)


@pytest.mark.parametrize(("box_z", "message"), [(0.9, "do not rest"), (0.65, "penetrate")])
def test_floating_or_penetrating_object_is_rejected(params, box_z, message):
    cfg = copy.deepcopy(params.scenarios["tiny"])
    cfg.objects["box"].pos = [0.4, 0.0, box_z]
    scene = build_scene("tiny", cfg, (64, 48))
    model = scene.spec.compile()
    with pytest.raises(SceneError, match=message):
        check_scene(model, model.key("home").qpos, "g1", 1e-3, 2e-3)


def test_human_model_loads_and_stands():
    model = human.human_mjspec().compile()
    data = mujoco.MjData(model)
    data.qpos[2] = human.standing_pelvis_height()
    data.qpos[3:7] = human.UPRIGHT_QUAT_WXYZ
    mujoco.mj_forward(model, data)
    head = data.body("human_middle_head").xpos
    assert 1.5 < head[2] < 1.9, "the demonstrator should be upright, head about 1.7 m high"
    pmodel = human.human_pinocchio_model()
    assert pmodel.nq == model.nq


def test_mobile_manipulator_kinematics_and_gripper():
    model = mobile_manipulator.mobile_manipulator_mjspec().compile()
    data = mujoco.MjData(model)
    assert [model.joint(i).name for i in range(3)] == list(mobile_manipulator.BASE_JOINTS)
    data.qpos[:3] = [1.0, -0.5, 0.7]
    mujoco.mj_kinematics(model, data)
    link0 = data.body("panda_link0").xpos
    expected = [1.0 + 0.3875 * np.cos(0.7), -0.5 + 0.3875 * np.sin(0.7), 0.75]
    np.testing.assert_allclose(link0, expected, atol=1e-12)
    data.ctrl[model.actuator("gripper").id] = 0.0
    data.qpos[model.joint("panda_finger_joint1").qposadr[0]] = 0.04
    data.qpos[model.joint("panda_finger_joint2").qposadr[0]] = 0.04
    hold = [model.joint(f"panda_joint{i}").qposadr[0] for i in range(1, 8)]
    for _ in range(500):
        mujoco.mj_step(model, data)
        data.qpos[hold] = mobile_manipulator.ARM_READY
    f1 = data.qpos[model.joint("panda_finger_joint1").qposadr[0]]
    f2 = data.qpos[model.joint("panda_finger_joint2").qposadr[0]]
    assert f1 < 0.005 and abs(f1 - f2) < 1e-3, "both fingers close together"


def test_unreachable_arm_start_is_reported():
    model = mobile_manipulator.mobile_manipulator_mjspec().compile()
    with pytest.raises(SceneError, match="reach"):
        mobile_manipulator.start_qpos(model, np.zeros(3), np.array([3.0, 0.0, 1.0]))


def test_the_scene_mjcf_holds_no_path_of_this_checkout(repo, tiny_scene, tmp_path):
    """scene.xml names its meshes by package, so it loads from a copy in another folder
    (DVC's experiment copies have no .venv)."""
    scene = tiny_scene
    text = (scene / "scene.xml").read_text()
    assert ".venv" not in text and str(repo) not in text
    assert 'meshdir="package://example-robot-data/robots/"' in text
    copy = tmp_path / "elsewhere" / "scene"
    shutil.copytree(scene, copy)
    assert load_scene_model(copy).nmesh == load_scene_model(scene).nmesh > 0
