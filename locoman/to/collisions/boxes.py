"""Where an object rests on a fixed surface above the floor, the TO counts the surface as
part of the object: its bottom boxes reach down through the support.

Why: an object's collision box keeps a sphere out through its nearest face (the smooth
clearance of :func:`locoman.to.terms.collisions.box_clearance`). A basket's floor is 2 cm thick
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

from locoman.to.problem.objects import Obstacle

_CORNER_SIGNS = [(x, y, z) for x in (-1.0, 1.0) for y in (-1.0, 1.0) for z in (-1.0, 1.0)]


def box_corners(half_extents) -> np.ndarray:
    """(8, 3) the corners of a box of ``half_extents`` (3,) [m] in its frame, which sits at
    the bottom face's centre."""
    half = np.asarray(half_extents, dtype=float).ravel()
    return np.array(_CORNER_SIGNS) * half + np.array([0.0, 0.0, half[2]])


def edge_point_counts(half_extents: np.ndarray, spacing: float) -> tuple[int, int, int]:
    """Points per edge of :func:`edge_points` along an obstacle's x, y and z axes, ends
    included, at most ``spacing`` apart [m]; a count is structure, so it comes from the
    numbers."""
    return tuple(int(np.ceil(2.0 * h / spacing)) + 1 for h in np.asarray(half_extents))


def edge_points(obstacle: Obstacle, counts: tuple[int, int, int]) -> np.ndarray:
    """(n, 3) world points along an obstacle's four vertical edges, from the top corners
    down, and along its four top edges between those corners (:func:`edge_point_counts`):
    an edge that enters a carried box between the box's corners is caught by one of them,
    a table's leg and the rim of its top alike (a box lifted off a table and swung over
    the rim, its corners outside the top, was not caught by corners alone). The bottom
    edges lie on the floor, where a carried object does not go."""
    n_x, n_y, n_z = counts
    signs = [(x, y, z) for x in (-1.0, 1.0) for y in (-1.0, 1.0) for z in np.linspace(1, -1, n_z)]
    signs += [(x, y, 1.0) for x in np.linspace(-1, 1, n_x)[1:-1] for y in (-1.0, 1.0)]
    signs += [(x, y, 1.0) for x in (-1.0, 1.0) for y in np.linspace(-1, 1, n_y)[1:-1]]
    local = np.array(signs) * np.asarray(obstacle.half_extents, dtype=float)
    return np.asarray(obstacle.centre, dtype=float) + local @ obstacle.rotation.T


def box_edge_points(centre, half_extents, spacing: float) -> np.ndarray:
    """(n, 3) points along all twelve edges of a box (centre [m], half sizes [m], in its
    frame), corners included, each once, at most ``spacing`` [m] apart. A carried box's
    corners alone miss its edge cutting into a thin post: tilted, it went 30 mm into S2's
    trolley post between them; along an edge, it goes at most about half the spacing in
    before a point is inside."""
    half = np.asarray(half_extents, dtype=float).ravel()
    points = []
    for axis in range(3):
        u, v = (a for a in range(3) if a != axis)
        n = int(np.ceil(2.0 * half[axis] / spacing)) + 1
        for s_u in (-1.0, 1.0):
            for s_v in (-1.0, 1.0):
                along = np.linspace(-1.0, 1.0, n)
                # The ends are corners: the edges along x hold them, the others skip them.
                for t in along if axis == 0 else along[1:-1]:
                    sign = np.zeros(3)
                    sign[[axis, u, v]] = t, s_u, s_v
                    points.append(sign * half)
    return np.asarray(centre, dtype=float).ravel() + np.array(points)


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
