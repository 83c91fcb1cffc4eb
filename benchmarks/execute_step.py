"""Benchmark of the execution controller's 1 kHz step: the inverse-dynamics QP and MuJoCo.

Usage: python benchmarks/execute_step.py [--scenarios tiny ...] [--repeats 3]
       [--out benchmarks/results/execute_step.json]
Needs each scenario's scene and solve outputs (`dvc repro solve@tiny`).

Per scenario, ``--repeats`` runs of the first :data:`STEPS` control steps (the settling, 1 s
at the defaults, and the first steps): the controller's step (Pinocchio's terms, the QP's
assembly and DAQP's solve) and MuJoCo's step, medians and 99th percentiles over the steps,
then the median over the runs. The QPs of the last run are solved again by DAQP and, where it
is installed (it is not a dependency), by proxsuite's dense solver, cold and warm started. And
how far the plan's centroidal dynamics, sampled as the reference samples it, lie from the
TO's wrenches, and what the plan asks of the G1's joints and soles, its two-handed carries
also with the least grip friction allows (:func:`least_grip`).
"""

from __future__ import annotations

import dataclasses
import time

import daqp
import mujoco
import numpy as np
import pinocchio as pin
from common import run

from locoman.artifacts import read_npz
from locoman.config import load_params
from locoman.execute import controller as controller_module
from locoman.execute.model import PALMS, SOLES, execution_model, torque_limits
from locoman.execute.pipeline import execution_setup
from locoman.execute.reference import build_reference
from locoman.execute.simulate import execute
from locoman.retarget.robot import contact_frames
from locoman.scene.g1 import G1_JOINT_NAMES
from locoman.stage import DATA_DIR
from locoman.to.io import TRAJECTORY, TRAJECTORY_FILE
from locoman.to.terms.actuation import ARM_JOINTS

STEPS = 2000


def _recording_solve(recorded: list, solve):
    """``solve`` (DAQP's), keeping a copy of every QP it is given in ``recorded``."""

    def recording(*args):
        recorded.append(tuple(np.array(a, copy=True) for a in args))
        return solve(*args)

    return recording


def _mj_step_times(model: mujoco.MjModel, executed) -> np.ndarray:
    """MuJoCo's step [s] from each recorded state with its torques."""
    data = mujoco.MjData(model)
    out = np.zeros(len(executed.time))
    for i in range(len(executed.time)):
        data.qpos[:] = executed.qpos[i]
        mujoco.mj_forward(model, data)
        data.ctrl[:] = executed.tau[i]
        tic = time.perf_counter()
        mujoco.mj_step(model, data)
        out[i] = time.perf_counter() - tic
    return out


def _daqp_times(qps: list) -> np.ndarray:
    out = []
    for qp in qps:
        tic = time.perf_counter()
        daqp.solve(*qp)  # restored after the runs
        out.append(time.perf_counter() - tic)
    return np.array(out)


def _proxsuite_times(qps: list) -> dict | None:
    """Cold (a new dense QP each step) and warm (the previous step's solution as the start,
    same size) solve times [s] of proxsuite's dense backend, or None without proxsuite."""
    try:
        import proxsuite
    except ImportError:
        return None
    cold, warm, previous = [], [], None
    for hessian, gradient, a, upper, lower, sense in qps:
        eq = sense == controller_module._EQUALITY
        n, n_eq, n_in = len(gradient), int(eq.sum()), int((~eq).sum())
        args = (hessian, gradient, a[eq], upper[eq], a[~eq], lower[~eq], upper[~eq])
        tic = time.perf_counter()
        qp = proxsuite.proxqp.dense.QP(n, n_eq, n_in)
        qp.init(*args)
        qp.solve()
        cold.append(time.perf_counter() - tic)
        if previous is not None and previous.model.dim == n and previous.model.n_eq == n_eq:
            tic = time.perf_counter()
            previous.update(*args)
            previous.solve(previous.results.x, previous.results.y, previous.results.z)
            warm.append(time.perf_counter() - tic)
        previous = qp
    return {
        "version": proxsuite.__version__,
        "cold_median_ms": float(np.median(cold) * 1e3),
        "warm_median_ms": float(np.median(warm) * 1e3) if warm else None,
    }


