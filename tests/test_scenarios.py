"""A user's own scenario: actions named by their verbs, and the mistakes the geometry alone
shows refused at ``validate``, before any image is made, each naming what is wrong."""

from __future__ import annotations

import copy
import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml

from locoman.config.compose import compose_text, sync_scenarios
from locoman.config.load import validate
from locoman.errors import ConfigError
from locoman.retarget.pipeline import check_reached
from locoman.scene.actions import ACTIONS, SYNONYMS, resolve_action
from locoman.scene.objects import box_geometry
from locoman.scene.plan_checks import Pose, Solid, hand_height, overlap, solids

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def raw() -> dict:
    return yaml.safe_load((REPO / "params.yaml").read_text())


def _refusal(raw: dict, change) -> str:
    """The message of ``validate`` on params.yaml with ``change`` applied to tiny."""
    params = copy.deepcopy(raw)
    change(params["scenarios"]["tiny"])
    with pytest.raises(ConfigError) as err:
        validate(params)
    return str(err.value)


@pytest.mark.parametrize(
    ("prompt", "action"),
    [
        ("carry the box to the far table", "place"),
        ("put the box on top of the crate", "place"),
        ("drop off the box at the side table", "place"),
        ("bring the box to the shelf", "place"),
        ("take the box off the table", "pick"),
        ("lift the box off the floor", "pick"),
        ("pick up the box", "pick"),
        ("fetch the basket", "pick"),
        ("grasp the basket", "grab"),
        ("roll the trolley forward", "push"),
        ("climb onto the box", "step"),
        ("approach the table", "walk"),
        ("Walk, then look", "walk"),
    ],
)
def test_a_prompts_verb_names_its_action(prompt, action):
    assert resolve_action(prompt, None) == action


def test_a_said_action_wins_over_the_verb_and_every_synonym_names_an_action():
    assert resolve_action("carry the box", "pick") == "pick"
    assert set(SYNONYMS.values()) == set(ACTIONS)
    assert all(SYNONYMS[a] == a for a in ACTIONS)


def test_an_unknown_verb_is_refused_naming_the_subtask_the_word_and_the_actions(raw):
    message = _refusal(raw, lambda s: s["plan"][2].update(prompt="yeet the box on the table"))
    assert "scenarios.tiny.plan[2].prompt" in message and "'yeet'" in message
    assert all(a in message for a in ACTIONS) and "action:" in message


def test_an_unknown_action_is_refused(raw):
    message = _refusal(raw, lambda s: s["plan"][2].update(action="throw"))
    assert "scenarios.tiny.plan[2].action" in message and "'throw'" in message


def test_the_existing_scenarios_pass_every_check(raw):
    validate(raw)


@pytest.mark.parametrize(
    ("change", "where", "words"),
    [
        (
            lambda s: s["objects"]["box"]["pos"].__setitem__(2, 0.80),
            "scenarios.tiny.objects.box.pos",
            ["floats 0.080 m", "scene.rest_tol_m"],
        ),
        (
            lambda s: s["objects"]["box"]["pos"].__setitem__(2, 0.70),
            "scenarios.tiny.objects.box.pos",
            ["sinks 0.020 m"],
        ),
        (
            lambda s: s["objects"]["side_table"].update(pos=[0.55, -0.5, 0.0]),
            "scenarios.tiny.objects.table.pos",
            ["overlaps", "by 0.", "move one of them"],
        ),
        (
            lambda s: s["plan"][2]["target"].update(pos=[0.55, 0.3, 0.5]),
            "scenarios.tiny.plan[2].target.pos",
            ["where 'place' sets it rests on nothing", "sinks 0.220 m"],
        ),
        (
            lambda s: s["plan"][2]["target"].update(pos=[-0.1, -2.5, 0.72]),
            "scenarios.tiny.plan[2].target.pos",
            ["floats 0.720 m"],
        ),
        (
            lambda s: s["plan"].pop(1),
            "scenarios.tiny.plan[1]",
            ["'place' sets down 'box', which the robot does not hold"],
        ),
        (
            lambda s: s["plan"][1].update(contacts=["left_hand", "left_foot"]),
            "scenarios.tiny.plan[1].contacts",
            ["'pick' does not use ['left_foot']"],
        ),
        (
            lambda s: s["plan"][2].pop("target"),
            "scenarios.tiny.plan[2].target",
            ["'place' needs a target for 'box'"],
        ),
        (
            lambda s: s["plan"][1].update(target={"pos": [0.4, 0.0, 0.72]}),
            "scenarios.tiny.plan[1].target",
            ["'pick' moves nothing to a target"],
        ),
    ],
    ids=[
        "floats",
        "sinks",
        "overlap",
        "target in the table",
        "target on nothing",
        "place not held",
        "unused contact",
        "no target",
        "needless target",
    ],
)
def test_a_layout_or_plan_the_geometry_refutes_stops_validate(raw, change, where, words):
    message = _refusal(raw, change)
    assert where in message, message
    assert all(w in message for w in words), message


