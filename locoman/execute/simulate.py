"""MuJoCo's forward dynamics of the G1 and the scene's objects under the tracking controller.

The scene stage's MJCF (``data/<scenario>/scene/scene.xml``) with, for execution:
    * a torque motor per joint, its control range the URDF's effort limit;
    * the controller's period as MuJoCo's step (1 kHz by default);
    * torsional friction on the palms, the TO's palm patch's (:func:`palm_torsion`);
the objects stay free bodies: a hand holds one only through MuJoCo's contact and friction.
"""

from __future__ import annotations

import dataclasses
import logging

import mujoco
import numpy as np

from locoman.config.execute import ExecuteCfg
from locoman.errors import SolverError
from locoman.execute.controller import Command, InverseDynamicsQp
from locoman.execute.grasp import GraspMonitor
from locoman.execute.model import BASE, execution_model, torque_limits
from locoman.execute.reference import Reference
from locoman.retarget.robot import contact_frames
from locoman.scene import g1
from locoman.scene.rotations import quat_wxyz_to_matrix, rpy_to_matrix

log = logging.getLogger(__name__)


def palm_torsion(friction: float, half_extents: np.ndarray) -> float:
    """MuJoCo's torsional friction [m] of a palm pressed flat on an object: the largest
    moment about the normal per newton of normal force, mu times the mean distance of the
    TO's palm patch (half extents (2,) [m]) from its centre under a uniform pressure."""
    a, b = (float(h) for h in half_extents)
    # Mean of sqrt(x^2 + y^2) over the rectangle [-a, a] x [-b, b] (closed form).
    d = np.hypot(a, b)
    mean = (2 * a * b * d + a**3 * np.log((b + d) / a) + b**3 * np.log((a + d) / b)) / (6 * a * b)
    return friction * mean


def execution_mjmodel(
    spec: mujoco.MjSpec, cfg: ExecuteCfg, palm_torsion_m: float = 0.0
) -> mujoco.MjModel:
    """The scene ``spec`` (the scene stage's, :func:`locoman.scene.io.load_scene_spec`;
    changed in place) with a torque motor on every G1 joint, stepping every
    ``cfg.timestep_s``; with ``palm_torsion_m`` > 0 [m] the palms' collision geoms resist a
    twist about their normal (MuJoCo's condim 4, :func:`palm_torsion`) as the TO's palm
    patch does: with point contacts a box held between two palms pivots about the line
    through them and drops."""
    spec.option.timestep = cfg.timestep_s
    limits = torque_limits(execution_model())
    for name, limit in zip(g1.G1_JOINT_NAMES, limits, strict=True):
        motor = spec.add_actuator()
        motor.name = name
        motor.target = name
        motor.trntype = mujoco.mjtTrn.mjTRN_JOINT
        motor.gainprm[0] = 1.0
        motor.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE
        motor.ctrlrange = [-limit, limit]
    if palm_torsion_m > 0.0:
        for link in g1.HAND_LINKS:
            for geom in spec.body(link).geoms:
                if geom.contype or geom.conaffinity:
                    geom.condim = 4
                    geom.friction = [geom.friction[0], palm_torsion_m, geom.friction[2]]
    return spec.compile()


def tilt_from(rotation: np.ndarray, planned: np.ndarray) -> float:
    """The angle [rad] between a frame's vertical axis (``rotation`` (3, 3), world axes) and
    the plan's (``planned``): how far the pelvis leans beyond the plan's lean (S1's plan
    bends it 1.06 rad to pick its basket up; an absolute bound called that a fall)."""
    return float(np.arccos(np.clip(rotation[:, 2] @ planned[:, 2], -1.0, 1.0)))


