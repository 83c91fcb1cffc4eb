"""Where an object rests on a fixed surface above the floor, the TO counts the surface as
part of the object: its bottom boxes reach down through the support.

Why: an object's collision box keeps a sphere out through its nearest face (the smooth
clearance of :func:`locoman.to.collision.box_clearance`). A basket's floor is 2 cm thick
and sits on a shelf's top, so a wrist that sinks into the floor's lower half is pushed
down, into the shelf, whose own pair pushes it back up: the penalties (12) hold it in the
wedge between the two. S1's Fig. 6 had three cells end ``Collision_Pairs_Unfreed`` that
way, a hand, wrist or elbow 43-85 mm in the basket's floor over the shelf
(``docs/trajectory-optimisation.md``). The TO already takes every fixed object as solid
down to the floor (the bounding box of its primitives, :func:`obstacles_from_objects`),
so the part of a bottom box over the support may as well reach down through it: then the
way out of it is up or sideways, never into the support. Where the object overhangs the
support, its bottom stays as thick as it is (a hand may pass under the overhang).

The seat is data (numbers of the pairs): it compiles nothing.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from locoman.to.collision import Obstacle

# A box whose bottom lies this close to the object's frame (its bottom face) is a bottom
# box [m]; the relative yaw within which a support's top counts as aligned with the
# object's axes [rad].
_BOTTOM_TOL_M = 1e-3
_ALIGNED_TOL_RAD = 1e-3
# The top of a fixed support lies this close to the object's support height [m].
_HEIGHT_TOL_M = 5e-3

Box = tuple[np.ndarray, np.ndarray]


@dataclasses.dataclass(frozen=True)
class Seat:
    """The part of the floor under an object that a fixed support holds, in the object's
    frame (its bottom face's centre).

    Attributes:
        centre: (2,) x, y of the support's top rectangle [m].
        half: (2,) its half sizes along the object's x and y [m].
        depth: How far below the object's bottom the support is solid [m] (its height).
    """

    centre: tuple[float, float]
    half: tuple[float, float]
    depth: float


def seat_on(pose: np.ndarray, obstacles: tuple[Obstacle, ...], height: float) -> Seat | None:
    """The seat of an object at ``pose`` ((6,) p [m], rpy [rad]) resting on a fixed surface
    at world ``height`` [m]: the obstacle whose top is there and holds the object's bottom
    centre. None where no obstacle does (the floor), or where the support's axes are not
    the object's (a turned rectangle is not a box in the object's frame)."""
    bottom = np.asarray(pose[:3], dtype=float)
    yaw = float(pose[5])
    for obstacle in obstacles:
        top = obstacle.centre[2] + obstacle.half_extents[2]
        if abs(top - height) > _HEIGHT_TOL_M:
            continue
        local = _in_frame(bottom[:2] - obstacle.centre[:2], obstacle.yaw)
        if np.any(np.abs(local) > obstacle.half_extents[:2]):
            continue
        turn = obstacle.yaw - yaw
        quarter = round(turn / (math.pi / 2))
        if abs(turn - quarter * math.pi / 2) > _ALIGNED_TOL_RAD:
            return None
        centre = _in_frame(obstacle.centre[:2] - bottom[:2], yaw)
        half = obstacle.half_extents[:2] if quarter % 2 == 0 else obstacle.half_extents[1::-1]
        return Seat(
            (float(centre[0]), float(centre[1])),
            (float(half[0]), float(half[1])),
            float(2.0 * obstacle.half_extents[2]),
        )
    return None


def _in_frame(offset: np.ndarray, yaw: float) -> np.ndarray:
    """A world xy ``offset`` [m] in a frame turned by ``yaw`` [rad] about z."""
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([c * offset[0] + s * offset[1], -s * offset[0] + c * offset[1]])


def _pieces(low: float, high: float, seat_low: float, seat_high: float) -> list:
    """The intervals of [low, high] below, inside and above [seat_low, seat_high], each
    with whether it is the inside one; empty ones left out."""
    cut_low, cut_high = max(low, seat_low), min(high, seat_high)
    if cut_high - cut_low <= 1e-9:
        return [((low, high), False)]
    out = [((low, cut_low), False), ((cut_low, cut_high), True), ((cut_high, high), False)]
    return [(span, inside) for span, inside in out if span[1] - span[0] > 1e-9]


def _box(x: tuple, y: tuple, z: tuple) -> Box:
    low, high = np.array([x[0], y[0], z[0]]), np.array([x[1], y[1], z[1]])
    return 0.5 * (low + high), 0.5 * (high - low)


def seated_boxes(boxes: list[Box], seat: Seat | None) -> list[Box]:
    """An object's collision boxes (centre (3,), half sizes (3,) in its frame [m]) with
    each bottom box split over ``seat``: its part over the support reaches ``seat.depth``
    down, the parts that overhang stay as they are. The other boxes are unchanged."""
    if seat is None:
        return list(boxes)
    out = []
    sc, sh = np.asarray(seat.centre), np.asarray(seat.half)
    for centre, half in boxes:
        low, high = centre - half, centre + half
        if low[2] > _BOTTOM_TOL_M:
            out.append((centre, half))
            continue
        z = (low[2], high[2])
        for x, x_in in _pieces(low[0], high[0], sc[0] - sh[0], sc[0] + sh[0]):
            if not x_in:
                out.append(_box(x, (low[1], high[1]), z))
                continue
            for y, y_in in _pieces(low[1], high[1], sc[1] - sh[1], sc[1] + sh[1]):
                out.append(_box(x, y, (-seat.depth, high[2]) if y_in else z))
    return out
