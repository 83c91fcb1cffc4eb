"""The execution controller (locoman.execute): its QP against Pinocchio and the contact model,
its reference against the TO's nodes, and a short executed segment in MuJoCo's physics."""

from __future__ import annotations

import dataclasses

import mujoco
import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import linprog

from locoman.config.execute import ExecuteCfg
from locoman.execute.contacts import local_wrench_rows, world_wrench_rows, wrench_bounds
from locoman.execute.controller import InverseDynamicsQp
from locoman.execute.grasp import GraspMonitor
from locoman.execute.model import PALMS, SOLES, execution_model, torque_limits
from locoman.execute.reference import build_reference, interpolate_nodes, pin_state
from locoman.execute.simulate import StateMap, execute, execution_mjmodel
from locoman.retarget.robot import contact_frames
from locoman.scene import g1
from locoman.scene.rotations import rpy_to_matrix
from locoman.sim.evaluate import cone_violation

HALF = np.array([0.09, 0.035])  # the G1's sole [m]
MU = 0.7
WORLD = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


def feet_fixed(q35: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """``q35`` with its leg joints moved so both soles are where ``reference`` has them
    (Newton's method on the soles' poses; the legs are 6 joints each)."""
    model = execution_model()
    data = model.createData()
    frames = [model.getFrameId(name) for name in SOLES]
    pin.framesForwardKinematics(model, data, g1.q35_to_pin(reference))
    targets = [data.oMf[f].copy() for f in frames]
    q = g1.q35_to_pin(q35)
    for _ in range(20):
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        errors, rows = [], []
        for frame, target in zip(frames, targets, strict=True):
            errors.append(pin.log6(data.oMf[frame].actInv(target)).vector)
            rows.append(pin.getFrameJacobian(model, data, frame, pin.ReferenceFrame.LOCAL))
        jac = np.vstack(rows)[:, 6:18]  # the legs' twelve joints
        dq = np.zeros(model.nv)
        dq[6:18] = np.linalg.solve(jac, np.concatenate(errors))
        q = pin.integrate(model, q, dq)
    return g1.pin_to_q35(q)


def standing_trajectory(nodes: int = 11, dt: float = 0.1, sway_m: float = 0.0) -> dict:
    """A TO trajectory of the G1 standing on both soles, its pelvis swaying ``sway_m`` [m]
    sideways and back, the legs bending so that the soles stay put."""
    q0 = g1.standing_q35()
    q = np.repeat(q0[None], nodes, axis=0)
    q[:, 1] += sway_m * np.sin(np.linspace(0.0, np.pi, nodes)) ** 2
    q = np.array([feet_fixed(qk, q0) for qk in q])
    v = np.zeros_like(q)
    v[1:] = np.diff(q, axis=0) / dt
    return {
        "dt": np.full(nodes, dt),
        "q": q,
        "v": v,
        "feet_contact": np.ones((nodes, 2), bool),
        "foot_wrench": np.zeros((nodes, 2, 6)),
        "hand_object": np.full((nodes, 2), -1),
        "hand_wrench": np.zeros((nodes, 2, 6)),
        "object_q": np.zeros((nodes, 0, 6)),
        "support_kind": np.zeros((nodes, 0), dtype=str),
    }


def floor_model(cfg: ExecuteCfg) -> mujoco.MjModel:
    spec = g1.g1_mjspec()
    floor = spec.worldbody.add_geom()
    floor.type = mujoco.mjtGeom.mjGEOM_PLANE
    floor.size = [0.0, 0.0, 0.05]
    return execution_mjmodel(spec, cfg)


CORNERS = np.array([[sx * HALF[0], sy * HALF[1], 0.0] for sx in (1, -1) for sy in (1, -1)])


def corner_wrench(forces: np.ndarray) -> np.ndarray:
    """(6,) the wrench at the sole's centre of four corner forces (4, 3), sole frame."""
    return np.r_[forces.sum(axis=0), np.cross(CORNERS, forces).sum(axis=0)]


@given(
    normal=st.lists(st.floats(0.0, 200.0), min_size=4, max_size=4),
    tangent=st.lists(st.floats(-1.0, 1.0), min_size=8, max_size=8),
    rpy=st.lists(st.floats(-0.3, 0.3), min_size=3, max_size=3),
)
@settings(max_examples=200, deadline=None)
def test_every_wrench_four_corners_can_push_is_inside_the_cone(normal, tangent, rpy):
    """Corner forces inside their friction pyramids make a wrench the rows accept, in any
    sole orientation (the rows are in world axes)."""
    fz = np.array(normal)
    forces = np.column_stack([MU * fz * np.array(tangent[:4]), MU * fz * np.array(tangent[4:]), fz])
    R = rpy_to_matrix(np.array(rpy))
    w_local = corner_wrench(forces)
    w = np.r_[R @ w_local[:3], R @ w_local[3:]]
    rows = world_wrench_rows(local_wrench_rows(MU, HALF), R)
    assert np.all(rows @ w <= wrench_bounds(0.0) + 1e-6 * (1.0 + fz.sum()))


@given(
    w=st.lists(st.floats(-1.0, 1.0), min_size=6, max_size=6),
    rpy=st.lists(st.floats(-0.3, 0.3), min_size=3, max_size=3),
)
@settings(max_examples=100, deadline=None)
def test_the_tos_exact_sole_cone_is_the_executions(w, rpy):
    """``solve.contact.sole_cone = exact``: the TO's rows (>= 0) are the execution's rows
    (<= 0) but the loading one, so a plan's sole wrench is one the QP can reproduce; the
    paper's (3c) is looser (it accepts a wrench the corners cannot push)."""
    from locoman.to.terms.contacts import foot_cone_kind

    R = rpy_to_matrix(np.array(rpy))
    wrench = np.array(w) * np.array([80.0, 80.0, 0.0, 10.0, 20.0, 15.0])
    wrench[2] = 200.0 + 200.0 * w[2]
    x = np.r_[wrench, R.ravel(order="F")]
    to_rows = np.array(foot_cone_kind(True).term.function(x, np.r_[MU, HALF])[0]).ravel()
    qp_rows = world_wrench_rows(local_wrench_rows(MU, HALF), R)[:-1] @ wrench
    np.testing.assert_allclose(np.sort(to_rows), np.sort(-qp_rows), atol=1e-9)


def test_the_papers_yaw_bound_accepts_a_wrench_the_sole_cannot_carry():
    from locoman.to.terms.contacts import foot_cone_kind

    fz = 300.0  # on the heel's edge, twisting as far as (3c) allows
    wrench = np.array([0.0, 0.0, fz, 0.0, -HALF[0] * fz, MU * HALF.max() * fz])
    x = np.r_[wrench, np.eye(3).ravel()]
    paper = np.array(foot_cone_kind(False).term.function(x, np.r_[MU, HALF])[0]).ravel()
    exact = np.array(foot_cone_kind(True).term.function(x, np.r_[MU, HALF])[0]).ravel()
    assert paper.min() >= -1e-9 and exact.min() < -1.0


def test_every_wrench_inside_the_cone_is_pushed_by_four_corners():
    """The converse: a wrench the rows accept is a sum of corner forces in their pyramids
    (a linear program finds them), so the rows are the sole's exact contact wrench cone."""
    rng = np.random.default_rng(0)
    rows = local_wrench_rows(MU, HALF)
    equality = np.zeros((6, 12))
    for i, corner in enumerate(CORNERS):
        equality[:3, 3 * i : 3 * i + 3] = np.eye(3)
        equality[3:, 3 * i : 3 * i + 3] = pin.skew(corner)
    pyramid = []
    for i in range(4):
        for axis in (0, 1):
            for sign in (1.0, -1.0):
                row = np.zeros(12)
                row[3 * i + axis], row[3 * i + 2] = sign, -MU
                pyramid.append(row)
        row = np.zeros(12)
        row[3 * i + 2] = -1.0
        pyramid.append(row)
    tested = 0
    while tested < 100:
        w = rng.normal(0.0, 1.0, 6) * np.array([60.0, 60.0, 0.0, 5.0, 10.0, 8.0])
        w[2] = rng.uniform(10.0, 400.0)
        if np.any(rows @ w > 0.0):
            continue
        tested += 1
        found = linprog(
            np.zeros(12), A_ub=np.array(pyramid), b_ub=np.zeros(len(pyramid)),
            A_eq=equality, b_eq=w, bounds=[(None, None)] * 12,
        )  # fmt: skip
        assert found.status == 0, w


def test_the_tos_yaw_bound_allows_what_the_corners_cannot_carry():
    """Paper A's (3c), |tau_z| <= mu max(X, Y) f_z, accepts a yaw moment on a sole loaded
    at its heel that no corner forces can make (the foot spins in MuJoCo)."""
    fz = 500.0
    w = np.array([0.0, 0.0, fz, 0.0, 0.8 * HALF[0] * fz, 0.9 * MU * HALF[0] * fz])
    assert cone_violation(w[:3], w[3:], np.eye(3), MU, HALF) == 0.0
    assert np.any(local_wrench_rows(MU, HALF) @ w > 0.0)


def test_the_base_twist_derivative_matches_finite_differences():
    """pin_state's a is the derivative of its v along a path of the TO's layout."""
    rng = np.random.default_rng(0)
    q0, q1, q2 = (rng.normal(0, 0.3, 35) for _ in range(3))

    def path(t):  # a smooth path and its two derivatives
        return q0 + t * q1 + t**2 * q2, q1 + 2 * t * q2, 2 * q2

    t, h = 0.4, 1e-6
    _, v_plus, _ = pin_state(*path(t + h))
    _, v_minus, _ = pin_state(*path(t - h))
    _, _, a = pin_state(*path(t))
    np.testing.assert_allclose(a, (v_plus - v_minus) / (2 * h), atol=1e-6)


def test_the_reference_passes_through_every_node():
    traj = standing_trajectory(sway_m=0.03)
    times = np.r_[0.0, np.cumsum(traj["dt"][:-1])]
    q, _, _ = interpolate_nodes(traj, times)
    np.testing.assert_allclose(q, traj["q"], atol=1e-12)


def test_the_qp_solution_obeys_the_dynamics_the_cones_and_the_torque_limits():
    """At a perturbed standing state, the QP's (a, w, tau) satisfies Pinocchio's inverse
    dynamics, M a + h = S^T tau + J^T w, each stance wrench its rows, tau its limits."""
    cfg = ExecuteCfg()
    model = execution_model()
    data = model.createData()
    ref = build_reference(standing_trajectory(), cfg.timestep_s, cfg.settle_s, cfg.hold_s)
    controller = InverseDynamicsQp(model, cfg, HALF, MU)
    rng = np.random.default_rng(1)
    q = pin.integrate(model, ref.q[0], rng.normal(0, 0.02, model.nv))
    v = rng.normal(0, 0.2, model.nv)
    command = controller.step(q, v, ref, 0)
    tau_full = pin.rnea(model, data, q, v, command.a).copy()
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)
    rows = local_wrench_rows(MU, HALF)
    for k, name in enumerate(SOLES):
        frame = model.getFrameId(name)
        tau_full -= pin.getFrameJacobian(model, data, frame, WORLD).T @ command.foot_wrench[k]
        C = world_wrench_rows(rows, data.oMf[frame].rotation)
        assert np.all(C @ command.foot_wrench[k] <= wrench_bounds(cfg.min_normal_force_n) + 1e-6)
    np.testing.assert_allclose(tau_full[:6], 0.0, atol=1e-6)
    np.testing.assert_allclose(tau_full[6:], command.tau, atol=1e-6)
    assert np.all(np.abs(command.tau) <= torque_limits(model) + 1e-9)
    # The stance feet's accelerations are the contact constraint's: J a + J_dot v = -kd J v.
    pin.forwardKinematics(model, data, q, v, command.a)
    for name in SOLES:
        frame = model.getFrameId(name)
        acc = pin.getFrameClassicalAcceleration(model, data, frame, WORLD).vector
        vel = pin.getFrameVelocity(model, data, frame, WORLD).vector
        np.testing.assert_allclose(acc, -cfg.contact_kd * vel, atol=1e-6)


