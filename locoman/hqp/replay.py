"""Closed-loop replay of a learned reference on the mobile manipulator in MuJoCo.

Every control period dt (= the simulation step): read the state, solve the HQP for the
optimal whole-body velocity qdot*, integrate it to q*, command the base with qdot*_b
(velocity actuators) and the arm with the joint impedance torque (10) around (q*_a, qdot*_a);
close the gripper at the grasp instant and open it at the place instant (known a priori, as
in Sec. IV-B). The bottle is a free body: the grasp and the place happen only if the contact
physics lets them.
"""

from __future__ import annotations

import contextlib
import dataclasses
import gc
import time
from collections.abc import Iterator

import mujoco
import numpy as np

from locoman.config.skill_transfer import HqpCfg
from locoman.errors import ModelError
from locoman.hqp.impedance import GravityModel, joint_impedance_torque
from locoman.hqp.limits import JointLimits
from locoman.hqp.orientation import grasp_orientation
from locoman.hqp.solver import WholeBodyHqp
from locoman.scene.mobile_manipulator import (
    ARM_JOINTS,
    BASE_JOINTS,
    EE_SITE,
    GRIPPER_OPEN,
    start_qpos,
)

JOINTS = BASE_JOINTS + ARM_JOINTS


@dataclasses.dataclass(frozen=True)
class ReplayTask:
    """What the replay tracks and when the gripper acts.

    Attributes:
        time_s: (T,) reference times [s], spaced by the control period.
        ee_pos: (T, 3) desired end-effector position x_d [m].
        ee_vel: (T, 3) desired end-effector velocity xd_dot [m/s].
        base: (T, 3) learned base pose q_b,d (x [m], y [m], yaw [rad]).
        grasp_velocity: Demonstrated wrist velocity at the grasp [m/s]; sets the gripper's
            orientation (:func:`locoman.hqp.orientation.grasp_orientation`).
        grasp_time_s: The gripper closes [s].
        release_time_s: The gripper opens [s].
        obj: Name of the free body to carry.
        target: Where the object must end (position of its base) [m].
    """

    time_s: np.ndarray
    ee_pos: np.ndarray
    ee_vel: np.ndarray
    base: np.ndarray
    grasp_velocity: np.ndarray
    grasp_time_s: float
    release_time_s: float
    obj: str
    target: np.ndarray


@dataclasses.dataclass(frozen=True)
class ReplayLog:
    """Commanded and actual signals at every control step (T rows)."""

    time_s: np.ndarray
    ee_pos_desired: np.ndarray
    ee_pos: np.ndarray
    ee_vel_desired: np.ndarray
    ee_vel: np.ndarray
    ee_rot_error: np.ndarray
    base_learned: np.ndarray
    base_optimal: np.ndarray
    base_actual: np.ndarray
    q_star: np.ndarray
    qdot_star: np.ndarray
    q: np.ndarray
    torque: np.ndarray
    gripper_closed: np.ndarray
    obj_pos: np.ndarray
    obj_quat_wxyz: np.ndarray
    level1_residual: np.ndarray
    hqp_step_s: np.ndarray
    qpos: np.ndarray
    wall_s: float


def joint_limits(model: mujoco.MjModel, cfg: HqpCfg) -> JointLimits:
    """Limits from the model's arm ranges (shrunk by the margin) and the configured rates."""
    rng = np.array([model.joint(n).range for n in ARM_JOINTS])
    return JointLimits(
        arm_min=rng[:, 0] + cfg.position_margin,
        arm_max=rng[:, 1] - cfg.position_margin,
        velocity_max=np.r_[cfg.base_velocity_max, cfg.arm_velocity_max],
        acceleration_max=np.r_[cfg.base_acceleration_max, cfg.arm_acceleration_max],
    )


