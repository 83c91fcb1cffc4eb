"""Issue 52: penetration by class, each geom pair once, on constructed MuJoCo scenes (a
floor, a table, a movable box and a few robot links named as the G1's), and on tiny's."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from locoman.scene import g1
from locoman.scene.io import load_scene_model
from locoman.sim.audit import body_of
from locoman.sim.penetration import (
    CLASSES,
    HEADLINE,
    PairDepth,
    Penetrations,
    pair_depths,
    penetrations,
)

# A solid table (its top 0.7 m up) and a 0.2 m box at x = 1.
TABLE = '<geom name="table/top" type="box" pos="1 0 0.35" size="0.3 0.3 0.35"/>'


def _link(name: str, pos: str, geom: str) -> str:
    """A free body: MuJoCo collides no two bodies welded to the world."""
    return f'<body name="{name}" pos="{pos}"><freejoint/>{geom}</body>'


def _box(z: float) -> str:
    geom = '<geom name="box/body" type="box" size="0.1 0.1 0.1"/>'
    return f'<body name="box" pos="1 0 {z}"><freejoint name="box_free"/>{geom}</body>'


def _pairs(
    bodies: str,
    *,
    standing: bool = False,
    holding: bool = False,
    exclude: str = "",
) -> list[PairDepth]:
    """The classified pairs of a scene of ``bodies`` at node 0: the left foot stands on the
    floor with ``standing``, the left hand holds the box with ``holding``."""
    xml = f"""<mujoco><worldbody>
        <geom name="floor" type="plane" size="5 5 0.1"/>{TABLE}{bodies}
        </worldbody><contact>{exclude}</contact></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    traj = {
        "feet_contact": np.array([[standing, False]]),
        "foot_object": np.full((1, 2), -1),
        "hand_object": np.array([[0 if holding else -1, -1]]),
    }
    return pair_depths(model, data, traj, 0, ["box"])


def test_a_box_100_mm_into_a_table_counts_once_as_object_environment():
    (pair,) = _pairs(_box(0.7))  # its bottom 0.1 m below the top: four MuJoCo contacts
    assert pair.kind == "object_environment" and pair.kind not in HEADLINE
    assert pair.geoms == ("box/body", "table/top")
    assert pair.depth_m == pytest.approx(0.1, abs=1e-6)


def test_a_robot_capsule_30_mm_into_the_object_counts_once_30_mm():
    # A knee capsule along the box's side (x = 0.9), its axis 0.0 m out: 30 mm deep.
    knee = _link(
        "left_knee_link",
        "0.9 0 1.1",
        '<geom type="capsule" size="0.03" fromto="0 -0.05 0 0 0.05 0"/>',
    )
    pairs = _pairs(_box(1.1) + knee)
    (pair,) = pairs
    assert pair.kind == "robot_object"
    assert pair.depth_m == pytest.approx(0.03, abs=1e-6)


@pytest.mark.parametrize(("standing", "kind"), [(True, "scheduled_contact"), (False, None)])
def test_a_sole_1_mm_into_the_floor_is_a_scheduled_contact_while_it_stands(standing, kind):
    foot = _link(
        "left_ankle_roll_link",
        "0 0 0.009",
        '<geom name="left_foot" type="box" size="0.1 0.04 0.01"/>',
    )
    (pair,) = _pairs(foot, standing=standing)
    assert pair.kind == (kind or "robot_environment")
    assert pair.depth_m == pytest.approx(0.001, abs=1e-6)


def test_a_knee_10_mm_into_the_floor_is_robot_environment():
    knee = _link(
        "left_knee_link",
        "0 0 0.02",
        '<geom type="capsule" size="0.03" fromto="0 -0.05 0 0 0.05 0"/>',
    )
    (pair,) = _pairs(knee)
    assert pair.kind == "robot_environment"
    assert pair.depth_m == pytest.approx(0.01, abs=1e-6)


@pytest.mark.parametrize("holding", [True, False])
def test_a_hand_in_the_box_is_a_scheduled_contact_while_it_holds_it(holding):
    hand = _link("left_rubber_hand", "0.88 0 1.1", '<geom type="sphere" size="0.03"/>')
    (pair,) = _pairs(_box(1.1) + hand, holding=holding)
    assert pair.kind == ("scheduled_contact" if holding else "robot_object")


