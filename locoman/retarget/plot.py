"""The picture of one keyframe: the generated image R_g next to the G1 in the keyframe, in the
scene, with the contact targets (green: the plan's contacts, grey: standing feet) and where the
keyframe's palms and soles are (blue)."""

from __future__ import annotations

import cv2
import mujoco
import numpy as np

from locoman.artifacts.pictures import fit_tile
from locoman.retarget.ik import IKResult
from locoman.scene import g1

TILE = 420  # [px]
CONTACT_RGBA = (0.15, 0.8, 0.15, 1.0)
STANDING_RGBA = (0.6, 0.6, 0.6, 1.0)
REACHED_RGBA = (0.1, 0.35, 1.0, 1.0)


def _add_sphere(scene: mujoco.MjvScene, pos: np.ndarray, radius: float, rgba) -> None:
    if scene.ngeom >= scene.maxgeom:
        return
    mujoco.mjv_initGeom(
        scene.geoms[scene.ngeom],
        mujoco.mjtGeom.mjGEOM_SPHERE,
        np.array([radius, 0.0, 0.0]),
        np.asarray(pos, dtype=float),
        np.eye(3).ravel(),
        np.asarray(rgba, dtype=np.float32),
    )
    scene.ngeom += 1


def render_keyframe(
    model: mujoco.MjModel,
    qpos: np.ndarray,
    result: IKResult,
    in_contact: list[bool],
    heading: float,
) -> np.ndarray:
    """The G1 at the keyframe, seen from its left and a little from the front of ``heading``
    [rad] (the feet's; a pelvis bent far over has no useful heading of its own), with targets
    and reached points. Not from the front: a shelf or a table the robot faces would hide
    it."""
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_forward(model, data)
    cam = mujoco.MjvCamera()
    base = result.q[:3]
    cam.lookat[:] = base + np.array([0.0, 0.0, -0.15])
    cam.distance = 2.6
    cam.azimuth = float(np.degrees(heading)) + 180.0 - 70.0
    cam.elevation = -20.0
    option = mujoco.MjvOption()
    option.geomgroup[:] = 1
    option.geomgroup[g1.COLLISION_GROUP] = 0
    with mujoco.Renderer(model, height=TILE, width=TILE) as renderer:
        renderer.update_scene(data, camera=cam, scene_option=option)
        for target, reached, contact in zip(
            result.targets, result.reached, in_contact, strict=True
        ):
            _add_sphere(renderer.scene, target, 0.03, CONTACT_RGBA if contact else STANDING_RGBA)
            _add_sphere(renderer.scene, reached, 0.02, REACHED_RGBA)
        return renderer.render().copy()


def keyframe_plot(generated: np.ndarray, robot: np.ndarray, title: str, footer: str) -> np.ndarray:
    """R_g and the rendered keyframe side by side, with a title and a footer line."""
    tiles = np.hstack([fit_tile(generated, TILE)[0], fit_tile(robot, TILE)[0]])
    band = np.full((28, tiles.shape[1], 3), 255, np.uint8)
    foot = band.copy()
    font = cv2.FONT_HERSHEY_SIMPLEX
    cv2.putText(band, title, (6, 20), font, 0.55, (0, 0, 0), 1, cv2.LINE_AA)
    cv2.putText(foot, footer, (6, 20), font, 0.45, (0, 0, 0), 1, cv2.LINE_AA)
    return np.vstack([band, tiles, foot])
