"""Simulated RGB-D views R_s, D_s of a scene's object (paper A, Sec. III-A.2).

The scene's MJCF is rendered with the robot hidden, from a camera on the object's approach
(-x) side turned ``azimuth_deg`` towards its +y side, with true intrinsics. Everything here is
known to a robot in its own simulator, so the pipeline may use it.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from locoman.config.perception import SimViewCfg
from locoman.errors import SceneError
from locoman.perception import camera
from locoman.perception.render_backend import (
    MIN_OBJECT_PIXELS,
    render_rgbd,
)
from locoman.scene import g1
from locoman.scene.io import load_scene_spec
from locoman.scene.objects import primitive_half_extents


@dataclasses.dataclass(frozen=True)
class SimView:
    """R_s and D_s of one object.

    Attributes:
        rgb: (H, W, 3) uint8.
        depth_m: (H, W) float32 depth along the optical axis [m], 0 where nothing is seen.
        K: (3, 3) true intrinsics.
        T_world_cam: (4, 4) camera pose in the scene (OpenCV axes).
        T_world_object: (4, 4) the object's pose in the scene.
        object_mask: (H, W) true segmentation of the object (used by the ``render`` masks).
    """

    rgb: np.ndarray
    depth_m: np.ndarray
    K: np.ndarray
    T_world_cam: np.ndarray
    T_world_object: np.ndarray
    object_mask: np.ndarray


def _place(model: mujoco.MjModel, data: mujoco.MjData, name: str, pose: np.ndarray) -> None:
    """Put a movable object at ``pose``; a fixed one must already be there."""
    joint = f"{name}_free"
    if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, joint) < 0:
        mujoco.mj_forward(model, data)
        if np.abs(data.body(name).xpos - pose[:3, 3]).max() > 1e-6:
            raise SceneError(f"object {name!r} is fixed in the scene; the plan cannot move it")
        return
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, pose[:3, :3].ravel())
    adr = model.joint(joint).qposadr[0]
    data.qpos[adr : adr + 7] = np.r_[pose[:3, 3], quat]


def bounding_sphere(obj: dict[str, Any]) -> tuple[np.ndarray, float]:
    """Centre (object frame) [m] and radius [m] of a sphere holding all primitives."""
    corners = []
    signs = np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1])).T.reshape(-1, 3)
    for p in obj["primitives"]:
        half = primitive_half_extents(p["shape"], tuple(p["size"]))
        corners.append(np.asarray(p["pos"]) + signs * half)
    pts = np.vstack(corners)
    centre = 0.5 * (pts.min(axis=0) + pts.max(axis=0))
    return centre, float(np.linalg.norm(pts - centre, axis=1).max())


def render_sim_view(
    scene_dir: str | Path,
    name: str,
    obj: dict[str, Any],
    T_obj: np.ndarray,
    cfg: SimViewCfg,
    movable_poses: dict[str, np.ndarray] | None = None,
) -> SimView:
    """Render R_s, D_s of object ``name``, at pose ``T_obj`` (4, 4), in the scene stage's MJCF,
    with every other movable object where the plan left it (``movable_poses``, world (4, 4);
    :mod:`locoman.scene.plan_state`).

    Raises:
        SceneError: When the object is hidden or out of view, or must move and cannot.
    """
    scene_dir = Path(scene_dir)
    centre_obj, radius = bounding_sphere(obj)
    target = camera.transform(centre_obj[None], T_obj)[0]
    az, el = np.deg2rad(cfg.azimuth_deg), np.deg2rad(cfg.elevation_deg)
    bearing_obj = np.array([-np.cos(az) * np.cos(el), np.sin(az) * np.cos(el), np.sin(el)])
    bearing = T_obj[:3, :3] @ bearing_obj
    fovy = np.deg2rad(cfg.fovy_deg)
    distance = radius / np.tan(0.5 * fovy * cfg.fill)
    T_cam = camera.look_at(target + distance * bearing, target)

    spec = load_scene_spec(scene_dir)
    spec.visual.global_.offwidth = max(spec.visual.global_.offwidth, cfg.width)
    spec.visual.global_.offheight = max(spec.visual.global_.offheight, cfg.height)
    spec.worldbody.add_camera(
        name="sim_view",
        pos=T_cam[:3, 3].tolist(),
        xyaxes=camera.mujoco_xyaxes(T_cam),
        fovy=cfg.fovy_deg,
    )
    model = spec.compile()
    data = mujoco.MjData(model)
    data.qpos[:] = model.key("home").qpos
    for other, pose in (movable_poses or {}).items():
        _place(model, data, other, pose)
    _place(model, data, name, T_obj)
    mujoco.mj_forward(model, data)
    option = mujoco.MjvOption()
    option.geomgroup[:] = 1
    option.geomgroup[g1.VISUAL_GROUP] = option.geomgroup[g1.COLLISION_GROUP] = 0
    rgb, depth, geoms = render_rgbd(model, data, "sim_view", cfg.width, cfg.height, option)
    body = model.body(name).id
    mask = np.isin(geoms, np.nonzero(model.geom_bodyid == body)[0])
    if mask.sum() < MIN_OBJECT_PIXELS:
        raise SceneError(
            f"object {name!r}: only {int(mask.sum())} pixels visible in the simulated view; "
            "change perception.generate.sim_view (azimuth_deg, elevation_deg)"
        )
    K = camera.intrinsics_from_fovy(cfg.width, cfg.height, fovy)
    return SimView(rgb, depth, K, T_cam, T_obj, mask)