def centroidal_residuals(ref) -> dict:
    """How far the reference's centroidal dynamics are from the TO's wrenches it carries:
    the momentum's rate (Pinocchio, at the samples' q, v, a) minus gravity and every contact
    wrench about the centre of mass, median and 90th percentile of each component's size
    over the motion [N, N m]."""
    model = execution_model()
    data = model.createData()
    mass = pin.computeTotalMass(model)
    weight = np.array([0.0, 0.0, -9.81 * mass])
    moving = (ref.time > ref.time[0] + load_params().execute.settle_s) & (
        ref.time < ref.time[-1] - load_params().execute.hold_s
    )
    rows = []
    for i in np.flatnonzero(moving)[::2]:
        pin.computeCentroidalMomentumTimeVariation(model, data, ref.q[i], ref.v[i], ref.a[i])
        pin.framesForwardKinematics(model, data, ref.q[i])
        com = pin.centerOfMass(model, data, ref.q[i])
        force, moment = weight.copy(), np.zeros(3)
        contacts = [(SOLES[k], ref.foot_wrench[i, k]) for k in range(2) if ref.foot_contact[i, k]]
        contacts += [
            (PALMS[k], ref.hand_wrench[i, k]) for k in range(2) if ref.hand_object[i, k] >= 0
        ]
        for frame, wrench in contacts:
            point = data.oMf[model.getFrameId(frame)].translation
            force += wrench[:3]
            moment += np.cross(point - com, wrench[:3]) + wrench[3:]
        rows.append(np.r_[data.dhg.linear - force, data.dhg.angular - moment])
    size = np.abs(np.array(rows))
    return {
        "force_median_n": float(np.median(size[:, :3])),
        "force_p90_n": float(np.percentile(size[:, :3], 90)),
        "moment_median_nm": float(np.median(size[:, 3:])),
        "moment_p90_nm": float(np.percentile(size[:, 3:], 90)),
    }


def plan_demands(ref, half_extents: np.ndarray, joints: tuple[str, ...] = G1_JOINT_NAMES) -> dict:
    """What the plan asks of the G1: each joint's largest torque by inverse dynamics at the
    reference with the TO's wrenches, as a fraction of its limit (the five largest of
    ``joints``), and the
    median of each stance CoP's distance from the sole's centre as a fraction of its half
    length (x) and half width (y), over the motion."""
    model = execution_model()
    data = model.createData()
    limits = torque_limits(model)
    world = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
    cfg = load_params().execute
    moving = (ref.time > ref.time[0] + cfg.settle_s) & (ref.time < ref.time[-1] - cfg.hold_s)
    worst, cop = np.zeros(len(limits)), []
    for i in np.flatnonzero(moving)[::2]:
        tau = pin.rnea(model, data, ref.q[i], ref.v[i], ref.a[i]).copy()
        pin.computeJointJacobians(model, data, ref.q[i])
        pin.updateFramePlacements(model, data)
        for frames, wrenches, on in (
            (SOLES, ref.foot_wrench[i], ref.foot_contact[i]),
            (PALMS, ref.hand_wrench[i], ref.hand_object[i] >= 0),
        ):
            for frame, wrench, touching in zip(frames, wrenches, on, strict=True):
                if not touching:
                    continue
                fid = model.getFrameId(frame)
                tau -= pin.getFrameJacobian(model, data, fid, world).T @ wrench
                if frame in SOLES and wrench[2] > 50.0:
                    R = data.oMf[fid].rotation
                    f, m = R.T @ wrench[:3], R.T @ wrench[3:]
                    cop.append(
                        [abs(m[1] / f[2]) / half_extents[0], abs(m[0] / f[2]) / half_extents[1]]
                    )
        worst = np.maximum(worst, np.abs(tau[6:]) / limits)
    among = np.array([name in joints for name in G1_JOINT_NAMES])
    order = np.argsort(-np.where(among, worst, -1.0))[:5]
    median = np.median(np.array(cop), axis=0)
    return {
        "torque_fraction_max": {G1_JOINT_NAMES[j]: float(worst[j]) for j in order},
        "cop_fraction_median": {"x": float(median[0]), "y": float(median[1])},
    }


