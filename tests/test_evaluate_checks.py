"""The evaluation's success: every check of its own, and a named reason when one fails
(issue 24: a mid-air placement and a NaN trajectory both passed)."""

from __future__ import annotations

import numpy as np
import pytest

from locoman.config.to import EvaluateCfg
from locoman.errors import SceneError
from locoman.sim.evaluate import (
    nonholonomic_tangent,
    nonholonomic_violation,
    object_at_rest,
    support_slip,
    support_under,
)
from locoman.sim.pipeline import all_finite, held_lifts, pose_matrix
from locoman.sim.view import view


def _table(pos, yaw=0.0) -> dict:
    """An ``objects.json`` entry of a fixed 0.6 x 0.8 x 0.72 m table."""
    quat = [np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)]
    return {
        "kind": "table",
        "size_m": [0.6, 0.8, 0.72],
        "pos_m": pos,
        "quat_wxyz": quat,
        "movable": False,
    }


@pytest.fixture
def objects() -> dict:
    return {"table": _table([0.55, 0.0, 0.0], yaw=0.3)}


def _box_at(q) -> dict[str, np.ndarray]:
    return {"box": pose_matrix(np.asarray(q, dtype=float))}


def test_an_object_on_a_table_top_or_the_floor_rests_on_it(objects):
    on_table = np.r_[0.55 + 0.1, 0.05, 0.72, 0.0, 0.0, 0.2]
    assert support_under(objects, "box", _box_at(on_table), 0.01) == "table"
    floor = _box_at(np.r_[2.0, 1.0, 0.004, 0.0, 0.0, 0.0])
    assert support_under(objects, "box", floor, 0.01) == "floor"


def test_an_object_rests_on_a_movable_one_where_that_one_ends():
    """The box on the trolley's platform (0.55 m) after the trolley was pushed 1 m."""
    trolley = {
        "kind": "trolley",
        "size_m": [0.8, 0.5, 0.55],
        "pos_m": [0.2, -1.1, 0.0],
        "quat_wxyz": [1.0, 0.0, 0.0, 0.0],
        "movable": True,
    }
    objects = {"trolley": trolley}
    poses = _box_at([1.3, -1.1, 0.55, 0.0, 0.0, 0.0])
    poses["trolley"] = pose_matrix(np.r_[1.2, -1.1, 0.0, 0.0, 0.0, 0.0])
    assert support_under(objects, "box", poses, 0.01) == "trolley"
    poses["trolley"] = pose_matrix(np.r_[0.2, -1.1, 0.0, 0.0, 0.0, 0.0])  # left behind
    assert support_under(objects, "box", poses, 0.01) is None
    assert support_under(objects, "trolley", poses, 0.01) == "floor"


@pytest.mark.parametrize(
    "where",
    [
        [3.0, 3.0, 0.72],  # the mid-air target: a table's height over bare floor
        [0.55, 0.0, 0.60],  # sunk into the table top
        [0.55 + 0.5, 0.0, 0.72],  # beside the table, at its height
    ],
)
def test_an_object_in_mid_air_or_inside_a_table_rests_on_nothing(objects, where):
    assert support_under(objects, "box", _box_at(np.r_[where, 0.0, 0.0, 0.0]), 0.01) is None


def test_at_rest_needs_a_support_upright_and_still(objects):
    q = np.r_[0.6, 0.0, 0.72, 0.0, 0.0, 0.0]
    still = np.zeros(6)

    def at_rest(q, v):
        return object_at_rest(objects, "box", _box_at(q), q, v, 0.01, 0.01, 0.1)

    assert at_rest(q, still) == (True, "table")
    tipped = q + np.r_[0, 0, 0, 0.3, 0, 0]
    assert not at_rest(tipped, still)[0]
    moving = still + np.r_[0.05, 0, 0, 0, 0, 0]
    assert not at_rest(q, moving)[0]


def test_a_nan_anywhere_in_the_trajectory_is_not_finite():
    traj = {"q": np.zeros((5, 35)), "phase": np.array(["a"] * 5), "success": np.array(True)}
    assert all_finite(traj)
    traj["q"][3, 7] = np.nan
    assert not all_finite(traj)


@pytest.mark.parametrize("value", [np.nan, np.inf, 0.0, -1.0])
def test_evaluate_tolerances_must_be_finite_and_positive(value):
    errors = dict(EvaluateCfg(max_penetration_tol_m=value).check())
    assert "max_penetration_tol_m" in errors
    assert dict(EvaluateCfg().check()) == {}


