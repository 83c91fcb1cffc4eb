"""The G1 as placo loads it: the URDF's kinematics with pure-shape collision geometry.

placo's self-collision constraint computes distances between collision geometries with
hpp-fcl. The URDF's collision meshes are non-convex and slow, so they are replaced by the
primitives the MuJoCo model uses to *measure* self-collision (:mod:`locoman.scene.g1`):
boxes for the feet, the shoulders' cylinders, and each fitted capsule as a chain of spheres
along its axis (URDF has no capsule). The collision pairs are MuJoCo's: every pair of links except
a link and its two nearest ancestors, whose shapes overlap by construction.

Two fixed frames are added for the contacts: ``<side>_palm`` at the centre of the hand's
capsule, and ``<side>_sole`` at the centre of the foot box's bottom face.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import re
import tempfile
import warnings
from pathlib import Path

import mujoco
import numpy as np
import placo

from locoman.scene import assets, g1, rotations

PALM_FRAMES = {"left_hand": "left_palm", "right_hand": "right_palm"}
SOLE_FRAMES = {"left_foot": "left_sole", "right_foot": "right_sole"}
_HAND_LINK = {"left_palm": "left_rubber_hand", "right_palm": "right_rubber_hand"}
_FOOT_LINK = {"left_sole": "left_ankle_roll_link", "right_sole": "right_ankle_roll_link"}


@dataclasses.dataclass(frozen=True)
class ContactFrames:
    """Where the G1 touches, in its link frames.

    Attributes:
        palm: Link name -> palm centre in the hand link frame [m].
        palm_radius: Radius of the hand's collision capsule [m].
        palm_half_length: Half length of that capsule's axis [m]; like the radius, the
            larger of the two hands' (they differ by 4 mm), so their spheres cover both.
        palm_axes: Link name -> (3, 3) palm contact frame in the hand link frame: z the
            palm's outward normal, square to the capsule's axis (x), so that a palm laid on
            a face along z touches it along the whole capsule.
        sole: Link name -> sole centre in the ankle roll link frame [m].
        sole_half_extents: (2,) half length and half width of the foot box [m].
    """

    palm: dict[str, np.ndarray]
    palm_radius: float
    palm_half_length: float
    palm_axes: dict[str, np.ndarray]
    sole: dict[str, np.ndarray]
    sole_half_extents: np.ndarray


@functools.cache
def contact_frames() -> ContactFrames:
    """Palm and sole frames of the MuJoCo G1's collision geometry."""
    model = g1.g1_mjmodel()
    palm, radii, lengths, axes, sole = {}, [], [], {}, {}
    for frame, link in _HAND_LINK.items():
        geom = _collision_geoms(model, link)[0]
        palm[frame] = model.geom_pos[geom].copy()
        radii.append(float(model.geom_size[geom][0]))
        lengths.append(float(model.geom_size[geom][1]))
        rot = np.zeros(9)
        mujoco.mju_quat2Mat(rot, model.geom_quat[geom])
        along = rot.reshape(3, 3)[:, 2] * np.sign(rot[2])  # towards the fingers (+x)
        # The left palm faces -y of its link, the right +y.
        facing = np.array([0.0, -1.0 if frame.startswith("left") else 1.0, 0.0])
        normal = facing - (facing @ along) * along
        normal /= np.linalg.norm(normal)
        axes[frame] = np.column_stack([along, np.cross(normal, along), normal])
    for frame, link in _FOOT_LINK.items():
        geom = model.geom(link.replace("_ankle_roll_link", "_foot"))
        sole[frame] = geom.pos - np.array([0.0, 0.0, geom.size[2]])
        half = geom.size[:2].copy()
    return ContactFrames(palm, max(radii), max(lengths), axes, sole, half)


def _collision_geoms(model: mujoco.MjModel, body: str) -> list[int]:
    bid = model.body(body).id
    return [
        g
        for g in range(model.ngeom)
        if model.geom_bodyid[g] == bid and model.geom_group[g] == g1.COLLISION_GROUP
    ]