def least_grip(ref, friction: float):
    """``ref`` with each two-handed carry's hand wrenches replaced by the least a friction
    grip needs: the plan's net force of the object on the hands shared equally, f_k = f/2 -
    s n_k, with n_k palm k's normal into the object and s >= 0 the least common squeeze that
    puts both palms inside their cones, |f_t| <= mu f_n; no moments (the TO's split puts
    opposing shears of up to 25 N on tiny's palms). For palms facing each other (n_l = -n_r)
    the squeezes cancel and the net force is the plan's."""
    wrench = ref.hand_wrench.copy()
    if friction <= 0.0:  # no objects
        return ref
    both = (
        (ref.hand_object[:, 0] >= 0)
        & (ref.hand_object[:, 0] == ref.hand_object[:, 1])
        & (np.abs(wrench).sum(axis=2) > 0).all(axis=1)
    )
    for i in np.flatnonzero(both):
        share = wrench[i, :, :3].sum(axis=0) / 2
        normals = [ref.frames[frame].rotation[i, :, 2] for frame in PALMS]
        squeeze = 0.0
        for n in normals:
            push = -share @ n  # the shared load pushing the palm back [N]
            need = np.linalg.norm(share + push * n) / friction
            squeeze = max(squeeze, need - push)
        for k, n in enumerate(normals):
            wrench[i, k] = np.r_[share - squeeze * n, np.zeros(3)]
    return dataclasses.replace(ref, hand_wrench=wrench)


def measure(scenario: str, repeats: int) -> dict:
    cfg = load_params().execute
    root = DATA_DIR / scenario
    traj = read_npz(root / "solve" / TRAJECTORY_FILE, TRAJECTORY)
    names = [str(name) for name in traj["object_names"]]
    friction = float(traj["floor_friction"])
    ref, model = execution_setup(root / "scene", traj, cfg)
    runs, qps = [], []
    for r in range(repeats):
        recorded: list = []
        original = controller_module.daqp.solve
        controller_module.daqp.solve = _recording_solve(recorded, original)
        try:
            tic = time.perf_counter()
            executed = execute(model, ref, names, cfg, friction, STEPS)
            wall = time.perf_counter() - tic
        finally:
            controller_module.daqp.solve = original
        qp = executed.solve_time_s
        mj = _mj_step_times(model, executed)
        count = len(executed.time)
        runs.append(
            {
                "steps": count,
                "controller_median_ms": float(np.median(qp) * 1e3),
                "controller_p99_ms": float(np.percentile(qp, 99) * 1e3),
                "mujoco_step_median_ms": float(np.median(mj) * 1e3),
                "step_median_ms": float(np.median(qp + mj) * 1e3),
                "step_p99_ms": float(np.percentile(qp + mj, 99) * 1e3),
                "loop_ms_per_step": wall / count * 1e3,
            }
        )
        if r == repeats - 1:
            qps = recorded
    keys = runs[0].keys()
    out = {key: float(np.median([run_[key] for run_ in runs])) for key in keys}
    daqp_times = _daqp_times(qps)
    # What the TO's plan itself asks (its centre of mass and wrenches, not the LIPM's).
    plan = build_reference(traj, cfg.timestep_s, cfg.settle_s, cfg.hold_s)
    out["reference_vs_to_wrenches"] = centroidal_residuals(plan)
    half = contact_frames().sole_half_extents
    out["plan_demands"] = plan_demands(plan, half)
    # The same motion with the least grip friction allows: what no controller can lower.
    mu = float(np.max(traj["object_friction"], initial=0.0))
    out["plan_demands"]["least_grip_arm_torque_fraction_max"] = plan_demands(
        least_grip(plan, mu), half, (*ARM_JOINTS[0], *ARM_JOINTS[1])
    )["torque_fraction_max"]
    out["qp_solvers"] = {
        "qps": len(qps),
        "unknowns_median": float(np.median([len(q[1]) for q in qps])),
        "daqp": {"median_ms": float(np.median(daqp_times) * 1e3)},
        "proxsuite_dense": _proxsuite_times(qps),
    }
    return out


def summary(result: dict) -> str:
    solvers = result["qp_solvers"]
    prox = solvers["proxsuite_dense"]
    prox_text = (
        f", proxsuite {prox['cold_median_ms']:.2f} ms cold / {prox['warm_median_ms']:.2f} warm"
        if prox
        else ""
    )
    return (
        f"step {result['step_median_ms']:.2f} ms median ({result['step_p99_ms']:.2f} p99): "
        f"controller {result['controller_median_ms']:.2f}, MuJoCo "
        f"{result['mujoco_step_median_ms']:.2f}; QP alone: DAQP "
        f"{solvers['daqp']['median_ms']:.2f} ms{prox_text}"
    )


if __name__ == "__main__":
    run(__doc__, "benchmarks/results/execute_step.json", measure, summary)
