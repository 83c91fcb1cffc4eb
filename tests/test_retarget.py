"""Retargeting: the joint map against both models, IK on known targets, unreachable contacts,
and the checks that do not trust the IK."""

from __future__ import annotations

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from locoman.config.retarget import RetargetCfg
from locoman.retarget.checks import joint_limit_violation, self_collision_pairs
from locoman.retarget.ik import (
    ContactTarget,
    IKProblem,
    Retargeter,
    convex_hull,
    polygon_margin,
    support_polygon,
)
from locoman.retarget.mapping import JOINT_MAP, map_human_joints
from locoman.retarget.robot import contact_frames
from locoman.scene import g1
from locoman.scene.human import UPRIGHT_QUAT_WXYZ, human_pinocchio_model

UP = np.array([0.0, 0.0, 1.0])


def _world_axes(model: pin.Model, q: np.ndarray) -> dict[str, np.ndarray]:
    """World axis of every revolute joint at configuration q."""
    data = model.createData()
    pin.forwardKinematics(model, data, q)
    axes = {}
    for j in range(2, model.njoints):
        joint = model.joints[j]
        unit = {"JointModelRX": 0, "JointModelRY": 1, "JointModelRZ": 2}.get(joint.shortname())
        local = np.eye(3)[unit] if unit is not None else joint.extract().axis
        axes[model.names[j]] = data.oMi[j].rotation @ local
    return axes


def test_joint_map_rows_match_both_models_axes():
    """With the human in the posture that maps to the G1's zero posture, each G1 joint turns
    about the same world axis as sign times its human joints' axes."""
    human = human_pinocchio_model()
    names = [human.names[j] for j in range(2, human.njoints)]
    q_h = pin.neutral(human)
    w, x, y, z = UPRIGHT_QUAT_WXYZ
    q_h[3:7] = [x, y, z, w]
    # The offset rows (elbows) hold their human joint at -offset / sign: 90 deg of flexion.
    for row in JOINT_MAP:
        if row.offset:
            ((name, sign),) = row.human
            q_h[7 + names.index(name)] = -row.offset / sign
    angles = q_h[7:]
    np.testing.assert_allclose(map_human_joints(names, angles), 0.0, atol=1e-12)
    human_axes = _world_axes(human, q_h)
    robot_axes = _world_axes(g1.g1_pinocchio_model(), pin.neutral(g1.g1_pinocchio_model()))
    assert {row.g1 for row in JOINT_MAP} == set(g1.G1_JOINT_NAMES)
    for row in JOINT_MAP:
        for name, sign in row.human:
            alignment = float(robot_axes[row.g1] @ (sign * human_axes[name]))
            assert alignment > 0.95, (row.g1, name, alignment)


def test_joint_map_adds_and_flips_and_names_a_missing_joint():
    human = human_pinocchio_model()
    names = [human.names[j] for j in range(2, human.njoints)]
    angles = np.zeros(len(names))
    for name, value in (
        ("middle_lumbar_Z", 0.1),
        ("middle_thoracic_Z", 0.2),
        ("left_elbow_Z", 0.5),
    ):
        angles[names.index(name)] = value
    out = map_human_joints(names, angles)
    assert out[g1.G1_JOINT_NAMES.index("waist_pitch_joint")] == pytest.approx(0.3)
    assert out[g1.G1_JOINT_NAMES.index("left_elbow_joint")] == pytest.approx(0.5 * np.pi - 0.5)
    with pytest.raises(KeyError, match="left_hip_Z"):
        map_human_joints(["middle_lumbar_Z"], np.zeros(1))


@pytest.fixture(scope="module")
def retargeter() -> Retargeter:
    return Retargeter(RetargetCfg())


def _known_problem(shift_hands: np.ndarray) -> tuple[IKProblem, np.ndarray]:
    """Targets read off a known G1 configuration (arms forward), started from standing."""
    q35 = g1.standing_q35()
    for side, sign in (("left", 1.0), ("right", -1.0)):
        q35[6 + g1.G1_JOINT_NAMES.index(f"{side}_shoulder_pitch_joint")] = -0.6
        q35[6 + g1.G1_JOINT_NAMES.index(f"{side}_shoulder_roll_joint")] = 0.3 * sign
        q35[6 + g1.G1_JOINT_NAMES.index(f"{side}_elbow_joint")] = 0.5
    model = g1.g1_pinocchio_model()
    data = model.createData()
    q = g1.q35_to_pin(q35)
    pin.framesForwardKinematics(model, data, q)
    frames = contact_frames()

    def point(link: str, offset: np.ndarray) -> np.ndarray:
        pose = data.oMf[model.getFrameId(link)]
        return pose.rotation @ offset + pose.translation

    hands = []
    for effector, link, palm in (
        ("left_hand", "left_rubber_hand", "left_palm"),
        ("right_hand", "right_rubber_hand", "right_palm"),
    ):
        normal = np.array([0.0, 1.0, 0.0]) if effector == "left_hand" else np.array([0, -1.0, 0])
        centre = point(link, frames.palm[palm]) + shift_hands
        hands.append(ContactTarget(effector, centre - frames.palm_radius * normal, normal, True))
    feet = [
        ContactTarget(e, point(link, frames.sole[sole]), UP, True)
        for e, link, sole in (
            ("left_foot", "left_ankle_roll_link", "left_sole"),
            ("right_foot", "right_ankle_roll_link", "right_sole"),
        )
    ]
    posture = g1.standing_q35()[6:]
    return IKProblem(tuple(hands), tuple(feet), np.eye(3), posture, np.array([0.05, -0.03])), q


