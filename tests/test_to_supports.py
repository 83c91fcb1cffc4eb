"""The support contact kinds on rigid bodies alone, without the robot: a trolley's chassis
(7a), (7b); a box riding on a moving platform (4)-(6) with (3); a box resting on a box
resting on the floor, whose contact forces balance.

Each toy is a small multiple-shooting problem written with the TO's own pieces: the rigid
body dynamics (1) of :mod:`locoman.to.terms.dynamics` and the kinds of
:mod:`locoman.to.terms.supports`, solved by IPOPT for the support wrenches (minimal in
norm) and the motion.
"""

from __future__ import annotations

import dataclasses

import casadi as ca
import numpy as np
import pytest
from to_toys import object_dynamics

from locoman.to.problem.objects import ObjectModel
from locoman.to.terms.kinematics import euler_rates_to_world, rpy_matrix
from locoman.to.terms.supports import (
    BodyFrame,
    Chassis,
    OnObject,
    Support,
    SupportContact,
    Surface,
    facing_same_way,
    turn_about_normal,
)

DT = 0.05  # [s]
G = 9.81  # [m/s^2]
TROLLEY = dataclasses.replace(
    ObjectModel.box("trolley", np.array([0.8, 0.5, 0.55]), 12.0, 0.5),
    half_extents=np.array([0.35, 0.2]),
    solid=False,
    prehensile=True,
    rear_axle_x=-0.35,
)
BOX = ObjectModel.box("box", np.array([0.3, 0.3, 0.2]), 5.0, 0.8)


@dataclasses.dataclass
class Body:
    """One body of a toy: its model, support, start pose (p, rpy) and, optionally, a
    prescribed motion (a function of time -> (p, rpy)) instead of free dynamics, and an
    applied world force [N] at a point of its frame [m]."""

    model: ObjectModel
    support: Support
    start: np.ndarray
    height: float = 0.0
    prescribed: object = None
    force: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(3))
    force_point: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(3))


def _frame(q: ca.SX, v: ca.SX) -> BodyFrame:
    return BodyFrame(q[0:3], rpy_matrix(q[3:6]), v[0:3], euler_rates_to_world(q[3:6]) @ v[3:6])


def solve_toy(bodies: list[Body], nodes: int) -> dict[str, np.ndarray]:
    """The bodies' motion over ``nodes`` nodes from rest: (1) for the free ones, each
    support's equalities at every node after the first and its wrench rows at every node;
    cost: the wrenches and slacks squared. Returns q, v, w (nodes, bodies, 6) and the
    status."""
    m = len(bodies)
    Q, V, W = (ca.SX.sym(n, 6, nodes * m) for n in ("q", "v", "w"))
    S = ca.SX.sym("s", nodes * m)

    def at(X, k, j):
        return X[:, k * m + j]

    g, lbg, ubg = [], [], []

    def eq(rows):
        g.append(rows)
        lbg.append(np.zeros(rows.numel()))
        ubg.append(np.zeros(rows.numel()))

    def ineq(rows):
        g.append(rows)
        lbg.append(np.zeros(rows.numel()))
        ubg.append(np.full(rows.numel(), np.inf))

    for j, body in enumerate(bodies):
        eq(at(Q, 0, j) - body.start)
        eq(at(V, 0, j))
    for k in range(nodes):
        for j, body in enumerate(bodies):
            q, v, w = at(Q, k, j), at(V, k, j), at(W, k, j)
            frame = _frame(q, v)
            eq(body.support.wrench_equalities(body.model, frame, w))
            ineq(body.support.inequalities(body.model, frame, w))
            if k == 0:
                continue
            before = _frame(at(Q, k - 1, j), at(V, k - 1, j))
            base = getattr(body.support, "base", None)
            base_now = base_before = None
            if base is not None:
                base_now = _frame(at(Q, k, base), at(V, k, base))
                base_before = _frame(at(Q, k - 1, base), at(V, k - 1, base))
            contact = SupportContact(
                body.model, frame, before, base_now, base_before, body.height, 50.0, 0.0
            )
            eq(body.support.equalities(contact))
            if body.prescribed is not None:
                eq(q - body.prescribed(k * DT))
                continue
            q0, v0 = at(Q, k - 1, j), at(V, k - 1, j)
            obj = body.model
            R0 = rpy_matrix(q0[3:6])
            contacts = [(q0[0:3], at(W, k - 1, j)[0:3], at(W, k - 1, j)[3:6])]
            contacts.append((q0[0:3] + R0 @ body.force_point, ca.DM(body.force), ca.DM.zeros(3)))
            for r, rider in enumerate(bodies):
                if getattr(rider.support, "base", None) == j:
                    wr = at(W, k - 1, r)
                    contacts.append((at(Q, k - 1, r)[0:3], -wr[0:3], -wr[3:6]))
            eq(
                object_dynamics(
                    q0,
                    v0,
                    q,
                    v,
                    contacts,
                    mass=obj.mass,
                    inertia=obj.inertia,
                    com=obj.com,
                    dt=DT,
                )
            )  # (1)
    x = ca.vertcat(ca.vec(Q), ca.vec(V), ca.vec(W), S)
    cost = 1e-4 * ca.sumsqr(W) + 1e4 * ca.sumsqr(S)
    solver = ca.nlpsol(
        "toy",
        "ipopt",
        {"x": x, "f": cost, "g": ca.vertcat(*g)},
        {"print_time": False, "ipopt": {"print_level": 0, "sb": "yes", "tol": 1e-10}},
    )
    x0 = np.zeros(x.numel())
    for k in range(nodes):
        for j, body in enumerate(bodies):
            x0[(k * m + j) * 6 : (k * m + j) * 6 + 6] = body.start
    result = solver(x0=x0, lbg=np.concatenate(lbg), ubg=np.concatenate(ubg))
    n6 = 6 * nodes * m
    xs = np.asarray(result["x"]).ravel()

    def unpack(i):
        return xs[i * n6 : (i + 1) * n6].reshape(nodes, m, 6)

    return {
        "q": unpack(0),
        "v": unpack(1),
        "w": unpack(2),
        "status": solver.stats()["return_status"],
    }