@dataclasses.dataclass(frozen=True)
class StateMap:
    """Where the G1's state lies in MuJoCo's ``qpos``/``qvel`` and its objects' poses."""

    base_qpos: int
    base_dof: int
    joint_qpos: np.ndarray
    joint_dof: np.ndarray
    object_qpos: dict[str, int]

    @classmethod
    def of(cls, model: mujoco.MjModel, objects: list[str]) -> StateMap:
        base = model.joint("floating_base_joint")
        joints = [model.joint(name) for name in g1.G1_JOINT_NAMES]
        return cls(
            int(base.qposadr[0]),
            int(base.dofadr[0]),
            np.array([j.qposadr[0] for j in joints]),
            np.array([j.dofadr[0] for j in joints]),
            {name: int(model.joint(f"{name}_free").qposadr[0]) for name in objects},
        )

    def pin_state(self, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
        """Pinocchio (q (36,), v (35,)): MuJoCo's free joint has its linear velocity in world
        axes, Pinocchio's in the base frame."""
        b, bd = self.base_qpos, self.base_dof
        quat = data.qpos[b + 3 : b + 7]
        rotation = quat_wxyz_to_matrix(quat)
        q = np.concatenate([data.qpos[b : b + 3], quat[1:], quat[:1], data.qpos[self.joint_qpos]])
        v = np.concatenate(
            [
                rotation.T @ data.qvel[bd : bd + 3],
                data.qvel[bd + 3 : bd + 6],
                data.qvel[self.joint_dof],
            ]
        )
        return q, v

    def set_pin_state(self, data: mujoco.MjData, q: np.ndarray, v: np.ndarray) -> None:
        b, bd = self.base_qpos, self.base_dof
        data.qpos[b : b + 3] = q[:3]
        data.qpos[b + 3 : b + 7] = np.r_[q[6], q[3:6]]
        data.qpos[self.joint_qpos] = q[7:]
        rotation = quat_wxyz_to_matrix(data.qpos[b + 3 : b + 7])
        data.qvel[bd : bd + 3] = rotation @ v[:3]
        data.qvel[bd + 3 : bd + 6] = v[3:6]
        data.qvel[self.joint_dof] = v[6:]

    def object_pose(self, data: mujoco.MjData, name: str) -> tuple[np.ndarray, np.ndarray]:
        """(position (3,) [m], rotation (3, 3)) of an object's body frame."""
        adr = self.object_qpos[name]
        return data.qpos[adr : adr + 3].copy(), quat_wxyz_to_matrix(data.qpos[adr + 3 : adr + 7])


@dataclasses.dataclass(frozen=True)
class Execution:
    """What happened, at every control step.

    Attributes:
        time: (T,) [s].
        q: (T, 36) the G1's Pinocchio configuration; ``v`` (T, 35) its velocity.
        tau: (T, 29) the torques applied [N m].
        foot_wrench: (T, 2, 6) the QP's wrench on each foot [N, N m].
        stance: (T, 2) feet the QP held on the ground.
        limits_dropped: (T,) steps solved without the torque limits (Command).
        object_position: (T, M, 3) [m]; ``object_rotation`` (T, M, 3, 3).
        qpos: (T, nq) MuJoCo's state (for the pictures).
        solve_time_s: (T,) the QP's time per step [s].
        lost_grasps: (time [s], hand (0 left, 1 right), object) of each hold a hand lost
            (:class:`locoman.execute.grasp.GraspMonitor`).
        completed: Whether every step ran (False: the QP failed, the robot fell, or the
            simulation diverged, ``stopped`` says which).
        stopped: Why it stopped early ('' when it completed).
    """

    time: np.ndarray
    q: np.ndarray
    v: np.ndarray
    tau: np.ndarray
    foot_wrench: np.ndarray
    stance: np.ndarray
    limits_dropped: np.ndarray
    object_position: np.ndarray
    object_rotation: np.ndarray
    qpos: np.ndarray
    solve_time_s: np.ndarray
    lost_grasps: list[tuple[float, int, int]]
    completed: bool
    stopped: str


def initial_qpos(
    model: mujoco.MjModel, states: StateMap, ref: Reference, objects: list[str]
) -> np.ndarray:
    """MuJoCo's qpos at the reference's first sample: the G1 and each object where the TO
    starts (any other body where the model puts it)."""
    data = mujoco.MjData(model)
    states.set_pin_state(data, ref.q[0], np.zeros(ref.v.shape[1]))
    for j, name in enumerate(objects):
        adr = states.object_qpos[name]
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, rpy_to_matrix(ref.object_q[0, j, 3:6]).ravel())
        data.qpos[adr : adr + 7] = np.r_[ref.object_q[0, j, :3], quat]
    return data.qpos.copy()