def test_the_viewer_says_it_needs_a_display(tiny_scene, monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    with pytest.raises(SceneError, match="no display"):
        view(tiny_scene, None)


def test_an_object_held_off_its_support_at_the_end_reports_its_lift():
    """S1 ends with the basket in both hands, lifted off the shelf: its lift is measured
    from where it was last supported. A ``place`` ends with the hands still on an object
    that rests on its target: that one is not held."""
    n = 4
    z = np.array([1.55, 1.55, 1.58, 1.61])
    traj = {
        "hand_object": np.array([[-1, -1], [0, 0], [0, 0], [0, 0]]),
        "support_kind": np.array([["surface"], ["surface"], ["none"], ["none"]]),
        "object_q": np.column_stack([np.zeros((n, 2)), z, np.zeros((n, 3))])[:, None, :],
    }
    assert held_lifts(traj, ["basket"]) == {"basket": pytest.approx(0.06)}
    traj["support_kind"][-1, 0] = "surface"
    assert held_lifts(traj, ["basket"]) == {}


X_REAR, DT, TURN, NODES = -0.3, 0.1, np.pi / 2, 12  # [m], [s], [rad]
STEP = TURN / (NODES - 1)  # the yaw of one step [rad]
# at a node, the rear axle's rate leaves the chord by the step's turn: |x_rear| (s - sin s) / dt
TANGENT_SLIP = abs(X_REAR) * (STEP - np.sin(STEP)) / DT  # [m/s]


def _rolling_chassis(lateral_mps: float = 0.0) -> dict[str, np.ndarray]:
    """A chassis whose rear axle rolls a quarter of a circle of radius 1 m, heading at each
    node along the axle's last step (the chord, as the TO's (7a) holds it), slid sideways at
    ``lateral_mps`` [m/s]; rates by backward Euler, as the TO's (1c). Node 0 is not yet
    moving (inactive), so every rate is a step's."""
    theta = np.linspace(0.0, TURN, NODES)
    yaw = theta - STEP / 2 + np.pi / 2
    heading = np.c_[np.cos(yaw), np.sin(yaw), np.zeros(NODES)]
    side = np.c_[-np.sin(yaw), np.cos(yaw), np.zeros(NODES)]
    rear = np.c_[np.cos(theta), np.sin(theta), np.zeros(NODES)]
    rear = rear + lateral_mps * DT * np.cumsum(side, axis=0)
    q = np.c_[rear - X_REAR * heading, np.zeros((NODES, 2)), yaw]
    active = np.ones((NODES, 1), dtype=bool)
    active[0] = False
    return {
        "q": np.zeros((NODES, 35)),
        "dt": np.full(NODES - 1, DT),
        "object_q": q[:, None, :],
        "object_v": np.diff(q, axis=0, prepend=q[:1])[:, None, :] / DT,
        "rear_axle_x": np.array([X_REAR]),
        "support_kind": np.full((NODES, 1), "chassis"),
        "object_active": active,
    }


def test_a_chassis_rolling_along_its_chords_holds_7a_where_its_tangent_slips():
    traj = _rolling_chassis()
    assert nonholonomic_violation(traj) < 1e-12
    assert nonholonomic_tangent(traj) == pytest.approx(TANGENT_SLIP, rel=1e-9)


def test_a_chassis_slid_sideways_violates_7a_by_its_sliding_speed():
    assert nonholonomic_violation(_rolling_chassis(lateral_mps=0.05)) == pytest.approx(0.05)


def test_7a_is_held_on_the_rate_where_a_chassis_starts_to_roll():
    """Where the chassis was not on the floor at the step's start, the TO holds (7a) on the
    rate at the node, and so does the check; an inactive chassis is free."""
    traj = _rolling_chassis()
    traj["support_kind"][:6] = "none"
    assert nonholonomic_violation(traj) == pytest.approx(TANGENT_SLIP, rel=1e-9)
    traj["object_active"][:] = False
    assert nonholonomic_violation(traj) == 0.0
    assert nonholonomic_tangent(traj) == 0.0


def _resting(yaws: list[float], kind: str = "surface") -> dict[str, np.ndarray]:
    """A box (object 0) resting on a support at every node, its origin still, turning by
    ``yaws`` [rad]; a still carrier (object 1) under it for ``on_object``."""
    n = len(yaws)
    q = np.zeros((n, 2, 6))
    q[:, 0, 2] = 0.55 if kind == "on_object" else 0.0
    q[:, 0, 5] = yaws
    return {
        "object_names": np.array(["box", "trolley"]),
        "object_q": q,
        "support_kind": np.array([[kind, "none"]] * n),
        "support_base": np.array([[1 if kind == "on_object" else -1, -1]] * n),
        "object_active": np.ones((n, 2), bool),
    }


@pytest.mark.parametrize("kind", ["surface", "on_object"])
def test_a_box_turning_on_its_support_slips_at_its_corners(kind):
    """S1's box spun on the floor, its origin still: the origin-based check saw nothing.
    The corners of a 0.4 x 0.4 m bottom turned by 0.1 rad move 2 r sin(0.05) = 28 mm."""
    half = [np.r_[0.2, 0.2], np.r_[0.3, 0.2]]
    key = "box_on_surface" if kind == "surface" else "box_on_trolley"
    still = support_slip(_resting([0.3] * 4, kind), half)
    assert still == {key: pytest.approx(0.0, abs=1e-12)}
    turned = support_slip(_resting([0.3, 0.3, 0.35, 0.4], kind), half)
    assert turned[key] == pytest.approx(2 * np.hypot(0.2, 0.2) * np.sin(0.05), rel=1e-9)
