"""Validity checks of a built scene at its initial state.

A scene is valid when (i) no two bodies penetrate beyond a tolerance, self-collisions
included; (ii) a humanoid stands with both soles on the floor; (iii) every movable object
rests: simulated for :data:`SETTLE_TIME` with the robot held still, it moves less than
:data:`SETTLE_TOL` (so nothing floats, falls or tips over at start).
"""

from __future__ import annotations

import dataclasses

import mujoco
import numpy as np

from locoman.errors import SceneError
from locoman.scene import g1

SETTLE_TIME = 0.5  # [s]
SETTLE_TOL = 0.01  # [m]


@dataclasses.dataclass(frozen=True)
class SceneReport:
    """Figures of the validity checks.

    Attributes:
        max_penetration_m: Deepest contact at the start [m] (>= 0).
        deepest_pair: Names of the two bodies of the deepest contact ("" if none).
        sole_gaps_m: Height of each G1 sole's lowest corner above the floor [m] (empty for
            other robots).
        settle_displacement_m: Displacement of each movable object after settling [m].
    """

    max_penetration_m: float
    deepest_pair: tuple[str, str]
    sole_gaps_m: tuple[float, ...]
    settle_displacement_m: dict[str, float]


def body_pair(model: mujoco.MjModel, contact: mujoco.MjContact) -> tuple[str, str]:
    """Names of the two bodies in a contact."""
    return (
        model.body(model.geom_bodyid[contact.geom1]).name,
        model.body(model.geom_bodyid[contact.geom2]).name,
    )


def check_scene(
    model: mujoco.MjModel,
    qpos: np.ndarray,
    robot: str,
    penetration_tol: float,
    foot_ground_tol: float,
) -> SceneReport:
    """Run the checks at configuration ``qpos``.

    Raises:
        SceneError: Naming the bodies, the feet or the objects that fail, and by how much.
    """
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_forward(model, data)
    depth, pair = 0.0, ("", "")
    offenders = []
    for contact in data.contact[: data.ncon]:
        if -contact.dist > depth:
            depth, pair = -contact.dist, body_pair(model, contact)
        if -contact.dist > penetration_tol:
            offenders.append(f"{'/'.join(body_pair(model, contact))} by {-contact.dist:.4f} m")
    if offenders:
        raise SceneError(
            f"bodies penetrate at start beyond {penetration_tol} m: {'; '.join(offenders)}. "
            "Move the objects or the robot's start pose apart."
        )
    gaps: tuple[float, ...] = ()
    if robot == "g1":
        gaps = tuple(_sole_gap(model, data, link) for link in g1.FOOT_LINKS)
        bad = [
            f"{link}: {gap:+.4f} m"
            for link, gap in zip(g1.FOOT_LINKS, gaps, strict=True)
            if abs(gap) > foot_ground_tol
        ]
        if bad:
            raise SceneError(f"the G1 does not stand on the floor: {', '.join(bad)}")
    moved = _settle(model, qpos)
    loose = [f"{name} by {d:.3f} m" for name, d in moved.items() if d > SETTLE_TOL]
    if loose:
        raise SceneError(
            f"objects do not rest at start (moved within {SETTLE_TIME} s): {', '.join(loose)}. "
            "Check their heights and supports."
        )
    return SceneReport(depth, pair, gaps, moved)


def _sole_gap(model: mujoco.MjModel, data: mujoco.MjData, link: str) -> float:
    geom = model.geom(link.replace("_ankle_roll_link", "_foot"))
    half = model.geom_size[geom.id]
    corners = np.array([[sx, sy, -1.0] for sx in (-1, 1) for sy in (-1, 1)]) * half
    rot = data.geom_xmat[geom.id].reshape(3, 3)
    return float((corners @ rot.T + data.geom_xpos[geom.id])[:, 2].min())


def movable_objects(model: mujoco.MjModel) -> dict[str, int]:
    """Body id of every object with a free joint named ``<object>_free``."""
    out = {}
    for j in range(model.njnt):
        name = model.joint(j).name
        if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE and name.endswith("_free"):
            out[name.removesuffix("_free")] = int(model.jnt_bodyid[j])
    return out


def _settle(model: mujoco.MjModel, qpos: np.ndarray) -> dict[str, float]:
    objects = movable_objects(model)
    object_dofs: set[int] = set()
    object_qpos: set[int] = set()
    for body in objects.values():
        j = model.body_jntadr[body]
        object_qpos.update(range(model.jnt_qposadr[j], model.jnt_qposadr[j] + 7))
        object_dofs.update(range(model.jnt_dofadr[j], model.jnt_dofadr[j] + 6))
    robot_q = np.array(sorted(set(range(model.nq)) - object_qpos), dtype=int)
    robot_v = np.array(sorted(set(range(model.nv)) - object_dofs), dtype=int)
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_forward(model, data)
    start = {name: data.xpos[body].copy() for name, body in objects.items()}
    for _ in range(round(SETTLE_TIME / model.opt.timestep)):
        mujoco.mj_step(model, data)
        data.qpos[robot_q] = qpos[robot_q]
        data.qvel[robot_v] = 0.0
    mujoco.mj_forward(model, data)
    return {
        name: float(np.linalg.norm(data.xpos[body] - start[name])) for name, body in objects.items()
    }