def test_keyframe_meets_known_reachable_targets(retargeter):
    problem, _ = _known_problem(np.zeros(3))
    result = retargeter.solve(problem)
    assert result.effectors == ["left_hand", "right_hand", "left_foot", "right_foot"]
    assert result.residual_m.max() < 0.005
    assert result.unreachable == {}
    assert joint_limit_violation(result.q) == 0.0
    assert self_collision_pairs(result.q) == []
    assert result.q35.shape == (35,)
    np.testing.assert_allclose(g1.q35_to_pin(result.q35)[:3], result.q[:3])


def test_unreachable_target_is_reported_with_its_distance(retargeter):
    problem, _ = _known_problem(np.array([0.0, 0.0, 1.5]))  # 1.5 m above the arms' reach
    result = retargeter.solve(problem)
    assert set(result.unreachable) == {"left_hand", "right_hand"}
    assert all(gap > 0.5 for gap in result.unreachable.values())
    # The soft version keeps the feet on their contacts and the joints within limits.
    assert result.residual_m[2:].max() < 0.01
    assert joint_limit_violation(result.q) == 0.0


def test_self_collisions_are_counted_by_mujoco():
    standing = g1.q35_to_pin(g1.standing_q35())
    assert self_collision_pairs(standing) == []
    arms_down = g1.q35_to_pin(np.r_[0.0, 0.0, 0.8, np.zeros(32)])  # zero posture: arms in torso
    assert ("left_elbow_link", "torso_link") in self_collision_pairs(arms_down)


def test_joint_limit_violation_measures_the_excursion():
    q = g1.q35_to_pin(g1.standing_q35())
    assert joint_limit_violation(q) == 0.0
    knee = 7 + g1.G1_JOINT_NAMES.index("left_knee_joint")
    q[knee] = g1.g1_pinocchio_model().upperPositionLimit[knee] + 0.1
    assert joint_limit_violation(q) == pytest.approx(0.1)


def test_support_polygon_and_margin():
    square = convex_hull(np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0.5, 0.5]], float))
    assert len(square) == 4
    assert polygon_margin(np.array([0.5, 0.5]), square) == pytest.approx(0.5)
    assert polygon_margin(np.array([1.5, 0.5]), square) == pytest.approx(-0.5)
    half = contact_frames().sole_half_extents
    soles = [np.array([0.0, 0.1, 0.0]), np.array([0.0, -0.1, 0.0])]
    polygon = support_polygon(soles, [0.0, 0.0])
    assert polygon_margin(np.zeros(2), polygon) == pytest.approx(half[0])


def test_palm_spheres_cover_the_hand_capsule_the_evaluation_collides():
    """The TO's palm spheres (centre, and both ends at palm_half_length along the palm
    frame's x) lie on each hand capsule's axis and reach its ends; one length serves both
    hands, the longer one."""
    model = g1.g1_mjmodel()
    data = mujoco.MjData(model)
    rng = np.random.default_rng(3)
    data.qpos[7:] = rng.uniform(model.jnt_range[1:, 0], model.jnt_range[1:, 1])
    mujoco.mj_forward(model, data)
    frames = contact_frames()
    for frame, link in (("left_palm", "left_rubber_hand"), ("right_palm", "right_rubber_hand")):
        body = model.body(link).id
        capsule = next(
            i
            for i in range(model.ngeom)
            if model.geom_bodyid[i] == body and model.geom_type[i] == mujoco.mjtGeom.mjGEOM_CAPSULE
        )
        centre, axis = data.geom_xpos[capsule], data.geom_xmat[capsule].reshape(3, 3)[:, 2]
        radius, half = model.geom_size[capsule][:2]
        R, p = data.xmat[body].reshape(3, 3), data.xpos[body]
        palm, along = frames.palm[frame], frames.palm_axes[frame][:, 0]
        for s in (-1.0, 1.0):
            end = p + R @ (palm + s * frames.palm_half_length * along) - centre
            along_axis = end @ axis
            assert np.linalg.norm(end - along_axis * axis) < 1e-9
            assert half - 1e-12 <= abs(along_axis) <= half + 0.005
        assert radius - 1e-12 <= frames.palm_radius <= radius + 0.005