@contextlib.contextmanager
def _gc_paused() -> Iterator[None]:
    """Python's cyclic garbage collector paused: a collection inside the 1 kHz loop stalls a
    step; the loop makes no reference cycles, so reference counting still frees everything."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()


def _consecutive(index: np.ndarray) -> slice:
    """``index`` as a slice (a view, not a copy, of the Jacobian's columns).

    Raises:
        ModelError: If the indices are not consecutive.
    """
    if not np.array_equal(index, np.arange(index[0], index[0] + len(index))):
        raise ModelError(
            f"the mobile manipulator's joints must be consecutive dofs, got {index.tolist()}; "
            "build it with locoman.scene.mobile_manipulator"
        )
    return slice(int(index[0]), int(index[0]) + len(index))


def replay(
    model: mujoco.MjModel, home_qpos: np.ndarray, task: ReplayTask, cfg: HqpCfg
) -> ReplayLog:
    """Run the closed loop over the whole reference; the model's timestep becomes ``cfg.dt``.

    Raises:
        SceneError: If the arm cannot reach the reference's first pose from its first base pose.
        SolverError: If a QP fails.
    """
    model.opt.timestep = cfg.dt
    qadr = np.array([model.joint(n).qposadr[0] for n in JOINTS])
    dadr = np.array([model.joint(n).dofadr[0] for n in JOINTS])
    arm_dadr = dadr[3:]
    site = model.site(EE_SITE).id
    obj_body = model.body(task.obj).id
    base_act = np.array([model.actuator(n + "_vel").id for n in BASE_JOINTS])
    arm_act = np.array([model.actuator(n + "_torque").id for n in ARM_JOINTS])
    grip_act = model.actuator("gripper").id

    rotation = grasp_orientation(task.grasp_velocity)
    data = mujoco.MjData(model)
    data.qpos[:] = start_qpos(model, task.base[0], task.ee_pos[0], rotation, qpos=home_qpos)
    mujoco.mj_forward(model, data)
    limits = joint_limits(model, cfg)
    hqp = WholeBodyHqp(
        limits,
        cfg.dt,
        data.qpos[qadr].copy(),
        cfg.kp,
        cfg.kv,
        1.0 / cfg.dt if cfg.level2_gain is None else cfg.level2_gain,
        cfg.arm_mid_range_weight,
        cfg.measured_velocity_feedback,
    )
    gravity = GravityModel(model)

    n = len(task.time_s)
    log = {
        name: np.zeros((n, 3))
        for name in ("ee_pos", "ee_vel", "ee_rot_error", "base_optimal", "base_actual", "obj_pos")
    }
    log |= {"q_star": np.zeros((n, 10)), "qdot_star": np.zeros((n, 10)), "q": np.zeros((n, 10))}
    log |= {"torque": np.zeros((n, 7)), "obj_quat_wxyz": np.zeros((n, 4))}
    log |= {"qpos": np.zeros((n, model.nq))}
    log |= {name: np.zeros(n) for name in ("gripper_closed", "level1_residual", "hqp_step_s")}
    jac = np.zeros((6, model.nv))
    xdot_desired = np.c_[task.ee_vel, np.zeros((n, 3))]  # no angular velocity
    # Views (into MjData and the Jacobian), made once: the loop below runs at 1 kHz.
    site_pos, site_rot = data.site_xpos[site], data.site_xmat[site].reshape(3, 3)
    cols = _consecutive(dadr)
    jac_pos, jac_rot, jac_cols = jac[:3], jac[3:], jac[:, cols]
    j = np.empty(jac_cols.shape)  # the arm and base columns, contiguous for DAQP
    qvel = data.qvel[cols]
    x_a = (site_pos, site_rot)
    feedback = cfg.measured_velocity_feedback
    with _gc_paused():
        start = time.perf_counter()
        for k in range(n):
            t = task.time_s[k]
            mujoco.mj_step1(model, data)
            tic = time.perf_counter()
            mujoco.mj_jacSite(model, data, jac_pos, jac_rot, site)
            np.copyto(j, jac_cols)
            x_d = (task.ee_pos[k], rotation)
            xdot_a = j @ qvel if feedback else None
            qdot = hqp.step(j, x_d, xdot_desired[k], x_a, task.base[k], xdot_a)
            log["hqp_step_s"][k] = time.perf_counter() - tic
            if xdot_a is None:  # measured for the log only, outside the controller's step
                xdot_a = j @ qvel
            log["ee_pos"][k] = site_pos
            log["ee_rot_error"][k] = rotation[:, 2] - site_rot[:, 2]

            tau = joint_impedance_torque(
                hqp.q_star[3:],
                qdot[3:],
                data.qpos[qadr[3:]],
                qvel[3:],
                cfg.joint_stiffness,
                cfg.joint_damping,
                gravity(data.qpos)[arm_dadr],
            )
            data.ctrl[base_act] = qdot[:3]
            data.ctrl[arm_act] = tau
            closed = task.grasp_time_s <= t < task.release_time_s
            data.ctrl[grip_act] = 0.0 if closed else GRIPPER_OPEN
            mujoco.mj_step2(model, data)

            log["ee_vel"][k] = xdot_a[:3]
            log["base_optimal"][k] = hqp.q_star[:3]
            log["base_actual"][k] = data.qpos[qadr[:3]]
            log["q_star"][k] = hqp.q_star
            log["qdot_star"][k] = qdot
            log["q"][k] = data.qpos[qadr]
            log["torque"][k] = data.actuator_force[arm_act]
            log["gripper_closed"][k] = float(closed)
            log["obj_pos"][k] = data.xpos[obj_body]
            log["obj_quat_wxyz"][k] = data.xquat[obj_body]
            log["qpos"][k] = data.qpos
            level1 = hqp.last_level1
            log["level1_residual"][k] = float(np.linalg.norm(level1[0] @ qdot - level1[1]))
        wall = time.perf_counter() - start
    return ReplayLog(
        time_s=task.time_s,
        ee_pos_desired=task.ee_pos,
        ee_vel_desired=task.ee_vel,
        base_learned=task.base,
        wall_s=wall,
        **log,
    )
