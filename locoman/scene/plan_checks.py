"""What a scenario's geometry alone refutes, checked before any stage runs.

The ``validate`` stage runs these on every scenario of ``params.yaml`` (through
:meth:`locoman.config.schema.RootCfg.check`), so a mistake in a scenario file stops the
pipeline before perception makes an image, naming the object or the subtask and the number
that is wrong:

- every object rests: on the floor or on the top of another object, within
  ``scene.rest_tol_m`` (an object that floats or sinks);
- no two objects overlap, at the start and wherever the plan moves one (an object inside
  furniture), beyond ``scene.penetration_tol``;
- a subtask's target rests on a support, carrying along what rests on the moved object;
- the hands can reach what a humanoid subtask takes or sets down: the height of the object's
  hand faces above the surface the robot stands on within ``scene.hand_height_m``. That one
  is a heuristic (the G1's reach, bending as a person does); its message says so, and
  ``scenarios.<name>.check_reach: false`` turns it off for a scenario.

Objects are the primitives of their registered kind (:mod:`locoman.scene.objects`), each a
box turned about z (a sphere or cylinder by its bounding box).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping, Sequence

import numpy as np

from locoman.errors import ConfigError
from locoman.scene.actions import ACTIONS, resolve_action
from locoman.scene.objects import BOX, ObjectGeometry, object_geometry

FLOOR = "floor"
# Patches an object can carry another object on.
CARRYING = ("top", "platform")


@dataclasses.dataclass(frozen=True)
class Pose:
    """An object's origin (the centre of its bottom face) [m] and yaw [rad]."""

    pos: tuple[float, float, float]
    yaw: float


@dataclasses.dataclass(frozen=True)
class Solid:
    """A box turned about z: centre [m], half extents [m], yaw [rad], the part's name."""

    centre: np.ndarray
    half: np.ndarray
    yaw: float
    part: str


def _rotation(yaw: float) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s], [s, c]])


def solids(geometry: ObjectGeometry, pose: Pose) -> list[Solid]:
    """The object's primitives in the world at ``pose``."""
    rot = _rotation(pose.yaw)
    out = []
    for p in geometry.primitives:
        if p.shape == BOX:
            half = np.asarray(p.size, float)
        elif len(p.size) == 2:  # a cylinder: radius, half height
            half = np.array([p.size[0], p.size[0], p.size[1]])
        else:  # a sphere
            half = np.full(3, p.size[0])
        xy = rot @ np.asarray(p.pos[:2]) + np.asarray(pose.pos[:2])
        centre = np.array([xy[0], xy[1], p.pos[2] + pose.pos[2]])
        out.append(Solid(centre, half, pose.yaw, p.name))
    return out


def overlap(a: Solid, b: Solid) -> float:
    """How deep two solids interpenetrate [m] (<= 0: apart or touching): the least overlap
    over the separating axes of two boxes turned about z (their four plane axes and z)."""
    dz = a.half[2] + b.half[2] - abs(a.centre[2] - b.centre[2])
    depth = dz
    d = b.centre[:2] - a.centre[:2]
    ra, rb = _rotation(a.yaw), _rotation(b.yaw)
    for axis in (*ra.T, *rb.T):
        pa = abs(a.half[0] * (ra[:, 0] @ axis)) + abs(a.half[1] * (ra[:, 1] @ axis))
        pb = abs(b.half[0] * (rb[:, 0] @ axis)) + abs(b.half[1] * (rb[:, 1] @ axis))
        depth = min(depth, pa + pb - abs(d @ axis))
    return float(depth)


@dataclasses.dataclass(frozen=True)
class Top:
    """A carrying surface in the world: its height [m] and rectangle (centre, half extents,
    yaw)."""

    z: float
    centre: np.ndarray
    half: np.ndarray
    yaw: float

    def holds(self, xy: Sequence[float]) -> bool:
        """Whether the point ``xy`` [m] lies on the surface."""
        local = _rotation(self.yaw).T @ (np.asarray(xy, float) - self.centre)
        return bool(np.all(np.abs(local) <= self.half + 1e-9))


