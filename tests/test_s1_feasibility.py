"""S1 is feasible only the paper's way: the basket is out of the G1's reach from the floor in
front of the shelf, and within reach standing on the box where the plan places it.

Both claims are checked with the keyframe IK (placo, joint limits, self-collisions, CoM over
the feet) on the scene as configured, so retuning the scene cannot silently break the story.
"""

from __future__ import annotations

import numpy as np
import pytest

from locoman.perception.demonstrator import contact_targets
from locoman.retarget.checks import self_collision_pairs
from locoman.retarget.ik import ContactTarget, IKProblem, Retargeter
from locoman.retarget.problem import g1_stance_half_width
from locoman.retarget.robot import contact_frames
from locoman.scene.builder import build_scene
from locoman.scene.g1 import G1_JOINT_NAMES
from locoman.scene.objects import object_geometry
from locoman.scene.plan_state import plan_states
from locoman.to.solve.bounds import BASE_TILT_MAX

UP = np.array([0.0, 0.0, 1.0])
TOE_CLEARANCE_M = 0.01  # [m] between the G1's toes and the shelf's front face
STANCE_BEHIND_M = 0.24  # [m] soles behind the hands on a box on the floor (the S1 keyframes')
# The mapped joint angles [rad] of a person bending to the floor (the S1 pick images'): waist
# pitched to the G1's limit, arms forward.
BENDING_PERSON = {
    "waist_pitch_joint": 0.52,
    "left_shoulder_pitch_joint": -1.4,
    "right_shoulder_pitch_joint": -1.4,
}


@pytest.fixture(scope="module")
def s1(params):
    scene = build_scene("s1_basket", params.scenarios["s1_basket"])
    states = plan_states(scene.objects, scene.plan["subtasks"])
    grab = next(s for s in scene.plan["subtasks"] if s["object"] == "basket")
    return scene, states[grab["index"]], grab


def _basket_grasps(scene, grab) -> tuple[ContactTarget, ...]:
    """The basket's hand contacts where the demonstrator grips it, world frame."""
    basket = scene.objects["basket"]
    geometry = object_geometry(basket["kind"], basket["size_m"])
    out = []
    for t in contact_targets(
        basket["kind"],
        geometry.patches,
        grab["contacts"],
        basket["size_m"],
        0.0,
        basket["pos_m"][2],
    ):
        out.append(ContactTarget(t.effector, t.point + basket["pos_m"], t.normal, True))
    return tuple(out)


def _solve(params, hands, feet_xy: np.ndarray, support_z: float):
    half_width = g1_stance_half_width()
    feet = tuple(
        ContactTarget(
            name, np.array([feet_xy[0], feet_xy[1] + side * half_width, support_z]), UP, True
        )
        for name, side in (("left_foot", 1.0), ("right_foot", -1.0))
    )
    problem = IKProblem(hands, feet, np.eye(3), np.zeros(29), feet_xy)
    return Retargeter(params.retarget).solve(problem)


def test_the_basket_is_out_of_reach_from_the_floor(params, s1):
    scene, _, grab = s1
    shelf = scene.objects["shelf"]
    front = shelf["pos_m"][0] - 0.5 * shelf["size_m"][0]
    sole_half_length = contact_frames().sole_half_extents[0]
    feet_x = front - TOE_CLEARANCE_M - sole_half_length  # toes at the shelf
    result = _solve(params, _basket_grasps(scene, grab), np.array([feet_x, 0.0]), 0.0)
    hands = result.residual_m[:2]
    assert hands.max() > 0.05, f"the G1 reaches the basket from the floor (miss {hands} m)"


def test_the_basket_is_within_reach_standing_on_the_placed_box(params, s1):
    scene, state, grab = s1
    assert state.stands_on == "box"
    box = scene.objects["box"]
    top = state.pose("box") @ np.r_[0.0, 0.0, box["size_m"][2], 1.0]
    result = _solve(params, _basket_grasps(scene, grab), top[:2], float(top[2]))
    assert result.residual_m.max() <= params.retarget.reach_tolerance_m, result.residual_m


@pytest.mark.parametrize("where", ["start", "target"])
def test_the_box_on_the_floor_is_within_reach_in_a_bend_the_to_can_take(params, s1, where):
    """Subtasks 0 and 1: the hands on the box where the demonstrator holds a box on the
    floor, the feet standing behind it as the human's stance puts them, the posture guided
    by a bending person's (waist pitched, arms forward); the keyframe IK meets both hands
    with the base's roll and pitch inside the bound the TO takes."""
    scene, _, _ = s1
    box = scene.objects["box"]
    by_predicate = {s["predicate"]: s for s in scene.plan["subtasks"] if s["object"] == "box"}
    pick, place = by_predicate["pick"], by_predicate["place"]
    pos = np.asarray(box["pos_m"] if where == "start" else place["target"]["pos_m"], float)
    geometry = object_geometry(box["kind"], box["size_m"])
    targets = contact_targets(
        box["kind"], geometry.patches, pick["contacts"], box["size_m"], 0.45, pos[2]
    )
    hands = tuple(ContactTarget(t.effector, t.point + pos, t.normal, True) for t in targets)
    feet_xy = np.mean([h.point[:2] for h in hands], axis=0) - np.array([STANCE_BEHIND_M, 0.0])
    half_width = g1_stance_half_width()
    feet = tuple(
        ContactTarget(name, np.r_[feet_xy + np.array([0.0, side * half_width]), 0.0], UP, False)
        for name, side in (("left_foot", 1.0), ("right_foot", -1.0))
    )
    bend = np.zeros(len(G1_JOINT_NAMES))
    for joint, angle in BENDING_PERSON.items():
        bend[G1_JOINT_NAMES.index(joint)] = angle
    result = Retargeter(params.retarget).solve(IKProblem(hands, feet, np.eye(3), bend, feet_xy))
    assert result.residual_m[:2].max() <= params.retarget.reach_tolerance_m, result.residual_m
    assert np.abs(result.q35[3:5]).max() <= params.retarget.base_tilt_max_rad
    assert params.retarget.base_tilt_max_rad < BASE_TILT_MAX
    assert not self_collision_pairs(result.q)