def _low_box(s):
    s["objects"]["box"].update(pos=[0.4, 0.0, 0.0], extents_m=[0.25, 0.3, 0.2])
    s["plan"][1]["prompt"] = "pick up the box from the floor"


def _high_box(s):
    s["objects"]["table"]["extents_m"][2] = 1.6
    s["objects"]["box"]["pos"][2] = 1.6


@pytest.mark.parametrize(
    ("change", "words"),
    [(_low_box, ["0.10 m above the floor", "too low"]), (_high_box, ["1.70 m", "too high"])],
)
def test_what_the_g1_cannot_reach_is_refused_as_a_heuristic_that_a_key_turns_off(
    raw, change, words
):
    message = _refusal(raw, change)
    assert "scenarios.tiny.plan[1]" in message and "A heuristic" in message
    assert "check_reach: false" in message and all(w in message for w in words)
    params = copy.deepcopy(raw)
    change(params["scenarios"]["tiny"])
    params["scenarios"]["tiny"]["check_reach"] = False
    validate(params)  # the same layout passes with the heuristic off


def test_a_step_raises_the_hands_reach_by_the_height_stood_on(raw):
    """S1's basket is 1.66 m above the floor, 1.36 m above the box the G1 steps on."""
    validate(raw)  # S1 passes with its step
    params = copy.deepcopy(raw)
    params["scenarios"]["s1_basket"]["plan"].pop(2)  # no step onto the box
    with pytest.raises(ConfigError, match=r"plan\[2\]: 'grab' 'basket'.*1\.66 m above the floor"):
        validate(params)


def test_two_solids_overlap_by_their_least_penetration():
    a = Solid(np.zeros(3), np.ones(3), 0.0, "a")
    b = Solid(np.array([1.5, 0.0, 0.0]), a.half, 0.0, "b")
    assert overlap(a, b) == pytest.approx(0.5)
    turned = Solid(np.array([2.5, 0.0, 0.0]), a.half, np.pi / 4, "c")
    assert overlap(a, turned) == pytest.approx(2**0.5 - 1.5)  # apart: its corner short of it
    box = solids(box_geometry([0.4, 0.2, 0.3]), Pose((1.0, 2.0, 0.72), np.pi / 2))
    assert box[0].centre.tolist() == pytest.approx([1.0, 2.0, 0.87])
    assert hand_height(box_geometry([0.4, 0.2, 0.3])) == pytest.approx(0.15)


def test_a_keyframe_that_misses_a_contact_stops_retarget_naming_it():
    rows = [
        {"index": 0, "prompt": "walk to the table", "unreachable": {}},
        {"index": 1, "prompt": "put the box on the shelf", "unreachable": {"left_hand": 0.23}},
    ]
    check_reached(rows[:1], 0.05)
    with pytest.raises(Exception, match=r"subtask 1 \('put the box on the shelf'\): left_hand by"):
        check_reached(rows, 0.05)


def test_a_scenario_file_is_listed_by_make_params(tmp_path):
    """Adding a scenario is adding its file: `make params` lists it and composes it."""
    conf = tmp_path / "conf"
    shutil.copytree(REPO / "conf", conf)
    tiny = yaml.safe_load((conf / "scenario" / "tiny.yaml").read_text())
    (conf / "scenario" / "my_task.yaml").write_text(yaml.safe_dump(tiny))
    assert sync_scenarios(conf)
    text = (conf / "config.yaml").read_text()
    assert "- scenario@scenarios.my_task: my_task" in text
    assert "humanoid_scenarios: [tiny, s1_basket, s2_trolley, my_task]" in text
    assert not sync_scenarios(conf)  # in step: nothing to change
    params = yaml.safe_load(compose_text([], conf))
    assert "my_task" in params["scenarios"]
    assert (
        "my_task" in params["perception"]["scenarios"] and "my_task" in params["solve"]["scenarios"]
    )
    (conf / "scenario" / "my_task.yaml").unlink()
    assert sync_scenarios(conf) and "my_task" not in (conf / "config.yaml").read_text()


def test_a_conf_file_yaml_cannot_read_is_a_message_naming_it(tmp_path):
    conf = tmp_path / "conf"
    shutil.copytree(REPO / "conf", conf)
    with (conf / "solve" / "default.yaml").open("a") as f:
        f.write("  bad: [unclosed\n")
    with pytest.raises(ConfigError, match=r"not valid YAML.*solve/default\.yaml.*line"):
        compose_text([], conf)
    (conf / "scenario" / "broken.yaml").write_text("robot: g1\nplan: [\n")
    with pytest.raises(ConfigError, match=r"broken\.yaml is not valid YAML"):
        sync_scenarios(conf)