def _trolley(force, point) -> Body:
    return Body(
        TROLLEY,
        Chassis(),
        np.zeros(6),
        force=np.asarray(force, float),
        force_point=np.asarray(point, float),
    )


HANDLE = (-0.4, 0.0, 0.95)  # [m] the handle bar, trolley frame


def test_a_trolley_pushed_forward_rolls_with_the_push():
    """20 N forward at the handle: it accelerates at F / m along its x, nothing sideways,
    and (7b) leaves the ground no longitudinal force."""
    out = solve_toy([_trolley([20.0, 0.0, 0.0], HANDLE)], nodes=11)
    assert out["status"] == "Solve_Succeeded"
    q, v, w = out["q"][:, 0], out["v"][:, 0], out["w"][:, 0]
    assert v[-1, 0] == pytest.approx(20.0 / TROLLEY.mass * 10 * DT, rel=1e-6)
    assert np.abs(q[:, [1, 5]]).max() < 1e-8
    assert np.abs(w[:, 0]).max() < 1e-8


def test_a_trolley_pushed_sideways_at_its_rear_axle_does_not_move():
    """(7a): 20 N sideways through the rear axle; the rear wheels' lateral force takes it."""
    out = solve_toy([_trolley([0.0, 20.0, 0.0], (-0.35, 0.0, 0.3))], nodes=11)
    assert out["status"] == "Solve_Succeeded"
    assert np.abs(out["q"][:, 0, :3] - 0.0).max() < 1e-8
    assert np.abs(out["v"][:, 0]).max() < 1e-8
    assert out["w"][:-1, 0, 1] == pytest.approx(-20.0, rel=1e-6)


def test_a_trolley_pushed_sideways_at_its_front_turns_about_its_rear_axle():
    """The front wheels swivel: pushed sideways at the front it yaws, and its rear axle
    centre moves only along the trolley's x (its lateral velocity stays zero)."""
    out = solve_toy([_trolley([0.0, 20.0, 0.0], (0.4, 0.0, 0.3))], nodes=11)
    assert out["status"] == "Solve_Succeeded"
    q, v = out["q"][:, 0], out["v"][:, 0]
    assert q[-1, 5] > 0.1  # it turned left
    R = [rpy_matrix(ca.DM(qk[3:6])).full() for qk in q]
    rear = [qk[:3] - 0.35 * Rk[:, 0] for qk, Rk in zip(q, R, strict=True)]
    for k in range(1, len(q)):
        assert abs(R[k][:, 1] @ (rear[k] - rear[k - 1])) < 1e-9  # (7a) over the step
    # The rate form at the nodes (what the evaluation measures) holds to O(omega^2 dt).
    omega = [
        euler_rates_to_world(ca.DM(qk[3:6])).full() @ vk[3:6] for qk, vk in zip(q, v, strict=True)
    ]
    lateral = [
        abs(Rk[:, 1] @ (vk[:3] + np.cross(wk, -0.35 * Rk[:, 0])))
        for Rk, vk, wk in zip(R, v, omega, strict=True)
    ]
    assert max(lateral) < 0.01 * np.abs(v[:, :3]).max()


def _platform(acceleration: float) -> Body:
    """A platform (the trolley) driven along x at ``acceleration`` [m/s^2] from rest."""

    def motion(t: float) -> np.ndarray:
        # (1b)'s semi-implicit steps of a constant acceleration.
        k = round(t / DT)
        return np.r_[acceleration * DT * DT * k * (k + 1) / 2, 0.0, 0.0, 0.0, 0.0, 0.0]

    return Body(TROLLEY, Chassis(), np.zeros(6), prescribed=motion)


