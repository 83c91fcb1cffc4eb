"""Human demonstrator model (``human_description`` from ``example-robot-data``).

The URDF is y-up (x forward, z to the person's right). The root is a free joint on the pelvis;
:data:`UPRIGHT_QUAT_WXYZ` turns the model upright in the z-up world (+90 deg about x).

The URDF's "virtual" links (between the revolute joints of a ball-like joint) have no
inertial; MuJoCo refuses moving bodies without mass, so they get :data:`VIRTUAL_LINK_MASS`
and a matching tiny inertia. This changes the total mass by under 0.1 %. The model is only
posed kinematically (rendering, inverse kinematics), so its dynamics do not matter here.
"""

from __future__ import annotations

import functools
import re

import mujoco
import numpy as np
import pinocchio as pin

from locoman.scene import assets

VIRTUAL_LINK_MASS = 1e-3  # [kg]
VIRTUAL_LINK_INERTIA = 1e-7  # [kg m^2]
UPRIGHT_QUAT_WXYZ = np.array([np.cos(np.pi / 4), np.sin(np.pi / 4), 0.0, 0.0])
ROOT_LINK = "middle_pelvis"
HAND_LINKS = ("left_hand", "right_hand")
FOOT_LINKS = ("left_foot", "right_foot")
SKIN_RGBA = (0.85, 0.66, 0.53, 1.0)


@functools.cache
def human_pinocchio_model() -> pin.Model:
    """Pinocchio model of the demonstrator with a free-flyer root (nq = 43)."""
    return pin.buildModelFromXML(assets.urdf_text(assets.HUMAN_URDF), pin.JointModelFreeFlyer())


def human_mjspec(prefix: str = "human_", rgba: tuple[float, ...] = SKIN_RGBA) -> mujoco.MjSpec:
    """MuJoCo spec of the demonstrator: free joint on the pelvis, meshes as visuals only.

    Its geoms never collide (contype = conaffinity = 0): the demonstrator is drawn, not
    simulated.

    Args:
        prefix: Prepended to body and joint names so the human can share a scene.
        rgba: Colour of the body meshes.
    """
    urdf = assets.urdf_text(assets.HUMAN_URDF, mesh_root="")
    ext = '<mujoco><compiler fusestatic="false" discardvisual="false" strippath="false"/></mujoco>'
    urdf = re.sub(r"(<robot[^>]*>)", lambda m: m.group(1) + ext, urdf, count=1)
    spec = mujoco.MjSpec.from_string(urdf)
    spec.meshdir = str(assets.robots_dir())
    spec.modelname = "human"
    spec.body(ROOT_LINK).add_freejoint(name="root_joint")
    for body in spec.bodies:
        if body.name == "world":
            continue
        if body.mass <= 0.0:
            body.mass = VIRTUAL_LINK_MASS
            body.inertia = [VIRTUAL_LINK_INERTIA] * 3
            body.explicitinertial = True
        for geom in body.geoms:
            geom.contype, geom.conaffinity, geom.group = 0, 0, 1
            geom.rgba = list(rgba)
        if prefix:
            body.name = prefix + body.name
    if prefix:
        for joint in spec.joints:
            joint.name = prefix + joint.name
    return spec


@functools.cache
def standing_pelvis_height() -> float:
    """Pelvis height [m] at which the upright, zero-posture demonstrator's soles touch z = 0."""
    model = human_mjspec(prefix="").compile()
    data = mujoco.MjData(model)
    data.qpos[3:7] = UPRIGHT_QUAT_WXYZ
    mujoco.mj_forward(model, data)
    lowest = np.inf
    for gid in range(model.ngeom):
        if model.body(model.geom_bodyid[gid]).name not in FOOT_LINKS:
            continue
        mesh = model.geom_dataid[gid]
        verts = model.mesh_vert[
            model.mesh_vertadr[mesh] : model.mesh_vertadr[mesh] + model.mesh_vertnum[mesh]
        ]
        world = verts @ data.geom_xmat[gid].reshape(3, 3).T + data.geom_xpos[gid]
        lowest = min(lowest, float(world[:, 2].min()))
    return -lowest