def execute(
    model: mujoco.MjModel,
    ref: Reference,
    objects: list[str],
    cfg: ExecuteCfg,
    friction: float,
    steps: int = -1,
) -> Execution:
    """Run the controller on MuJoCo's forward dynamics along ``ref``, ``steps`` steps (all
    by default), the soles' cones with the TO's floor ``friction``; stops early when the QP
    fails or the pelvis falls (``cfg.fallen_*``)."""
    states = StateMap.of(model, objects)
    data = mujoco.MjData(model)
    data.qpos[:] = initial_qpos(model, states, ref, objects)
    mujoco.mj_forward(model, data)
    half = contact_frames().sole_half_extents
    controller = InverseDynamicsQp(execution_model(), cfg, half, friction)
    total = len(ref) if steps < 0 else min(steps, len(ref))
    monitor = GraspMonitor.of(model, objects, cfg.grasp_grace_s, cfg.timestep_s)
    log_rows: list[tuple] = []
    lost: list[tuple[float, int, int]] = []
    stopped = ""
    for i in range(total):
        q, v = states.pin_state(data)
        for hand in monitor.update(model, data, ref.hand_object[i]):
            lost.append((float(data.time), hand, int(ref.hand_object[i, hand])))
        try:
            command: Command = controller.step(q, v, ref, i)
        except SolverError as exc:
            stopped = f"controller: {exc}"
            break
        log_rows.append((data.time, q, v, command, data.qpos.copy()))
        data.ctrl[:] = command.tau
        mujoco.mj_step(model, data)
        if not np.all(np.isfinite(data.qpos)):
            stopped = f"simulation diverged at t = {data.time:.3f} s"
            break
        tilt = tilt_from(quat_wxyz_to_matrix(data.qpos[3:7]), ref.frames[BASE].rotation[i])
        if data.qpos[2] < cfg.fallen_height_m or tilt > cfg.fallen_tilt_rad:
            stopped = (
                f"fell at t = {data.time:.3f} s (pelvis {data.qpos[2]:.2f} m, tilt {tilt:.2f} rad)"
            )
            break
    if stopped:
        log.warning("execution stopped early: %s", stopped)
    return _execution(log_rows, model, states, objects, lost, not stopped, stopped)


def _execution(rows, model, states, objects, lost, completed, stopped) -> Execution:
    data = mujoco.MjData(model)
    positions, rotations = [], []
    for row in rows:
        data.qpos[:] = row[4]
        poses = [states.object_pose(data, name) for name in objects]
        positions.append([p for p, _ in poses])
        rotations.append([R for _, R in poses])
    count = len(rows)
    return Execution(
        time=np.array([r[0] for r in rows]),
        q=np.array([r[1] for r in rows]),
        v=np.array([r[2] for r in rows]),
        tau=np.array([r[3].tau for r in rows]),
        foot_wrench=np.array([r[3].foot_wrench for r in rows]),
        stance=np.array([r[3].stance for r in rows]),
        limits_dropped=np.array([r[3].limits_dropped for r in rows], dtype=bool),
        object_position=np.array(positions).reshape(count, len(objects), 3),
        object_rotation=np.array(rotations).reshape(count, len(objects), 3, 3),
        qpos=np.array([r[4] for r in rows]),
        solve_time_s=np.array([r[3].solve_time_s for r in rows]),
        lost_grasps=lost,
        completed=completed,
        stopped=stopped,
    )