@pytest.fixture(scope="module")
def swaying():
    """0.3 s standing, then a 5 cm sway of the pelvis and back over 1 s, in MuJoCo: the
    controller tracks the plan's centre of mass (``build_reference``)."""
    cfg = dataclasses.replace(ExecuteCfg(), settle_s=0.3, hold_s=0.1)
    traj = standing_trajectory(sway_m=0.05)
    ref = build_reference(traj, cfg.timestep_s, cfg.settle_s, cfg.hold_s)
    model = floor_model(cfg)
    return model, ref, execute(model, ref, [], cfg, MU), cfg


def test_a_short_executed_segment_stays_up_and_tracks(swaying):
    _, ref, executed, _ = swaying
    assert executed.completed, executed.stopped
    assert len(executed.time) == len(ref)
    assert executed.q[:, 2].min() > 0.7
    base_error = np.abs(executed.q[:, :3] - ref.q[:, :3]).max()
    assert base_error < 0.01, base_error
    assert np.all(executed.stance)


def test_the_executed_wrenches_are_inside_the_qps_cones_and_mujoco_carries_them(swaying):
    """Every step's stance wrench satisfies its rows, and MuJoCo's floor pushes the soles
    with the QP's total normal force: within 15 % at every step checked once settled (12 %
    where the sway turns back), 2 % at the median (the floor is soft: its force follows the
    QP's with a lag)."""
    model, _, executed, _ = swaying
    rows = local_wrench_rows(MU, HALF)
    pin_model = execution_model()
    pin_data = pin_model.createData()
    states = StateMap.of(model, [])
    data = mujoco.MjData(model)
    feet = {model.body(link).id for link in g1.FOOT_LINKS}
    errors = []
    for i in range(0, len(executed.time), 25):
        pin.framesForwardKinematics(pin_model, pin_data, executed.q[i])
        for k, name in enumerate(SOLES):
            R = pin_data.oMf[pin_model.getFrameId(name)].rotation
            w = executed.foot_wrench[i, k]
            assert np.all(world_wrench_rows(rows, R) @ w <= wrench_bounds(5.0) + 1e-6)
        if executed.time[i] < 0.1:
            continue
        data.qpos[:] = executed.qpos[i]
        data.qvel[:] = 0.0
        states.set_pin_state(data, executed.q[i], executed.v[i])
        data.ctrl[:] = executed.tau[i]
        mujoco.mj_forward(model, data)
        normal = 0.0
        for c in range(data.ncon):
            contact = data.contact[c]
            if {model.geom_bodyid[contact.geom1], model.geom_bodyid[contact.geom2]} & feet:
                force = np.zeros(6)
                mujoco.mj_contactForce(model, data, c, force)
                normal += force[0]
        planned = executed.foot_wrench[i, :, 2].sum()
        errors.append(abs(normal - planned) / planned)
    assert max(errors) <= 0.15, max(errors)
    assert np.median(errors) <= 0.02, np.median(errors)


