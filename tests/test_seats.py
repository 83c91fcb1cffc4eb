"""An object on a fixed support above the floor: its bottom boxes reach down through the
support where it holds them (:mod:`locoman.to.collisions.boxes`), so that the way out of them is up
or sideways, never into the support; where the object overhangs, its bottom is unchanged."""

from __future__ import annotations

import math

import casadi as ca
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from locoman.config.to import CollisionCfg, ContactCfg
from locoman.retarget.robot import contact_frames
from locoman.to.collisions.boxes import Seat, seat_on, seated_boxes
from locoman.to.collisions.pairs import node_collision_pairs
from locoman.to.problem.modes import NodeMode, ObjectMode
from locoman.to.problem.objects import ObjectModel, Obstacle
from locoman.to.terms.collisions import box_clearance
from locoman.to.terms.supports import Surface

# S1's shelf (the bounding box of its primitives) and its basket's floor and a wall.
SHELF = Obstacle("shelf", np.array([2.0, 0.0, 0.775]), 0.0, np.array([0.2, 0.45, 0.775]))
BASKET_POSE = np.array([1.85, 0.0, 1.55, 0.0, 0.0, 0.0])
FLOOR = (np.array([0.0, 0.0, 0.01]), np.array([0.15, 0.2, 0.01]))
WALL = (np.array([0.14, 0.0, 0.11]), np.array([0.01, 0.2, 0.11]))
BASKET = ObjectModel(
    "basket",
    0.8,
    np.eye(3) * 0.01,
    np.array([0.0, 0.0, 0.05]),
    np.array([0.15, 0.2]),
    0.8,
    solid=False,
    parts=tuple((tuple(c), tuple(h)) for c, h in (FLOOR, WALL)),
)


def _clearance(point: np.ndarray, box) -> float:
    centre, half = box
    return float(box_clearance(ca.DM(point), ca.DM(centre), ca.DM(np.eye(3)), ca.DM(half), 0.004))


def _deepest(point: np.ndarray, boxes) -> float:
    return min(_clearance(point, box) for box in boxes)


def test_the_basket_on_the_shelf_has_the_shelf_under_its_front_two_thirds():
    seat = seat_on(BASKET_POSE, (SHELF,), 1.55)
    assert seat is not None
    np.testing.assert_allclose(seat.centre, [0.15, 0.0], atol=1e-12)
    np.testing.assert_allclose(seat.half, [0.2, 0.45])
    assert seat.depth == 1.55


def test_no_seat_on_the_floor_off_the_support_or_turned_against_it():
    assert seat_on(BASKET_POSE, (SHELF,), 0.0) is None
    assert seat_on(BASKET_POSE + np.array([1.0, 0, 0, 0, 0, 0]), (SHELF,), 1.55) is None
    assert seat_on(BASKET_POSE + np.array([0, 0, 0, 0, 0, 0.3]), (SHELF,), 1.55) is None


def test_a_quarter_turn_swaps_the_supports_half_sizes():
    seat = seat_on(BASKET_POSE + np.array([0, 0, 0, 0, 0, math.pi / 2]), (SHELF,), 1.55)
    np.testing.assert_allclose(seat.half, [0.45, 0.2])
    np.testing.assert_allclose(seat.centre, [0.0, -0.15], atol=1e-12)


def test_the_bottom_boxes_over_the_shelf_reach_down_and_the_overhang_stays():
    seat = seat_on(BASKET_POSE, (SHELF,), 1.55)
    boxes = seated_boxes([FLOOR, WALL], seat)
    assert len(boxes) == 3
    overhang, seated, wall = boxes
    np.testing.assert_allclose(overhang[0] - overhang[1], [-0.15, -0.2, 0.0], atol=1e-12)
    np.testing.assert_allclose(overhang[0] + overhang[1], [-0.05, 0.2, 0.02], atol=1e-12)
    np.testing.assert_allclose(seated[0] - seated[1], [-0.05, -0.2, -1.55], atol=1e-12)
    np.testing.assert_allclose(seated[0] + seated[1], [0.15, 0.2, 0.02], atol=1e-12)
    # The front wall stands on the floor's seated part: it reaches down too.
    np.testing.assert_allclose(wall[0] - wall[1], [0.13, -0.2, -1.55], atol=1e-12)
    np.testing.assert_allclose(wall[0] + wall[1], [0.15, 0.2, 0.22], atol=1e-12)
    lid = (np.array([0.0, 0.0, 0.23]), np.array([0.15, 0.2, 0.01]))
    assert seated_boxes([lid], seat) == [lid]


def test_a_wrist_in_the_floors_lower_half_is_pushed_up_not_into_the_shelf():
    """The wedge of S1's unfreed cells: 5 mm above the shelf, in the floor's lower half,
    the floor alone pushes the point down (into the shelf); seated, up."""
    point = np.array([0.05, 0.0, 0.005])
    step = np.array([0.0, 0.0, 1e-3])
    up, down = point + step, point - step
    assert _clearance(down, FLOOR) > _clearance(up, FLOOR)
    boxes = seated_boxes([FLOOR], seat_on(BASKET_POSE, (SHELF,), 1.55))
    assert _deepest(up, boxes) > _deepest(down, boxes)
    # Under the overhang, 5 mm below the floor, the point is as free as it was (to the
    # log-sum-exp smoothing, which sees the other piece).
    free = np.array([-0.1, 0.0, -0.005])
    assert abs(_deepest(free, boxes) - _clearance(free, FLOOR)) < 1e-6  # the smoothing


@settings(max_examples=60, deadline=None)
@given(
    st.tuples(*[st.floats(-0.3, 0.3)] * 2),
    st.tuples(*[st.floats(0.01, 0.4)] * 2),
)
def test_the_pieces_tile_the_bottom_box(seat_centre, seat_half):
    """The pieces cover the box's footprint once (their areas sum to its area, each
    inside it); only the piece over the seat reaches down."""
    seat = Seat(seat_centre, seat_half, 0.7)
    pieces = seated_boxes([FLOOR], seat)
    area = sum(4 * h[0] * h[1] for _, h in pieces)
    assert math.isclose(area, 4 * FLOOR[1][0] * FLOOR[1][1], rel_tol=1e-9)
    for centre, half in pieces:
        assert np.all(centre[:2] - half[:2] >= FLOOR[0][:2] - FLOOR[1][:2] - 1e-12)
        assert np.all(centre[:2] + half[:2] <= FLOOR[0][:2] + FLOOR[1][:2] + 1e-12)
        inside = np.all(np.abs(centre[:2] - seat_centre) <= np.array(seat_half) + 1e-12)
        assert math.isclose(centre[2] - half[2], -0.7 if inside else 0.0, abs_tol=1e-12)


def test_a_seated_mode_gives_the_hands_the_seated_floor():
    seat = seat_on(BASKET_POSE, (SHELF,), 1.55)
    mode = NodeMode((True, True), (None, None), (ObjectMode(False, Surface(), seat),))
    cfg = CollisionCfg(self_pairs=[])
    pairs = node_collision_pairs(1, mode, (BASKET,), (SHELF,), cfg, ContactCfg(), contact_frames())
    bottoms = {
        round(float(p.numbers["centre"][2] - p.numbers["half"][2]), 6)
        for p in pairs
        if p.kind == "hands_object"
    }
    assert bottoms == {0.0, -1.55}
