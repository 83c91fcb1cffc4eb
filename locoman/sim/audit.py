"""Which bodies come closer than a margin along a trajectory, at its nodes and between them,
where the contact schedule does not let them touch.

The trajectory is replayed kinematically in the MuJoCo scene, at every node and at
``substeps`` poses between two nodes (q and the objects' (p, rpy) linear along the step), with
every geom's margin raised so that MuJoCo reports pairs up to ``margin`` apart, not only
those in contact. A pair the schedule allows is left out:

- a foot on its support (the floor or the object it stands on) while it stands: a swing
  foot in the floor is the robot in its environment, as the evaluation counts it
  (:func:`scheduled`);
- a hand on the object it holds;
- an object on what supports it (the floor or a fixed object, or the object it rests on),
  and one not yet simulated where the scene put it;

at a node or next to it (a pose between two nodes is allowed what either node allows). Every
other pair, the robot's own links, the robot against any object or the floor, a carried
object against anything, is reported with its distance and where it lies.
"""

from __future__ import annotations

import copy
import dataclasses

import mujoco
import numpy as np

from locoman.scene import g1
from locoman.scene.builder import FLOOR
from locoman.sim.evaluate import ROBOT, poses, scene_qpos


@dataclasses.dataclass(frozen=True)
class Body:
    """One side of a close pair.

    Attributes:
        kind: ``robot`` (a G1 link), ``object`` (movable), ``fixed`` (a fixed object) or
            ``floor``.
        name: The link's or the object's name (``floor`` for the floor).
        geom: The geom's name (a robot geom: its link's name and index).
    """

    kind: str
    name: str
    geom: str


@dataclasses.dataclass(frozen=True)
class ClosePair:
    """Two bodies closer than the margin at one pose of the trajectory.

    Attributes:
        node: The step k -> k + 1 the pose lies on (its first node).
        fraction: Where along the step [-]: 0 at node k.
        a, b: The bodies.
        distance: Their signed distance [m]; negative inside each other.
        point: The contact point in the world [m].
    """

    node: int
    fraction: float
    a: Body
    b: Body
    distance: float
    point: np.ndarray

    @property
    def label(self) -> str:
        return f"{self.a.geom} | {self.b.geom}"


def body_of(model: mujoco.MjModel, geom: int, movable: list[str]) -> Body:
    """What ``geom`` belongs to: the floor, an object (named ``<object>/<part>``; movable if
    in ``movable``, else fixed) or a link of the robot."""
    name = model.geom(geom).name
    if name == FLOOR:
        return Body("floor", FLOOR, FLOOR)
    if "/" in name:
        owner = name.split("/", 1)[0]
        return Body("object" if owner in movable else "fixed", owner, name)
    link = model.body(model.geom_bodyid[geom]).name
    return Body(ROBOT, link, name or f"{link}#{geom}")


def scheduled(
    traj: dict[str, np.ndarray], k: int, robot: Body, other: Body, names: list[str]
) -> bool:
    """The schedule makes ``robot`` touch ``other`` at node k: a foot on its support while
    it stands, a hand on the object it holds."""
    if robot.name in g1.FOOT_LINKS:
        i = g1.FOOT_LINKS.index(robot.name)
        on = int(traj["foot_object"][k, i])
        support_is_other = (
            other.kind == "floor" if on < 0 else other.kind == "object" and other.name == names[on]
        )
        return bool(traj["feet_contact"][k, i]) and support_is_other
    if robot.name in g1.HAND_LINKS and other.kind == "object":
        i = g1.HAND_LINKS.index(robot.name)
        return int(traj["hand_object"][k, i]) == names.index(other.name)
    return False


def allowed_at(traj: dict[str, np.ndarray], k: int, a: Body, b: Body, names: list[str]) -> bool:
    """The schedule lets ``a`` and ``b`` touch at node k."""
    for first, second in ((a, b), (b, a)):
        if first.kind == ROBOT and scheduled(traj, k, first, second, names):
            return True
        if first.kind == "object":
            j = names.index(first.name)
            resting = str(traj["support_kind"][k, j]) != "none" or not traj["object_active"][k, j]
            base = int(traj["support_base"][k, j])
            if resting and base < 0 and second.kind in ("floor", "fixed"):
                return True
            if resting and base >= 0 and second.kind == "object" and second.name == names[base]:
                return True
    return False


def allowed(traj: dict[str, np.ndarray], pair: ClosePair, names: list[str]) -> bool:
    """The schedule lets the pair touch at its node, or, between two nodes, at either."""
    k = pair.node
    nodes = [k] if pair.fraction == 0.0 else [k, k + 1]
    return any(allowed_at(traj, node, pair.a, pair.b, names) for node in nodes)


def close_pairs(
    model: mujoco.MjModel,
    traj: dict[str, np.ndarray],
    margin: float,
    substeps: int,
    first: int = 1,
) -> list[ClosePair]:
    """Every pair of geoms closer than ``margin`` [m] at a node from ``first`` on or
    between two, that the schedule does not let touch (:func:`allowed`)."""
    names = [str(n) for n in traj["object_names"]]
    model = copy.copy(model)  # MuJoCo's copy is deep
    model.geom_margin[:] = margin
    data = mujoco.MjData(model)
    out = []
    for k, t, q35, object_q in poses(traj, substeps, first):
        data.qpos[:] = scene_qpos(model, q35, names, object_q)
        mujoco.mj_forward(model, data)
        for c in data.contact[: data.ncon]:
            if c.dist >= margin:
                continue
            pair = ClosePair(
                k,
                t,
                body_of(model, c.geom1, names),
                body_of(model, c.geom2, names),
                float(c.dist),
                np.array(c.pos),
            )
            if not allowed(traj, pair, names):
                out.append(pair)
    return out


@dataclasses.dataclass(frozen=True)
class Penetration:
    """The deepest penetration of one body into another along the trajectory, where the
    schedule does not let them touch.

    Attributes:
        depth_m: [m].
        pair: The two geoms.
        node: The step it lies on (its first node).
        fraction: Where along the step [-]: 0 at the node.
    """

    depth_m: float
    pair: tuple[str, str]
    node: int
    fraction: float


def unscheduled_penetrations(
    model: mujoco.MjModel, traj: dict[str, np.ndarray], substeps: int
) -> tuple[float, dict[str, Penetration]]:
    """Bodies inside each other where the schedule does not let them touch: the deepest
    such penetration [m] at the ``substeps`` poses between two nodes, and per body (the
    robot as ``robot``, each object, fixed or movable, by name) its deepest one anywhere.
    Contacts the schedule makes (a hand on the object it holds, linear in q between two
    nodes while the object moves along its own line) are the contact terms' business."""
    between, deepest = 0.0, {}
    for c in close_pairs(model, traj, 0.0, substeps, first=0):
        depth = -c.distance
        if c.fraction > 0.0:
            between = max(between, depth)
        for body in (c.a, c.b):
            owner = ROBOT if body.kind == ROBOT else body.name
            if owner == FLOOR:
                continue
            if owner not in deepest or depth > deepest[owner].depth_m:
                deepest[owner] = Penetration(depth, (c.a.geom, c.b.geom), c.node, c.fraction)
    return between, deepest
