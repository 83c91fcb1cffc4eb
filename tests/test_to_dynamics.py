"""Centroidal dynamics and contact kinds on single-body toy problems solved by IPOPT, the
dynamics (1) through the TO's compiled kinds (:mod:`to_toys`)."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from to_toys import object_dynamics

from locoman.to.terms.contacts import (
    friction_cone_cop,
    interactive_contact,
    no_rolling,
    patch_contact,
    sinking_bound,
)
from locoman.to.terms.dynamics import rigid_body_momentum
from locoman.to.terms.kinematics import euler_rates_to_world, rpy_matrix

MASS = 5.0  # [kg]
SIZE = np.array([0.25, 0.3, 0.2])  # [m] box extents; its frame sits at the bottom face centre
INERTIA = ca.DM(np.diag(MASS / 12.0 * (SIZE[[1, 0, 0]] ** 2 + SIZE[[2, 2, 1]] ** 2)))
COM = ca.DM([0.0, 0.0, 0.5 * SIZE[2]])
DT = 0.02  # [s]


def test_falling_body_follows_semi_implicit_euler():
    """No contacts: the momentum gains m g dt per step and the body falls as (1) says."""
    q, v, z = ca.SX.sym("q", 6), ca.SX.sym("v", 6), ca.SX.sym("z", 12)
    rows = object_dynamics(q, v, z[0:6], z[6:12], [], mass=MASS, inertia=INERTIA, com=COM, dt=DT)
    step = ca.rootfinder("step", "newton", ca.Function("rows", [z, ca.vertcat(q, v)], [rows]))
    h, _ = rigid_body_momentum(q, v, MASS, INERTIA, COM)
    momentum = ca.Function("h", [q, v], [h])
    qk = np.array([0.0, 0.0, 1.0, 0.1, -0.2, 0.3])
    vk = np.array([0.5, 0.0, 0.0, 0.0, 0.0, 0.0])
    for _ in range(10):
        z_next = np.asarray(step(np.r_[qk, vk], np.r_[qk, vk])).ravel()
        q_next, v_next = z_next[0:6], z_next[6:12]
        h_gained = np.asarray(momentum(q_next, v_next) - momentum(qk, vk)).ravel()
        np.testing.assert_allclose(h_gained, [0, 0, -MASS * 9.81 * DT, 0, 0, 0], atol=1e-9)
        np.testing.assert_allclose(q_next, qk + v_next * DT, atol=1e-12)  # (1b)
        np.testing.assert_allclose(v_next[3:], 0.0, atol=1e-9)  # no torque, no turn
        qk, vk = q_next, v_next
    # Ten steps: v_z = -10 g dt, z = 1 - g dt^2 (1 + 2 + ... + 10).
    assert vk[2] == pytest.approx(-10 * 9.81 * DT)
    assert qk[2] == pytest.approx(1.0 - 9.81 * DT**2 * 55)
    assert qk[0] == pytest.approx(0.5 * DT * 10)


def _body(opti: ca.Opti, nodes: int, start: np.ndarray):
    """A free box over ``nodes`` nodes starting at rest at ``start`` (p, rpy)."""
    q, v = opti.variable(6, nodes), opti.variable(6, nodes)
    opti.subject_to(q[:, 0] == start)
    opti.subject_to(v[:, 0] == 0)
    return q, v


def _dynamics(opti, q, v, contacts_of):
    for k in range(q.shape[1] - 1):
        _, com = rigid_body_momentum(q[:, k], v[:, k], MASS, INERTIA, COM)
        rows = object_dynamics(
            q[:, k],
            v[:, k],
            q[:, k + 1],
            v[:, k + 1],
            contacts_of(k, com),
            mass=MASS,
            inertia=INERTIA,
            com=COM,
            dt=DT,
        )
        opti.subject_to(rows == 0)


def _solve(opti):
    opti.solver("ipopt", {"print_time": False}, {"print_level": 0, "sb": "yes"})
    return opti.solve()


def test_patch_contact_holds_a_box_on_the_ground():
    opti = ca.Opti()
    nodes = 6
    q, v = _body(opti, nodes, np.array([0.3, 0.1, 0.0, 0.0, 0.0, 0.4]))
    f, tau, slack = opti.variable(3, nodes), opti.variable(3, nodes), opti.variable(1, nodes)
    _dynamics(opti, q, v, lambda k, com: [(q[0:3, k], f[:, k], tau[:, k])])
    cost = 0
    for k in range(nodes):
        R = rpy_matrix(q[3:6, k])
        omega = euler_rates_to_world(q[3:6, k]) @ v[3:6, k]
        opti.subject_to(
            ca.vertcat(
                patch_contact(q[0:3, k], v[0:3, k], R, 0.0, 50.0, slack[k]), no_rolling(omega)
            )
            == 0
        )
        opti.subject_to(friction_cone_cop(f[:, k], tau[:, k], R, 0.8, 0.12, 0.15) >= 0)
        cost += 1e-6 * ca.sumsqr(ca.vertcat(f[:, k], tau[:, k])) + 1e5 * slack[k] ** 2
        cost += 1e-1 * ca.sumsqr(v[:, k])
    opti.minimize(cost)
    sol = _solve(opti)
    # The slack is a penalty, not a hard zero: the force regularisation buys a sinking of
    # micrometres, as in the paper's formulation.
    forces = sol.value(f)[:, :-1]
    np.testing.assert_allclose(forces[2], MASS * 9.81, rtol=2e-3)
    np.testing.assert_allclose(forces[:2], 0.0, atol=1e-6)
    np.testing.assert_allclose(sol.value(q)[:, -1], sol.value(q)[:, 0], atol=1e-4)


@pytest.mark.parametrize("pull", [0.5, 0.9])
def test_friction_cone_holds_a_pull_within_mu_m_g_and_not_beyond(pull):
    """A sideways pull on a box that may not slide (mu = 0.8): at 0.5 m g the ground pushes
    back with 0.5 m g; at 0.9 m g no admissible force exists and IPOPT says so."""
    opti = ca.Opti()
    nodes = 4
    q, v = _body(opti, nodes, np.zeros(6))
    f, tau, slack = opti.variable(3, nodes), opti.variable(3, nodes), opti.variable(1, nodes)
    push = ca.DM([pull * MASS * 9.81, 0.0, 0.0])
    _dynamics(
        opti,
        q,
        v,
        lambda k, com: [(q[0:3, k], f[:, k], tau[:, k]), (com, push, ca.DM.zeros(3))],
    )
    for k in range(nodes):
        R = rpy_matrix(q[3:6, k])
        omega = euler_rates_to_world(q[3:6, k]) @ v[3:6, k]
        if k > 0:  # node 0 is fixed at rest already
            opti.subject_to(
                ca.vertcat(
                    patch_contact(q[0:3, k], v[0:3, k], R, 0.0, 50.0, slack[k]), no_rolling(omega)
                )
                == 0
            )
        opti.subject_to(slack[k] == 0)
        opti.subject_to(friction_cone_cop(f[:, k], tau[:, k], R, 0.8, 0.12, 0.15) >= 0)
    opti.minimize(ca.sumsqr(f))
    if pull < 0.8:
        sol = _solve(opti)
        np.testing.assert_allclose(sol.value(f)[0, :-1], -pull * MASS * 9.81, rtol=1e-6)
        return
    with pytest.raises(RuntimeError):
        _solve(opti)
    assert opti.stats()["return_status"] == "Infeasible_Problem_Detected"


def test_interactive_contact_stacks_two_boxes_with_equal_and_opposite_forces():
    """Box B rests on box A, which rests on the ground: the ground carries 2 m g, the
    interface m g. The interface's one wrench acts on B and, with the opposite sign, on A
    (Newton's third law (6), as the TO's wrench shares hold it)."""
    opti = ca.Opti()
    nodes = 5
    top = float(SIZE[2])
    qa, va = _body(opti, nodes, np.zeros(6))
    qb, vb = _body(opti, nodes, np.array([0.0, 0.0, top, 0.0, 0.0, 0.0]))
    fg, tg, sg = opti.variable(3, nodes), opti.variable(3, nodes), opti.variable(1, nodes)
    fb, tb = opti.variable(3, nodes), opti.variable(3, nodes)  # on B, from A
    sab = opti.variable(3, nodes)
    top_of_a = [qa[0:3, k] + rpy_matrix(qa[3:6, k]) @ ca.DM([0, 0, top]) for k in range(nodes)]
    _dynamics(
        opti,
        qa,
        va,
        lambda k, com: [(qa[0:3, k], fg[:, k], tg[:, k]), (top_of_a[k], fb[:, k], tb[:, k], -1.0)],
    )
    _dynamics(opti, qb, vb, lambda k, com: [(qb[0:3, k], fb[:, k], tb[:, k])])
    cost = 0
    for k in range(nodes):
        Ra, Rb = rpy_matrix(qa[3:6, k]), rpy_matrix(qb[3:6, k])
        wa = euler_rates_to_world(qa[3:6, k]) @ va[3:6, k]
        wb = euler_rates_to_world(qb[3:6, k]) @ vb[3:6, k]
        opti.subject_to(
            ca.vertcat(patch_contact(qa[0:3, k], va[0:3, k], Ra, 0.0, 50.0, sg[k]), no_rolling(wa))
            == 0
        )
        opti.subject_to(friction_cone_cop(fg[:, k], tg[:, k], Ra, 0.8, 0.12, 0.15) >= 0)
        opti.subject_to(
            interactive_contact(qb[0:3, k], top_of_a[k], sab[:, k], Rb, Ra, wb, wa) == 0
        )
        opti.subject_to(friction_cone_cop(fb[:, k], tb[:, k], Rb, 0.8, 0.12, 0.15) >= 0)
        cost += 1e-6 * ca.sumsqr(ca.vertcat(fg[:, k], tg[:, k], fb[:, k], tb[:, k]))
        cost += 1e8 * (sg[k] ** 2 + ca.sumsqr(sab[:, k])) + 1e-1 * ca.sumsqr(
            ca.vertcat(va[:, k], vb[:, k])
        )
    opti.minimize(cost)
    sol = _solve(opti)
    np.testing.assert_allclose(sol.value(fg)[2, :-1], 2 * MASS * 9.81, rtol=2e-3)
    np.testing.assert_allclose(sol.value(fb)[2, :-1], MASS * 9.81, rtol=2e-3)
    # A feels -f_B, -tau_B at the interface: its dynamics hold with that wrench written out.
    q_a, v_a, f_b, t_b = sol.value(qa), sol.value(va), sol.value(fb), sol.value(tb)
    for k in range(nodes - 1):
        top = sol.value(top_of_a[k])
        contacts = [
            (q_a[0:3, k], sol.value(fg)[:, k], sol.value(tg)[:, k]),
            (top, -f_b[:, k], -t_b[:, k]),
        ]
        rows = object_dynamics(
            q_a[:, k],
            v_a[:, k],
            q_a[:, k + 1],
            v_a[:, k + 1],
            contacts,
            mass=MASS,
            inertia=INERTIA,
            com=COM,
            dt=DT,
        )
        np.testing.assert_allclose(np.asarray(ca.DM(rows)).ravel(), 0.0, atol=1e-8)


@pytest.mark.parametrize("bounded", [False, True])
def test_a_sole_rising_at_touchdown_sinks_by_its_velocity_unless_its_depth_is_bounded(bounded):
    """issue 48: (2a) puts r_z - z_g at -s - r_dot_z / k_z; with |s| <= 4 mm a sole moving up
    at 0.15 m/s (k_z = 50/s) reaches 7 mm below its surface, the S1 step-up's failure. The
    sinking bound holds the point itself within 4 mm."""
    opti = ca.Opti()
    r, r_dot, slack = opti.variable(3), opti.variable(3), opti.variable()
    opti.subject_to(patch_contact(r, r_dot, ca.DM.eye(3), 0.2, 50.0, slack) == 0)
    opti.subject_to(opti.bounded(-0.004, slack, 0.004))
    opti.subject_to(r_dot[2] == 0.15)
    if bounded:
        opti.subject_to(sinking_bound(r, 0.2, 0.004) >= 0)
    opti.minimize(r[2] + 1e-3 * ca.sumsqr(r_dot[0:2]))
    depth = 0.2 - _solve(opti).value(r[2])  # [m] below the surface
    assert depth == pytest.approx(0.004 if bounded else 0.007, abs=1e-6)