def test_a_pair_that_mujoco_excludes_counts_nowhere_others_count_as_self():
    links = _link("torso_link", "0 0 1", '<geom type="sphere" size="0.1"/>') + _link(
        "left_rubber_hand", "0 0 1.15", '<geom type="sphere" size="0.1"/>'
    )
    (pair,) = _pairs(links)
    assert pair.kind == "self" and pair.depth_m == pytest.approx(0.05, abs=1e-6)
    excluded = '<exclude body1="torso_link" body2="left_rubber_hand"/>'
    assert _pairs(links, exclude=excluded) == []


def test_unnamed_robot_geoms_are_named_by_their_link_and_index():
    model = mujoco.MjModel.from_xml_string(
        """<mujoco><worldbody>
        <geom name="table/top" type="box" size="1 1 0.1"/>
        <body name="left_wrist_yaw_link"><geom type="sphere" size="0.05"/></body>
        </worldbody></mujoco>"""
    )
    assert body_of(model, 0, []).geom == "table/top"
    assert body_of(model, 0, []).kind == "fixed"
    assert body_of(model, 1, []).geom == "left_wrist_yaw_link#1"


def test_the_headline_sums_the_robots_classes_per_node():
    pairs = (
        PairDepth(0, "self", ("a", "b"), 0.01),
        PairDepth(0, "robot_object", ("a", "box/body"), 0.02),
        PairDepth(0, "object_environment", ("box/body", "floor"), 0.5),
        PairDepth(2, "robot_environment", ("a", "floor"), 0.03),
        PairDepth(2, "scheduled_contact", ("left_foot", "floor"), 0.004),
    )
    found = Penetrations(pairs, np.array([2.0, 0.0, 0.1]))
    np.testing.assert_allclose(found.per_node(HEADLINE), [0.03, 0.0, 0.03])
    by_class = found.by_class()
    assert set(by_class) == set(CLASSES)
    assert by_class["object_environment"]["max_m"] == 0.5
    assert by_class["robot_environment"]["deepest_pair"] == {
        "geoms": ["a", "floor"],
        "node": 2,
        "depth_m": 0.03,
    }
    assert by_class["self"]["nodes_penetrating"] == 1
    assert by_class["robot_object"]["avg_m"] == pytest.approx(0.02 / 3)
    assert found.deepest(HEADLINE, node=0).geoms == ("a", "box/body")


def test_a_scheduled_contact_is_bounded_on_its_own_not_summed_over_the_node():
    """Two soles 3 mm into the floor at one node: the node's class sum is 6 mm, the
    deepest contact 3 mm, which is what the scheduled-contact check bounds."""
    pairs = (
        PairDepth(1, "scheduled_contact", ("floor", "left_foot"), 0.003),
        PairDepth(1, "scheduled_contact", ("floor", "right_foot"), 0.003),
        PairDepth(2, "self", ("a", "b"), 0.009),
    )
    found = Penetrations(pairs, np.zeros(3))
    assert found.by_class()["scheduled_contact"]["max_m"] == pytest.approx(0.006)
    assert found.deepest_depth(("scheduled_contact",)) == pytest.approx(0.003)
    assert found.deepest_depth(("robot_object",)) == 0.0


def test_tiny_a_box_sunk_in_the_table_beside_a_standing_g1_is_not_the_headline(tiny_scene):
    """The G1's own scene: the box 100 mm into the table at node 1 is four MuJoCo contacts
    (the per-contact sum 0.4 m) and one pair, of the object's class."""
    model = load_scene_model(tiny_scene)
    box = np.tile([0.4, 0.0, 0.72, 0.0, 0.0, 0.0], (3, 1))
    box[1, 2] -= 0.1
    traj = {
        "q": np.tile(g1.standing_q35(), (3, 1)),
        "object_q": box[:, None, :],
        "object_names": np.array(["box"]),
        "feet_contact": np.ones((3, 2), bool),
        "foot_object": np.full((3, 2), -1),
        "hand_object": np.full((3, 2), -1),
    }
    found = penetrations(model, traj)
    assert found.per_node(HEADLINE).max() < 1e-3
    objects = found.per_node(("object_environment",))
    assert objects[1] == pytest.approx(0.1, abs=0.01) and objects[0] < 1e-3
    assert found.contact_sum[1] > 2 * objects[1]


def test_touching_is_not_penetrating():
    """A sole resting on the floor within MuJoCo's round-off counts nowhere."""
    foot = _link(
        "left_ankle_roll_link",
        "0 0 0.0099999999",
        '<geom name="left_foot" type="box" size="0.1 0.04 0.01"/>',
    )
    assert _pairs(foot) == []
