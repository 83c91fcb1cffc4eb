"""The G1 as the controller sees it: Pinocchio's model with the contact frames added.

Frames (``pin.FrameType.OP_FRAME``), the same points the TO's contacts use
(:func:`locoman.retarget.robot.contact_frames`):
    * ``left_sole``, ``right_sole``: the centre of each foot box's bottom face, axes of the
      ankle-roll link (z up when the foot is flat);
    * ``left_palm``, ``right_palm``: the centre of each hand's capsule, axes of the palm's
      contact frame (z its outward normal);
    * ``pelvis``: the base link, ``torso_link`` the torso above the waist (both already in
      the model).
Conventions: ``q`` (36,) and ``v`` (35,) are Pinocchio's (base quaternion xyzw; base twist in
the base frame). Jacobians are ``LOCAL_WORLD_ALIGNED``: a frame's linear velocity [m/s] and
angular velocity [rad/s], both in world axes, and a wrench (force [N], moment [N m]) at the
frame's origin in world axes maps to joint torques through J^T.
"""

from __future__ import annotations

import functools

import numpy as np
import pinocchio as pin

from locoman.retarget.robot import contact_frames
from locoman.scene import g1

SOLES = ("left_sole", "right_sole")
PALMS = ("left_palm", "right_palm")
BASE = g1.BASE_LINK
TORSO = "torso_link"


@functools.cache
def execution_model() -> pin.Model:
    """The G1's Pinocchio model with the sole and palm frames (shared: do not modify)."""
    model = pin.Model(g1.g1_pinocchio_model())
    frames = contact_frames()
    for name, link in zip(SOLES, g1.FOOT_LINKS, strict=True):
        _add_frame(model, name, link, np.eye(3), frames.sole[name])
    for name, link in zip(PALMS, g1.HAND_LINKS, strict=True):
        _add_frame(model, name, link, frames.palm_axes[name], frames.palm[name])
    return model


def _add_frame(
    model: pin.Model, name: str, link: str, rotation: np.ndarray, offset: np.ndarray
) -> None:
    parent_id = model.getFrameId(link)
    parent = model.frames[parent_id]
    placement = parent.placement * pin.SE3(rotation, np.asarray(offset, dtype=float))
    model.addFrame(
        pin.Frame(name, parent.parentJoint, parent_id, placement, pin.FrameType.OP_FRAME)
    )


def torque_limits(model: pin.Model) -> np.ndarray:
    """(29,) each joint's torque limit from the URDF's ``effort`` [N m]."""
    return np.asarray(model.effortLimit[6:], dtype=float).copy()
