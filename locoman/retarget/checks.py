"""Checks of a keyframe that do not trust the IK: MuJoCo and Pinocchio recompute them."""

from __future__ import annotations

import functools

import mujoco
import numpy as np
import pinocchio as pin

from locoman.retarget.ik import polygon_margin, support_polygon, yaw_of
from locoman.scene import g1


@functools.cache
def _g1_alone() -> tuple[mujoco.MjModel, mujoco.MjData]:
    model = g1.g1_mjmodel()
    return model, mujoco.MjData(model)


def self_collision_pairs(q: np.ndarray) -> list[tuple[str, str]]:
    """Pairs of G1 links (names) whose collision geoms touch or overlap at Pinocchio
    configuration ``q`` (36,), from MuJoCo's collision detection on the G1 alone (the
    neighbour exclusions of :func:`locoman.scene.g1.g1_mjspec` apply)."""
    model, data = _g1_alone()
    data.qpos[:] = g1.pin_to_mujoco_qpos(q, model, data.qpos)
    mujoco.mj_forward(model, data)
    pairs = set()
    for contact in data.contact[: data.ncon]:
        if contact.dist < 0.0:
            a = model.body(model.geom_bodyid[contact.geom1]).name
            b = model.body(model.geom_bodyid[contact.geom2]).name
            pairs.add(tuple(sorted((a, b))))
    return sorted(pairs)


def joint_limit_violation(q: np.ndarray) -> float:
    """Largest excursion [rad] of a joint beyond its limits (0 when within)."""
    model = g1.g1_pinocchio_model()
    joints = q[7:]
    below = model.lowerPositionLimit[7:] - joints
    above = joints - model.upperPositionLimit[7:]
    return float(max(0.0, below.max(), above.max()))


def com_support_margin(q: np.ndarray, soles: list[np.ndarray]) -> tuple[np.ndarray, float]:
    """Centre of mass (3,) [m] (Pinocchio) and its signed distance [m] inside the support
    polygon of the soles (sole centres (3,), turned like the base): > 0 inside."""
    model = g1.g1_pinocchio_model()
    data = model.createData()
    com = pin.centerOfMass(model, data, q)
    yaw = yaw_of(pin.Quaternion(q[6], q[3], q[4], q[5]).toRotationMatrix())
    polygon = support_polygon(soles, [yaw] * len(soles))
    return com, polygon_margin(com[:2], polygon)
