"""Where the plan has left things at each subtask: the objects' poses and the feet's support.

A plan is a sequence: after "place the box in front of the shelf" the box is there, and after
"step on the box" the demonstrator (and the robot) stands on it. Every consumer of a subtask
(the generated image, the simulated view R_s, the keyframe and its picture, the TO) reads the
world from here, so they agree.

Rules, in plan order:

- every movable object starts at its pose in ``objects.json``;
- a subtask with a ``target`` moves its object there. A ``place`` keyframe already shows it
  there (the keyframe is where the placing ends: the box set down); any other keyframe is
  where the subtask begins (``push``: the hands on the handle before the trolley moves), so
  the move shows from the next subtask on;
- objects resting on a moved object ride along (the box on the trolley): an object rests on
  another when its bottom lies on the other's top face, within ``REST_TOL_M``;
- a subtask whose predicate is ``step`` puts the feet on its object's top, for its own
  keyframe and every later one (the plan has no "step down").
"""

from __future__ import annotations

import dataclasses
from typing import Any

import mujoco
import numpy as np

from locoman.errors import ArtifactError
from locoman.scene.objects import object_geometry
from locoman.scene.rotations import yaw_quat_wxyz

STEP = "step"  # the predicate that puts the feet on an object
PLACE = "place"  # the predicate whose keyframe shows its object at the target
REST_TOL_M = 0.01  # [m] an object's bottom this close to a top face rests on it


@dataclasses.dataclass(frozen=True)
class PlanState:
    """The world during one subtask's keyframe.

    Attributes:
        index: Subtask index.
        poses: Movable object -> world pose (4, 4) [m].
        stands_on: The object the feet stand on, or None for the floor.
    """

    index: int
    poses: dict[str, np.ndarray]
    stands_on: str | None

    def pose(self, name: str) -> np.ndarray:
        """World pose (4, 4) of a movable object.

        Raises:
            ArtifactError: If ``name`` is not a movable object of the scene.
        """
        if name not in self.poses:
            raise ArtifactError(
                f"object {name!r} is not a movable object of the scene "
                f"(movable: {sorted(self.poses)})"
            )
        return self.poses[name]


def _pose(pos: Any, quat_wxyz: Any) -> np.ndarray:
    pose = np.eye(4)
    mat = np.zeros(9)
    mujoco.mju_quat2Mat(mat, np.asarray(quat_wxyz, dtype=float))
    pose[:3, :3] = mat.reshape(3, 3)
    pose[:3, 3] = pos
    return pose


def top_face(obj: dict[str, Any]) -> tuple[np.ndarray, np.ndarray] | None:
    """Centre (3,) and half extents (2,) of an object's highest upward face (a box's ``top``,
    a trolley's ``platform``) in its frame, if it has one."""
    patches = object_geometry(obj["kind"], obj["size_m"]).patches
    up = [p for p in patches if p.normal[2] > 0.9]
    if not up:
        return None
    top = max(up, key=lambda p: p.centre[2])
    return np.asarray(top.centre), np.asarray(top.half_extents)


def _riders(
    objects: dict[str, dict[str, Any]], poses: dict[str, np.ndarray], carrier: str
) -> list[str]:
    """Movable objects whose bottom (their frame's origin) rests on ``carrier``'s top face."""
    face = top_face(objects[carrier])
    if face is None:
        return []
    centre, half = face
    out = []
    for name, pose in poses.items():
        if name == carrier:
            continue
        local = np.linalg.solve(poses[carrier], np.r_[pose[:3, 3], 1.0])[:3] - centre
        if abs(local[2]) <= REST_TOL_M and np.all(np.abs(local[:2]) <= half):
            out.append(name)
    return out


def _move(
    objects: dict[str, dict[str, Any]],
    poses: dict[str, np.ndarray],
    name: str,
    target: np.ndarray,
) -> None:
    """Move ``name`` to ``target`` (4, 4), and what rests on it by the same motion."""
    motion = target @ np.linalg.inv(poses[name])
    for rider in _riders(objects, poses, name):
        poses[rider] = motion @ poses[rider]
    poses[name] = target


def plan_states(
    objects: dict[str, dict[str, Any]], subtasks: list[dict[str, Any]]
) -> list[PlanState]:
    """The state of the world at every subtask of a plan, in plan order.

    Args:
        objects: ``objects.json``'s object table (name -> entry with ``movable``, ``pos_m``,
            ``quat_wxyz``).
        subtasks: ``plan.json``'s subtasks (``index``, ``predicate``, ``object``, ``target``).

    Raises:
        ArtifactError: If a subtask moves or steps on an object the scene does not have, or
            moves a fixed one.
    """
    poses = {
        name: _pose(obj["pos_m"], obj["quat_wxyz"])
        for name, obj in objects.items()
        if obj["movable"]
    }
    stands_on: str | None = None
    states = []
    for sub in sorted(subtasks, key=lambda s: int(s["index"])):
        name = sub["object"]
        if name not in objects:
            raise ArtifactError(f"subtask {sub['index']} names object {name!r}, not in the scene")
        target = sub.get("target")
        if target and name not in poses:
            raise ArtifactError(
                f"subtask {sub['index']} moves {name!r}, which is fixed in the scene"
            )
        goal = _pose(target["pos_m"], yaw_quat_wxyz(float(target["yaw_rad"]))) if target else None
        if goal is not None and sub["predicate"] == PLACE:
            _move(objects, poses, name, goal)
        if sub["predicate"] == STEP:
            stands_on = name
        states.append(
            PlanState(int(sub["index"]), {k: v.copy() for k, v in poses.items()}, stands_on)
        )
        if goal is not None and sub["predicate"] != PLACE:
            _move(objects, poses, name, goal)
    return states


# The world before any subtask: every object where the scene puts it.
AS_BUILT = PlanState(-1, {}, None)


def world_pose(objects: dict[str, dict[str, Any]], state: PlanState, name: str) -> np.ndarray:
    """World pose (4, 4) of any object during ``state``: a movable one where the plan left
    it, a fixed one where the scene has it."""
    if name in state.poses:
        return state.poses[name]
    if name not in objects:
        raise ArtifactError(f"object {name!r} is not in the scene")
    obj = objects[name]
    return _pose(obj["pos_m"], obj["quat_wxyz"])