def test_a_box_rides_on_an_accelerating_platform_within_its_friction_cone():
    """(4)-(6), (3): on a platform accelerating at 2 m/s^2 (below mu g) the box stays where
    it was put, the platform pushes it with m a, and the cone holds."""
    box = Body(BOX, OnObject(0), np.r_[0.1, 0.0, 0.55, 0.0, 0.0, 0.0], height=0.55)
    out = solve_toy([_platform(2.0), box], nodes=9)
    assert out["status"] == "Solve_Succeeded"
    q = out["q"]
    np.testing.assert_allclose(q[:, 1, 0] - q[:, 0, 0], 0.1, atol=1e-8)
    np.testing.assert_allclose(q[:, 1, 2], 0.55, atol=1e-8)
    w = out["w"][:-1, 1]
    np.testing.assert_allclose(w[1:, 0], BOX.mass * 2.0, rtol=1e-6)
    np.testing.assert_allclose(w[:, 2], BOX.mass * G, rtol=1e-6)
    assert np.all(np.abs(w[:, 0]) <= BOX.friction * w[:, 2] + 1e-9)


def test_a_box_cannot_ride_a_platform_accelerating_beyond_its_friction():
    """At 12 m/s^2 > mu g the friction cone (3) cannot hold the box: infeasible."""
    box = Body(BOX, OnObject(0), np.r_[0.1, 0.0, 0.55, 0.0, 0.0, 0.0], height=0.55)
    out = solve_toy([_platform(12.0), box], nodes=5)
    assert out["status"] != "Solve_Succeeded"


def test_a_box_on_a_box_on_the_floor_balances_both_weights():
    """The two-object toy of S1: the lower box's floor contact carries both boxes; the
    upper one's contact carries its own weight, handed down to the lower one by (6)."""
    lower = Body(BOX, Surface(), np.zeros(6))
    upper_model = ObjectModel.box("upper", np.array([0.2, 0.2, 0.1]), 2.0, 0.8)
    upper = Body(upper_model, OnObject(0), np.r_[0.02, -0.03, 0.2, 0.0, 0.0, 0.3], height=0.2)
    out = solve_toy([lower, upper], nodes=6)
    assert out["status"] == "Solve_Succeeded"
    w = out["w"][:-1]
    np.testing.assert_allclose(w[:, 0, 2], (BOX.mass + upper_model.mass) * G, rtol=1e-6)
    np.testing.assert_allclose(w[:, 1, 2], upper_model.mass * G, rtol=1e-6)
    np.testing.assert_allclose(w[:, :, :2], 0.0, atol=1e-6)
    assert np.abs(out["v"]).max() < 1e-8


def test_a_box_on_the_floor_does_not_turn_under_a_twisting_push():
    """Paper A's (2b) holds the patch's point, not the patch: S1's box spun 0.34 rad per
    node on the floor. A 10 N push 15 cm off its centre (1.5 N m about the normal, within
    its friction) leaves it where it was set, turned by nothing."""
    push = Body(BOX, Surface(), np.zeros(6), force=np.r_[0.0, 10.0, 0.0])
    push.force_point = np.r_[0.15, 0.0, 0.0]
    out = solve_toy([push], nodes=6)
    assert out["status"] == "Solve_Succeeded"
    np.testing.assert_allclose(out["q"][:, 0], 0.0, atol=1e-8)
    w = out["w"][:-1, 0]
    np.testing.assert_allclose(w[:, 5], -1.5, rtol=1e-6)  # the floor's moment holds it


@pytest.mark.parametrize("yaw_deg", [0.0, -84.0, 90.0, 179.0])
def test_the_turn_about_the_normal_is_seen_at_every_yaw(yaw_deg):
    """(5b) was R[0, 1] - R_before[0, 1], the difference of two yaws' sines: flat at +-90
    deg, where S2's box turned from -84 to -96 deg on the trolley with it satisfied."""
    before = rpy_matrix(ca.DM([0.0, 0.0, np.radians(yaw_deg)]))
    turned = rpy_matrix(ca.DM([0.0, 0.0, np.radians(yaw_deg - 12.0)]))
    assert float(turn_about_normal(before, before)) == pytest.approx(0.0, abs=1e-12)
    assert float(turn_about_normal(before, turned)) == pytest.approx(-np.sin(np.radians(12.0)))
    # A half turn has no sine: the cosine's row (>= 0) refuses it (a stance foot flipped).
    flipped = rpy_matrix(ca.DM([0.0, 0.0, np.radians(yaw_deg + 180.0)]))
    assert float(turn_about_normal(before, flipped)) == pytest.approx(0.0, abs=1e-12)
    assert float(facing_same_way(before, before)) == pytest.approx(1.0)
    assert float(facing_same_way(before, flipped)) == pytest.approx(-1.0)
