"""Off-screen rendering (``MUJOCO_GL=egl`` renders on the CPU through Mesa)."""

from __future__ import annotations

import mujoco
import numpy as np

from locoman.scene import g1


def render_camera(
    model: mujoco.MjModel,
    qpos: np.ndarray,
    camera: str,
    width: int,
    height: int,
    show_collision: bool = False,
) -> np.ndarray:
    """RGB image (height, width, 3) uint8 of ``camera`` at configuration ``qpos``.

    Args:
        show_collision: Draw the G1's collision primitives instead of its visual meshes.
    """
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_forward(model, data)
    option = mujoco.MjvOption()
    option.geomgroup[:] = 1
    option.geomgroup[g1.COLLISION_GROUP] = int(show_collision)
    option.geomgroup[g1.VISUAL_GROUP] = int(not show_collision)
    with mujoco.Renderer(model, height=height, width=width) as renderer:
        renderer.update_scene(data, camera=camera, scene_option=option)
        return renderer.render().copy()