def tops(geometry: ObjectGeometry, pose: Pose) -> list[Top]:
    """The object's carrying surfaces (``top``, ``platform`` patches) at ``pose``."""
    rot = _rotation(pose.yaw)
    return [
        Top(
            p.centre[2] + pose.pos[2],
            rot @ np.asarray(p.centre[:2]) + np.asarray(pose.pos[:2]),
            np.asarray(p.half_extents, float),
            pose.yaw,
        )
        for p in geometry.patches
        if p.name in CARRYING
    ]


def hand_height(geometry: ObjectGeometry) -> float | None:
    """Height of the object's hand faces above its bottom [m]: the mean height of its patches
    with a horizontal normal (a box's sides, a trolley's handle); None where it has none."""
    sides = [p.centre[2] for p in geometry.patches if abs(p.normal[2]) < 0.5]
    return float(np.mean(sides)) if sides else None


@dataclasses.dataclass
class World:
    """The objects' geometry and poses as the plan goes, and what rests on what."""

    geometry: dict[str, ObjectGeometry]
    poses: dict[str, Pose]

    def support(self, name: str, tol: float) -> tuple[str | None, float]:
        """What ``name`` rests on (``floor``, another object, or None) and the height of its
        bottom above the nearest surface under it [m] (negative: below it)."""
        pose = self.poses[name]
        z = pose.pos[2]
        best: tuple[str | None, float] = (FLOOR, z)
        for other, geometry in self.geometry.items():
            if other == name:
                continue
            for top in tops(geometry, self.poses[other]):
                if top.holds(pose.pos[:2]) and abs(z - top.z) < abs(best[1]):
                    best = (other, z - top.z)
        return (best[0] if abs(best[1]) <= tol else None), best[1]

    def riders(self, name: str, tol: float) -> list[str]:
        """The objects resting on ``name``, and on them, in turn."""
        out = [o for o in self.poses if o != name and self.support(o, tol)[0] == name]
        for rider in list(out):
            out += [r for r in self.riders(rider, tol) if r not in out]
        return out

    def move(self, name: str, pose: Pose, tol: float) -> None:
        """Put ``name`` at ``pose``, carrying what rests on it."""
        riders = self.riders(name, tol)
        old = self.poses[name]
        turn = pose.yaw - old.yaw
        rot = _rotation(turn)
        for rider in riders:
            p = self.poses[rider]
            xy = rot @ (np.asarray(p.pos[:2]) - old.pos[:2]) + pose.pos[:2]
            z = p.pos[2] - old.pos[2] + pose.pos[2]
            self.poses[rider] = Pose((float(xy[0]), float(xy[1]), float(z)), p.yaw + turn)
        self.poses[name] = pose

    def deepest_overlap(self, name: str, skip: Sequence[str] = ()) -> tuple[str, float]:
        """The object ``name`` goes deepest into (not in ``skip``), and how deep [m]."""
        best = ("", 0.0)
        mine = solids(self.geometry[name], self.poses[name])
        for other, geometry in self.geometry.items():
            if other == name or other in skip:
                continue
            for a in mine:
                for b in solids(geometry, self.poses[other]):
                    depth = overlap(a, b)
                    if depth > best[1]:
                        best = (f"{other} ({b.part})", depth)
        return best


def _pose(pos: Sequence[float], yaw: float) -> Pose:
    return Pose((float(pos[0]), float(pos[1]), float(pos[2])), float(yaw))