def test_the_palms_and_soles_are_the_tos_contact_points():
    model = execution_model()
    data = model.createData()
    q = g1.q35_to_pin(g1.standing_q35())
    pin.framesForwardKinematics(model, data, q)
    frames = contact_frames()
    for name, link in zip(SOLES + PALMS, g1.FOOT_LINKS + g1.HAND_LINKS, strict=True):
        pose = data.oMf[model.getFrameId(link)]
        offset = frames.sole[name] if name in SOLES else frames.palm[name]
        expected = pose.rotation @ offset + pose.translation
        np.testing.assert_allclose(data.oMf[model.getFrameId(name)].translation, expected)
    # Standing: the soles on the floor.
    for name in SOLES:
        assert abs(data.oMf[model.getFrameId(name)].translation[2]) < 1e-6


def test_the_grasp_monitor_says_when_a_holding_hand_lets_go():
    """A box in the left palm: held while it touches, lost ``grace`` steps after it is
    taken away, and a new hold starts afresh; the right hand holds nothing, loses nothing."""
    spec = g1.g1_mjspec()
    box = spec.worldbody.add_body()
    box.name = "box"
    box.add_freejoint()
    geom = box.add_geom()
    geom.type = mujoco.mjtGeom.mjGEOM_BOX
    geom.size = [0.03, 0.03, 0.03]
    model = execution_mjmodel(spec, ExecuteCfg())
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    hand = model.body(g1.HAND_LINKS[0]).id
    palm = next(
        data.geom_xpos[g].copy()
        for g in range(model.ngeom)
        if model.geom_bodyid[g] == hand and model.geom_contype[g]
    )
    adr = model.joint(model.body("box").jntadr[0]).qposadr[0]
    data.qpos[adr : adr + 3] = palm
    mujoco.mj_forward(model, data)
    monitor = GraspMonitor.of(model, ["box"], grace_s=0.003, timestep_s=0.001)
    plan = np.array([0, -1])
    assert monitor.update(model, data, plan) == []
    data.qpos[adr : adr + 3] = palm + np.array([0.0, 0.0, 1.0])
    mujoco.mj_forward(model, data)
    assert [monitor.update(model, data, plan) for _ in range(4)] == [[], [], [], [0]]
    assert monitor.update(model, data, plan) == []  # lost once per hold
    assert monitor.update(model, data, np.array([-1, -1])) == []
    assert not monitor.lost.any()


def test_the_palms_resist_a_twist_only_when_asked():
    """``execution_mjmodel``'s ``palm_torsion_m``: the palms' collision geoms get MuJoCo's
    torsional friction (condim 4), nothing else changes."""
    plain = execution_mjmodel(g1.g1_mjspec(), ExecuteCfg())
    twisting = execution_mjmodel(g1.g1_mjspec(), ExecuteCfg(), palm_torsion_m=0.02)
    hands = {plain.body(link).id for link in g1.HAND_LINKS}
    palms = [
        g for g in range(plain.ngeom) if plain.geom_bodyid[g] in hands and plain.geom_contype[g]
    ]
    others = [g for g in range(plain.ngeom) if g not in palms]
    assert len(palms) == 2
    np.testing.assert_array_equal(twisting.geom_condim[palms], 4)
    np.testing.assert_allclose(twisting.geom_friction[palms, 1], 0.02)
    np.testing.assert_array_equal(twisting.geom_condim[others], plain.geom_condim[others])
    np.testing.assert_array_equal(twisting.geom_friction[others], plain.geom_friction[others])
