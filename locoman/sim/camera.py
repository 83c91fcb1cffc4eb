"""The camera that follows the robot in the filmstrip and the MP4, on the side where the
scene does not hide it.

A fixed view fails somewhere: from the robot's front right, S1's shelf stands between the
camera and the robot stepping onto the box; from its right, ``tiny``'s place table hides its
legs. So each trajectory's view is the candidate bearing from which the most of the robot
is seen, on average over the filmstrip's nodes (segmentation renders).
"""

from __future__ import annotations

import copy
from collections.abc import Sequence

import mujoco
import numpy as np

DISTANCE_M = 3.0  # [m]
ELEVATION_DEG = -20.0  # [deg]
LOOKAT_OFFSET_M = (0.0, 0.0, -0.2)  # from the base, in the world frame [m]
# Where the camera stands, seen from the robot: counter-clockwise from its heading [deg], in
# order of preference (the first of equals wins): front right, right, front left, left.
BEARINGS_DEG = (-50.0, -80.0, 50.0, 80.0)


def follow(q: np.ndarray, bearing_deg: float) -> mujoco.MjvCamera:
    """A free camera ``DISTANCE_M`` from the robot's base (``q`` (35,): p, rpy, joints) at
    ``bearing_deg`` [deg] counter-clockwise from its heading, looking at it."""
    cam = mujoco.MjvCamera()
    cam.lookat[:] = q[:3] + np.array(LOOKAT_OFFSET_M)
    cam.distance, cam.elevation = DISTANCE_M, ELEVATION_DEG
    # MuJoCo's azimuth is the direction the camera looks in, the opposite of its bearing.
    cam.azimuth = float(np.degrees(q[5])) + bearing_deg + 180.0
    return cam


def robot_geoms(model: mujoco.MjModel) -> np.ndarray:
    """(ngeom,) bool: the geoms of the robot (the tree under the ``pelvis`` body)."""
    root = model.body_rootid[model.body("pelvis").id]
    return model.body_rootid[model.geom_bodyid] == root


def robot_pixels(
    renderer: mujoco.Renderer,
    data: mujoco.MjData,
    cam: mujoco.MjvCamera,
    option: mujoco.MjvOption,
    robot: np.ndarray,
) -> int:
    """How many pixels of the robot ``cam`` sees in ``data``'s state (a segmentation render
    of ``renderer``'s model)."""
    renderer.enable_segmentation_rendering()
    try:
        renderer.update_scene(data, camera=cam, scene_option=option)
        seg = renderer.render()
    finally:
        renderer.disable_segmentation_rendering()
    ids, types = seg[..., 0], seg[..., 1]
    geom = (types == mujoco.mjtObj.mjOBJ_GEOM) & (ids >= 0)
    return int(robot[ids[geom]].sum())


def robot_alone(model: mujoco.MjModel, option: mujoco.MjvOption) -> mujoco.MjModel:
    """A copy of ``model`` whose geoms other than the robot's are in a group ``option`` hides:
    what the camera would see of the robot were nothing in the way."""
    hidden_groups = np.flatnonzero(np.asarray(option.geomgroup) == 0)
    if not len(hidden_groups):
        raise ValueError(
            "robot_alone needs a view option that hides at least one geom group (set "
            "option.geomgroup[g] = 0 for a group g the scene does not show)"
        )
    alone = copy.deepcopy(model)
    hidden = int(hidden_groups[-1])
    alone.geom_group[~robot_geoms(model)] = hidden
    return alone


def best_bearing(
    model: mujoco.MjModel,
    option: mujoco.MjvOption,
    states: Sequence[np.ndarray],
    bases: Sequence[np.ndarray],
    size: int = 160,
) -> float:
    """The bearing of :data:`BEARINGS_DEG` [deg] from which the most of the robot is seen,
    on average over the ``states`` (MuJoCo qpos), the camera following each state's base
    ``q`` (35,) (``bases``): the robot's pixels against those of the robot alone, in
    ``size`` x ``size`` [px] segmentation renders (less where the model's off-screen buffer
    is smaller)."""
    alone = robot_alone(model, option)
    size = min(size, model.vis.global_.offwidth, model.vis.global_.offheight)
    robot = robot_geoms(model)
    fraction = np.ones((len(states), len(BEARINGS_DEG)))
    data, data_alone = mujoco.MjData(model), mujoco.MjData(alone)
    with (
        mujoco.Renderer(model, size, size) as renderer,
        mujoco.Renderer(alone, size, size) as renderer_alone,
    ):
        for k, (qpos, q) in enumerate(zip(states, bases, strict=True)):
            data.qpos[:] = data_alone.qpos[:] = qpos
            mujoco.mj_forward(model, data)
            mujoco.mj_forward(alone, data_alone)
            for i, bearing in enumerate(BEARINGS_DEG):
                cam = follow(q, bearing)
                seen = robot_pixels(renderer, data, cam, option, robot)
                whole = robot_pixels(renderer_alone, data_alone, cam, option, robot)
                fraction[k, i] = seen / max(whole, 1)
    return BEARINGS_DEG[int(np.argmax(fraction.mean(axis=0)))]
