"""The scene's geometry as ``foxglove.SceneUpdate`` entities, so Foxglove draws the robot and
the objects, not only their coordinate frames.

One entity per MuJoCo body with visible geoms (groups 0-2): boxes, spheres and cylinders as
themselves (a capsule as a cylinder and two spheres), a mesh as its bounding box (the G1's
290,000 mesh triangles would make every MCAP tens of megabytes). A body whose frame the MCAP
moves on ``/tf`` is frame-locked to it; every other body is placed once in ``world``.
"""

from __future__ import annotations

from collections.abc import Collection
from typing import Any

import mujoco
import numpy as np

VISIBLE_GROUPS = (0, 1, 2)  # MuJoCo's viewer shows these by default
IDENTITY = np.array([1.0, 0.0, 0.0, 0.0])  # quaternion (w, x, y, z)


def _pose(pos: np.ndarray, quat_wxyz: np.ndarray) -> dict[str, Any]:
    w, x, y, z = (float(v) for v in quat_wxyz)
    return {
        "position": dict(zip("xyz", (float(v) for v in pos), strict=True)),
        "orientation": {"x": x, "y": y, "z": z, "w": w},
    }


def _colour(rgba: np.ndarray) -> dict[str, float]:
    return dict(zip("rgba", (float(v) for v in rgba), strict=True))


def _compose(
    pos: np.ndarray, quat: np.ndarray, local_pos: np.ndarray, local_quat: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """(pos, quat) ∘ (local_pos, local_quat)."""
    out_pos, out_quat = np.zeros(3), np.zeros(4)
    mujoco.mju_rotVecQuat(out_pos, local_pos, quat)
    mujoco.mju_mulQuat(out_quat, quat, local_quat)
    return pos + out_pos, out_quat


def _geom_primitives(model: mujoco.MjModel, g: int, pos, quat) -> dict[str, list]:
    """The primitives of geom ``g`` at (pos, quat) in its entity's frame."""
    kind, size, rgba = model.geom_type[g], model.geom_size[g], model.geom_rgba[g]
    colour = _colour(rgba)
    if kind == mujoco.mjtGeom.mjGEOM_MESH:
        centre, half = model.geom_aabb[g, :3], model.geom_aabb[g, 3:]
        pos, quat = _compose(pos, quat, centre, IDENTITY)
        return {"cubes": [{"pose": _pose(pos, quat), "size": _xyz(2 * half), "color": colour}]}
    if kind == mujoco.mjtGeom.mjGEOM_BOX:
        return {"cubes": [{"pose": _pose(pos, quat), "size": _xyz(2 * size), "color": colour}]}
    if kind == mujoco.mjtGeom.mjGEOM_SPHERE:
        sphere = {"pose": _pose(pos, quat), "size": _xyz(np.full(3, 2 * size[0])), "color": colour}
        return {"spheres": [sphere]}
    if kind in (mujoco.mjtGeom.mjGEOM_CYLINDER, mujoco.mjtGeom.mjGEOM_CAPSULE):
        r, half = size[0], size[1]
        out: dict[str, list] = {
            "cylinders": [
                {
                    "pose": _pose(pos, quat),
                    "size": _xyz(np.array([2 * r, 2 * r, 2 * half])),
                    "bottom_scale": 1.0,
                    "top_scale": 1.0,
                    "color": colour,
                }
            ]
        }
        if kind == mujoco.mjtGeom.mjGEOM_CAPSULE:
            ends = [_compose(pos, quat, np.array([0.0, 0.0, s * half]), IDENTITY) for s in (-1, 1)]
            out["spheres"] = [
                {"pose": _pose(p, q), "size": _xyz(np.full(3, 2 * r)), "color": colour}
                for p, q in ends
            ]
        return out
    return {}  # planes: Foxglove draws its own grid


def _xyz(v: np.ndarray) -> dict[str, float]:
    return dict(zip("xyz", (float(x) for x in v), strict=True))


def scene_entities(
    model: mujoco.MjModel, qpos: np.ndarray, moving: Collection[str]
) -> list[dict[str, Any]]:
    """``foxglove.SceneEntity`` dicts of every body with visible geoms.

    Args:
        model: The scene.
        qpos: Its configuration for the bodies placed in ``world`` (e.g. the home keyframe).
        moving: Body names whose frames the MCAP moves on ``/tf``.
    """
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_kinematics(model, data)
    entities: dict[int, dict[str, Any]] = {}
    for g in range(model.ngeom):
        if model.geom_group[g] not in VISIBLE_GROUPS or model.geom_rgba[g, 3] <= 0.0:
            continue
        b = int(model.geom_bodyid[g])
        name = model.body(b).name
        pos, quat = model.geom_pos[g], model.geom_quat[g]
        if name not in moving:  # fixed in this motion: placed once, in world
            pos, quat = _compose(data.xpos[b], data.xquat[b], pos, quat)
        primitives = _geom_primitives(model, g, pos, quat)
        if not primitives:
            continue
        entity = entities.setdefault(
            b,
            {
                "timestamp": {"sec": 0, "nsec": 0},
                "frame_id": name if name in moving else "world",
                "id": name or f"body{b}",
                "lifetime": {"sec": 0, "nsec": 0},
                "frame_locked": name in moving,
            },
        )
        for key, items in primitives.items():
            entity.setdefault(key, []).extend(items)
    return list(entities.values())
