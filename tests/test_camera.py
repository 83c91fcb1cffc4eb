"""The filmstrip's camera: where it stands, and the side it picks when the scene hides the
robot."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from locoman.scene.io import load_scene_spec
from locoman.sim import camera
from locoman.sim.pipeline import view_option


@pytest.mark.parametrize("bearing", camera.BEARINGS_DEG)
def test_the_camera_stands_at_its_bearing_from_the_robots_heading(tiny_scene, bearing):
    model = load_scene_spec(tiny_scene).compile()
    data = mujoco.MjData(model)
    q = np.zeros(35)
    q[:3], q[5] = [0.3, -0.2, 0.75], 0.7  # base position [m], yaw [rad]
    with mujoco.Renderer(model, 32, 32) as renderer:
        renderer.update_scene(data, camera=camera.follow(q, bearing))
        eye = np.mean([c.pos for c in renderer.scene.camera], axis=0)
    offset = eye - (q[:3] + camera.LOOKAT_OFFSET_M)
    elevation = np.radians(-camera.ELEVATION_DEG)
    heading = q[5] + np.radians(bearing)
    expected = camera.DISTANCE_M * np.array(
        [
            np.cos(heading) * np.cos(elevation),
            np.sin(heading) * np.cos(elevation),
            np.sin(elevation),
        ]
    )
    assert np.allclose(offset, expected, atol=1e-3)


@pytest.mark.parametrize("side", [1.0, -1.0])
def test_a_wall_on_one_side_of_the_robot_turns_the_camera_to_the_other(tiny_scene, side):
    spec = load_scene_spec(tiny_scene)
    qpos = spec.compile().key("home").qpos.copy()
    w, _, _, z = qpos[3:7]
    q = np.zeros(35)
    q[:3], q[5] = qpos[:3], 2.0 * np.arctan2(z, w)  # the base and its yaw (level base)
    left = np.array([-np.sin(q[5]), np.cos(q[5]), 0.0])
    # A wall 1.2 m to the robot's left (side 1) or right (-1), along its heading: 4 m long,
    # 3 m tall, between the camera and the robot from every bearing on that side.
    wall = spec.worldbody.add_geom()
    wall.type = mujoco.mjtGeom.mjGEOM_BOX
    wall.size = [2.0, 0.05, 1.5]
    wall.pos = np.r_[q[:2], 0.0] + 1.2 * side * left + [0.0, 0.0, 1.5]
    wall.quat = [np.cos(q[5] / 2), 0.0, 0.0, np.sin(q[5] / 2)]
    bearing = camera.best_bearing(spec.compile(), view_option(), [qpos], [q])
    assert np.sign(bearing) == -side


def test_the_robot_alone_needs_a_hidden_geom_group(tiny_scene):
    model = load_scene_spec(tiny_scene).compile()
    option = mujoco.MjvOption()
    option.geomgroup[:] = 1
    with pytest.raises(ValueError, match="hides at least one geom group"):
        camera.robot_alone(model, option)
