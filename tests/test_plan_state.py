"""The plan's state: objects where earlier subtasks left them, feet on what was stepped on,
and the generated image posing the demonstrator accordingly."""

from __future__ import annotations

import numpy as np
import pytest

from locoman.errors import ArtifactError
from locoman.perception import demonstrator
from locoman.perception.render_backend import StandOn, render_subtask
from locoman.scene.builder import build_scene
from locoman.scene.plan_state import plan_states, world_pose


@pytest.fixture(scope="module")
def s1(params):
    scene = build_scene("s1_basket", params.scenarios["s1_basket"])
    return scene, plan_states(scene.objects, scene.plan["subtasks"])


def test_s1_states_follow_the_plan(s1):
    scene, states = s1
    start = np.asarray(scene.objects["box"]["pos_m"])
    target = np.asarray(scene.plan["subtasks"][1]["target"]["pos_m"])
    np.testing.assert_allclose(states[0].pose("box")[:3, 3], start)  # picked where it was
    for i in (1, 2, 3):  # placed in subtask 1: its keyframe and every later one
        np.testing.assert_allclose(states[i].pose("box")[:3, 3], target)
    assert [s.stands_on for s in states] == [None, None, "box", "box"]
    basket = np.asarray(scene.objects["basket"]["pos_m"])
    np.testing.assert_allclose(states[3].pose("basket")[:3, 3], basket)
    shelf = world_pose(scene.objects, states[3], "shelf")  # fixed: where the scene has it
    np.testing.assert_allclose(shelf[:3, 3], scene.objects["shelf"]["pos_m"])


def test_a_plan_cannot_move_a_fixed_object(s1):
    scene, _ = s1
    subtasks = [dict(scene.plan["subtasks"][1], object="shelf")]
    with pytest.raises(ArtifactError, match="fixed"):
        plan_states(scene.objects, subtasks)


def test_the_demonstrator_stands_on_the_box_the_plan_placed(params, s1):
    """Subtask 3 of S1: the person stands on the box (drawn in front of the shelf), not on
    the floor beside it, and still reaches the basket."""
    scene, states = s1
    state, sub = states[3], scene.plan["subtasks"][3]
    basket = scene.objects["basket"]
    T_basket = state.pose("basket")
    T_stand = np.linalg.solve(T_basket, state.pose("box"))
    box_top = scene.objects["box"]["size_m"][2]
    rendered = render_subtask(
        basket,
        sub,
        float(T_basket[2, 3]),
        params.perception.generate,
        np.random.default_rng(0),
        StandOn(scene.objects["box"], T_stand),
    )
    assert rendered.ik_residual_m < 0.02
    names = list(demonstrator.KEYPOINTS)
    soles = rendered.truth["keypoints_world_m"][
        [names.index("left_foot"), names.index("right_foot")]
    ]
    np.testing.assert_allclose(soles[:, 2], box_top, atol=0.02)
    # In the image the soles are over the box, which stands where the plan put it (relative to
    # the approach face of the drawn basket).
    variant_front = -0.5 * rendered.truth["variant_size_m"][0]
    scene_front = -0.5 * basket["size_m"][0]
    box_x = T_stand[0, 3] + variant_front - scene_front
    half = 0.5 * np.asarray(scene.objects["box"]["size_m"][:2])
    assert np.all(np.abs(soles[:, 0] - box_x) < half[0])
    assert np.all(np.abs(soles[:, 1] - T_stand[1, 3]) < half[1])


def test_without_a_stood_on_object_the_feet_are_on_the_floor(params, s1):
    scene, states = s1
    sub = scene.plan["subtasks"][3]
    basket = scene.objects["basket"]
    rendered = render_subtask(
        basket,
        sub,
        float(states[3].pose("basket")[2, 3]),
        params.perception.generate,
        np.random.default_rng(0),
    )
    names = list(demonstrator.KEYPOINTS)
    soles = rendered.truth["keypoints_world_m"][
        [names.index("left_foot"), names.index("right_foot")]
    ]
    np.testing.assert_allclose(soles[:, 2], 0.0, atol=0.02)


def test_s2_push_keyframe_is_its_start_and_the_box_rides_the_trolley(params):
    """The push's keyframe has the hands on the handle before the trolley moves; once it has
    moved, the box placed on its platform has moved with it."""
    scene = build_scene("s2_trolley", params.scenarios["s2_trolley"])
    subtasks = scene.plan["subtasks"]
    after = dict(subtasks[0], index=len(subtasks), predicate="walk", target=None)
    states = plan_states(scene.objects, [*subtasks, after])
    push, later = states[2], states[3]
    trolley_start = np.asarray(scene.objects["trolley"]["pos_m"])
    np.testing.assert_allclose(push.pose("trolley")[:3, 3], trolley_start)
    placed = np.asarray(subtasks[1]["target"]["pos_m"])
    np.testing.assert_allclose(push.pose("box")[:3, 3], placed)
    shift = np.asarray(subtasks[2]["target"]["pos_m"]) - trolley_start
    np.testing.assert_allclose(later.pose("trolley")[:3, 3], trolley_start + shift)
    np.testing.assert_allclose(later.pose("box")[:3, 3], placed + shift, atol=1e-12)