def _origin(pos: np.ndarray, quat_wxyz: np.ndarray | None = None) -> str:
    rpy = np.zeros(3)
    if quat_wxyz is not None:
        with warnings.catch_warnings():  # gimbal lock: any valid angle triple will do
            warnings.simplefilter("ignore", UserWarning)
            rpy = rotations.quat_xyzw_to_rpy(rotations.wxyz_to_xyzw(quat_wxyz))
    return '<origin xyz="{} {} {}" rpy="{} {} {}"/>'.format(*pos, *rpy)


def _shapes(model: mujoco.MjModel, geom: int) -> list[str]:
    """URDF ``<collision>`` elements of one MuJoCo collision geom."""
    kind, size = model.geom_type[geom], model.geom_size[geom]
    pos, quat = model.geom_pos[geom], model.geom_quat[geom]
    if kind == mujoco.mjtGeom.mjGEOM_BOX:
        shape = '<box size="{} {} {}"/>'.format(*(2.0 * size))
        return [f"<collision>{_origin(pos, quat)}<geometry>{shape}</geometry></collision>"]
    if kind == mujoco.mjtGeom.mjGEOM_CYLINDER:
        shape = f'<cylinder radius="{size[0]}" length="{2.0 * size[1]}"/>'
        return [f"<collision>{_origin(pos, quat)}<geometry>{shape}</geometry></collision>"]
    # Spheres at most a radius apart: between two of them the chain is at most 13 % of a
    # radius (1.6 cm on the torso) thinner than the capsule; the IK margin covers that.
    return [
        f'<collision>{_origin(c)}<geometry><sphere radius="{r}"/></geometry></collision>'
        for c, r in g1.capsule_spheres(model, geom)
    ]


@functools.cache
def placo_urdf() -> Path:
    """The URDF placo loads, with ``collisions.json`` (its collision pairs) beside it, in a
    temporary folder of this process."""
    model = g1.g1_mjmodel()
    urdf = assets.urdf_text(assets.G1_URDF)
    urdf = re.sub(r"<collision>.*?</collision>", "", urdf, flags=re.S)
    urdf = re.sub(r"<visual>.*?</visual>", "", urdf, flags=re.S)
    bodies = []
    for body in range(1, model.nbody):
        name = model.body(body).name
        geoms = _collision_geoms(model, name)
        if not geoms:
            continue
        bodies.append(name)
        shapes = "".join(s for g in geoms for s in _shapes(model, g))
        urdf, count = re.subn(
            rf'(<link\s+name="{re.escape(name)}"\s*>)', lambda m, s=shapes: m.group(1) + s, urdf
        )
        if count != 1:
            raise ValueError(f"link {name!r} not found once in the G1 URDF")
    frames = contact_frames()
    extra = []
    for frame, link in (*_HAND_LINK.items(), *_FOOT_LINK.items()):
        offset = frames.palm.get(frame, frames.sole.get(frame))
        extra.append(
            f'<link name="{frame}"/><joint name="{frame}_joint" type="fixed">'
            f'<parent link="{link}"/><child link="{frame}"/>{_origin(offset)}</joint>'
        )
    urdf = urdf.replace("</robot>", "".join(extra) + "</robot>")
    excluded = {
        frozenset((model.body(s >> 16).name, model.body(s & 0xFFFF).name))
        for s in model.exclude_signature
    }
    pairs = [
        [a, b]
        for k, a in enumerate(bodies)
        for b in bodies[k + 1 :]
        if frozenset((a, b)) not in excluded
    ]
    folder = Path(tempfile.mkdtemp(prefix="locoman_g1_"))
    (folder / "collisions.json").write_text(json.dumps(pairs))
    (folder / "robot.urdf").write_text(urdf)
    return folder / "robot.urdf"


def placo_robot() -> placo.RobotWrapper:
    """A fresh placo model of the G1 (placo reads ``collisions.json`` beside the URDF)."""
    return placo.RobotWrapper(str(placo_urdf()))