def check_layout(
    objects: Mapping[str, object],
    plan: Sequence[object],
    robot: str,
    rest_tol_m: float,
    penetration_tol_m: float,
    hand_height_m: Sequence[float],
    check_reach: bool,
) -> list[tuple[str, str]]:
    """Every refutation of a scenario's layout and plan as (key path, message) pairs.

    ``objects`` are :class:`locoman.config.schema.ObjectCfg` by name and ``plan`` the
    :class:`~locoman.config.schema.SubtaskCfg` in order; a subtask whose action does not
    resolve (reported by the scenario's own check) and an object of an unknown kind
    (reported here once) are left out.
    """
    numbers = [v for o in objects.values() for v in (*o.pos, *o.extents_m, o.yaw)]
    numbers += [v for sub in plan if sub.target for v in (*sub.target.pos, sub.target.yaw)]
    if not np.all(np.isfinite(numbers)):
        return []  # the configuration's own check names the number that is not finite
    errors: list[tuple[str, str]] = []
    geometry: dict[str, ObjectGeometry] = {}
    poses: dict[str, Pose] = {}
    for name, obj in objects.items():
        try:
            geometry[name] = object_geometry(obj.kind, obj.extents_m)
        except ConfigError as exc:  # an unknown kind, or extents it cannot take
            errors.append((f"objects.{name}.kind", str(exc)))
            continue
        poses[name] = _pose(obj.pos, obj.yaw)
    world = World(geometry, poses)
    for name in geometry:
        errors += _resting(world, name, f"objects.{name}.pos", rest_tol_m)
    errors += _overlaps(world, list(geometry), lambda n: f"objects.{n}.pos", penetration_tol_m)
    if robot != "g1":
        return errors
    stands_on = FLOOR
    low, high = hand_height_m
    for i, sub in enumerate(plan):
        try:
            action = ACTIONS[resolve_action(sub.prompt, sub.action)]
        except ValueError:
            continue
        if sub.object not in geometry:
            continue
        if action.moves_object and sub.target is not None:
            moving = [sub.object, *world.riders(sub.object, rest_tol_m)]
            world.move(sub.object, _pose(sub.target.pos, sub.target.yaw), rest_tol_m)
            errors += _resting(world, sub.object, f"plan[{i}].target.pos", rest_tol_m, action.name)
            errors += _overlaps(
                world, moving, lambda n, i=i: f"plan[{i}].target", penetration_tol_m
            )
        if action.name == "step":
            stands_on = sub.object
        if check_reach and action.contacts & {"left_hand", "right_hand"}:
            errors += _reach(world, sub.object, stands_on, i, action.name, low, high)
    return errors


def _resting(
    world: World, name: str, path: str, tol: float, action: str | None = None
) -> list[tuple[str, str]]:
    support, gap = world.support(name, tol)
    if support is not None:
        return []
    where = "at the start" if action is None else f"where {action!r} sets it"
    if gap > 0:
        what = f"floats {gap:.3f} m above the nearest surface under it"
    else:
        what = f"sinks {-gap:.3f} m into the surface under it"
    return [
        (
            path,
            f"{name!r} {where} rests on nothing: its bottom (z = "
            f"{world.poses[name].pos[2]:.3f} m) {what}; set z to the floor (0) or to the top "
            f"of what it stands on (within {tol} m, scene.rest_tol_m)",
        )
    ]


def _overlaps(
    world: World, names: Sequence[str], path: Callable[[str], str], tol: float
) -> list[tuple[str, str]]:
    """An error per object of ``names`` deeper than ``tol`` in another, at ``path(name)``."""
    errors = []
    seen: set[frozenset[str]] = set()
    for name in names:
        other, depth = world.deepest_overlap(name)
        key = frozenset((name, other.split(" ")[0]))
        if depth > tol and key not in seen:
            seen.add(key)
            errors.append(
                (
                    path(name),
                    f"{name!r} overlaps {other} by {depth:.3f} m (more than "
                    f"scene.penetration_tol, {tol} m): move one of them",
                )
            )
    return errors


def _reach(
    world: World, name: str, stands_on: str, i: int, action: str, low: float, high: float
) -> list[tuple[str, str]]:
    above = hand_height(world.geometry[name])
    if above is None:
        return []
    floor = 0.0
    if stands_on != FLOOR and stands_on in world.poses:
        surfaces = tops(world.geometry[stands_on], world.poses[stands_on])
        floor = max((t.z for t in surfaces), default=0.0)
    height = world.poses[name].pos[2] + above - floor
    if low <= height <= high:
        return []
    where = "the floor" if stands_on == FLOOR else f"the top of {stands_on!r}"
    why = (
        "too low: below it the G1 bends its pelvis past 90 deg, where the TO's roll-pitch-yaw "
        "base is singular; a taller object, or one raised, is reachable"
        if height < low
        else "too high for the G1's arms; a step onto an object first raises the hands"
    )
    return [
        (
            f"plan[{i}]",
            f"{action!r} {name!r}: its hand faces are {height:.2f} m above {where}, outside "
            f"[{low}, {high}] m (scene.hand_height_m), {why}. A heuristic: "
            "`check_reach: false` in the scenario turns it off",
        )
    ]
