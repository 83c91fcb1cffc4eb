"""HQP: bounds respected, strict hierarchy, tasks and the short closed loop in MuJoCo."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from locoman.hqp.impedance import joint_impedance_torque
from locoman.hqp.limits import JointLimits, VelocityBox
from locoman.hqp.solver import HierarchySolver, WholeBodyHqp, weighted_objective

LIMITS = JointLimits(
    arm_min=np.full(7, -2.5),
    arm_max=np.full(7, 2.5),
    velocity_max=np.r_[0.5, 0.5, 0.5, np.full(7, 2.0)],
    acceleration_max=np.r_[0.5, 0.5, 0.3, np.full(7, 10.0)],
)


def solve_level(jac, b1, lo, hi, objective=None):
    """The product's solver on one problem: the bounds, (jac, b1), then the objective
    (H, f) (none: min 1/2 ||x||^2)."""
    h, f = (np.eye(len(lo)), np.zeros(len(lo))) if objective is None else objective
    qp = HierarchySolver(h, len(b1))
    qp.lower[:], qp.upper[:] = lo, hi
    return qp.solve((jac, b1), f)


def random_problem(seed: int):
    rng = np.random.default_rng(seed)
    jac = rng.normal(size=(6, 10))
    b1 = rng.normal(scale=0.3, size=6)
    q_arm = rng.uniform(-2.6, 2.6, 7)
    prev = np.clip(rng.normal(scale=0.5, size=10), -LIMITS.velocity_max, LIMITS.velocity_max)
    lo, hi = VelocityBox(LIMITS, 1e-3)(np.r_[np.zeros(3), q_arm], prev)
    level2 = (np.eye(10), rng.normal(size=10))
    return jac, b1, lo, hi, level2, q_arm, prev


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 10_000))
def test_velocity_box_is_never_empty_and_respects_7_to_9(seed):
    _, _, lo, hi, _, q_arm, prev = random_problem(seed)
    assert np.all(lo <= hi)
    assert np.all(np.abs(lo) <= LIMITS.velocity_max + 1e-12)
    assert np.all(np.abs(hi) <= LIMITS.velocity_max + 1e-12)
    assert np.all(np.abs(lo - prev) <= LIMITS.acceleration_max * 1e-3 + 1e-12)
    assert np.all(np.abs(hi - prev) <= LIMITS.acceleration_max * 1e-3 + 1e-12)
    inside = (q_arm > LIMITS.arm_min) & (q_arm < LIMITS.arm_max)
    step_hi = q_arm + hi[3:] * 1e-3
    # A joint too fast to stop before its limit brakes as hard as (9) lets it (the box is
    # never empty); every other joint inside its limits stays inside (7).
    braking = prev[3:] - LIMITS.acceleration_max[3:] * 1e-3
    can_stop = (LIMITS.arm_max - q_arm) / 1e-3 >= braking
    assert np.all(step_hi[inside & can_stop] <= LIMITS.arm_max[inside & can_stop] + 1e-12)
    assert np.allclose(hi[3:][~can_stop], braking[~can_stop], rtol=0.0, atol=1e-12)


def sequential_box(q_star, prev, limits, dt):
    """(7)-(9) intersected one after the other, as the docstring of VelocityBox states them."""
    lo = np.maximum(-limits.velocity_max, prev - limits.acceleration_max * dt)  # (8), (9)
    hi = np.minimum(limits.velocity_max, prev + limits.acceleration_max * dt)
    lo = np.minimum(lo, hi)
    pos_lo = np.r_[np.full(3, -np.inf), (limits.arm_min - q_star[3:]) / dt]  # (7)
    pos_hi = np.r_[np.full(3, np.inf), (limits.arm_max - q_star[3:]) / dt]
    lo = np.clip(pos_lo, lo, hi)  # where (7) empties the box, the acceleration bound wins
    return lo, np.clip(pos_hi, lo, hi)


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 10_000))
def test_the_velocity_box_is_the_sequential_intersection_to_the_bit(seed):
    """The box's fused form (fewer numpy calls at 1 kHz) changes no bit: the replay is
    chaotic at the grasp, so a last-bit change would move its results."""
    *_, q_arm, prev = random_problem(seed)
    q_star = np.r_[np.random.default_rng(seed).normal(size=3), q_arm]
    lo, hi = VelocityBox(LIMITS, 1e-3)(q_star, prev)
    expected = sequential_box(q_star, prev, LIMITS, 1e-3)
    np.testing.assert_array_equal(lo, expected[0])
    np.testing.assert_array_equal(hi, expected[1])


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 10_000))
def test_hqp_respects_every_bound(seed):
    jac, b1, lo, hi, level2, *_ = random_problem(seed)
    x = solve_level(jac, b1, lo, hi, weighted_objective(level2, np.ones(10)))
    assert np.all(x >= lo) and np.all(x <= hi)


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 10_000), st.floats(0.01, 10.0))
def test_level2_never_degrades_level1(seed, weight):
    jac, b1, lo, hi, level2, *_ = random_problem(seed)
    alone = solve_level(jac, b1, lo, hi)
    both = solve_level(jac, b1, lo, hi, weighted_objective(level2, np.full(10, weight)))
    r_alone = np.linalg.norm(jac @ alone - b1)
    r_both = np.linalg.norm(jac @ both - b1)
    assert r_both <= r_alone + 1e-6


def test_unbounded_hierarchy_matches_the_nullspace_projection():
    rng = np.random.default_rng(3)
    jac, b1 = rng.normal(size=(6, 10)), rng.normal(size=6)
    target = rng.normal(size=10)
    x = solve_level(jac, b1, np.full(10, -1e3), np.full(10, 1e3), (np.eye(10), -target))
    pinv = np.linalg.pinv(jac)
    expected = pinv @ b1 + (np.eye(10) - pinv @ jac) @ target
    np.testing.assert_allclose(x, expected, atol=1e-6)


def test_clik_closes_the_loop_on_a_kinematic_arm():
    """Integrating the HQP on a linear 'robot' x = J q drives x to a moving target."""
    jac = np.random.default_rng(4).normal(size=(6, 10))
    hqp = WholeBodyHqp(LIMITS, 1e-3, np.zeros(10), 4.0, 1.0, 1.0, 0.05)
    rot = np.eye(3)
    for k in range(3000):
        t = k * 1e-3
        x_d = np.array([0.05 * t, 0.02, 0.0])
        q = hqp.q_star
        x_a = (jac[:3] @ q, rot)
        hqp.step(
            jac * np.r_[1, 1, 1, 0, 0, 0][:, None],
            (x_d, rot),
            np.r_[0.05, 0, 0, 0, 0, 0],
            x_a,
            np.zeros(3),
        )
    assert np.linalg.norm(jac[:3] @ hqp.q_star - x_d) < 1e-3


def test_joint_impedance_law_is_eq_10():
    tau = joint_impedance_torque(
        np.ones(7), np.zeros(7), np.zeros(7), np.ones(7), 20.0, 8.0, np.full(7, 0.5)
    )
    np.testing.assert_allclose(tau, 20.0 - 8.0 + 0.5)


@pytest.mark.parametrize("feedback", [False, True])
def test_measured_velocity_option_reaches_the_task(feedback):
    hqp = WholeBodyHqp(LIMITS, 1e-3, np.zeros(10), 4.0, 1.0, 1.0, 0.05, feedback)
    jac = np.eye(6, 10)
    hqp.step(
        jac,
        (np.ones(3), np.eye(3)),
        np.zeros(6),
        (np.zeros(3), np.eye(3)),
        np.zeros(3),
        np.full(6, 0.1),
    )
    expected = 4.0 * np.ones(3) - (0.1 if feedback else 0.0)
    np.testing.assert_allclose(hqp.last_level1[1][:3], expected)


def test_the_reused_qp_workspace_gives_the_one_shot_solution():
    """HierarchySolver keeps DAQP's workspace between solves: problem after problem, it
    returns what a fresh solver (DAQP set up for that problem) returns, to the last bit:
    the replay's grasp is chaotic at that level, so a warm start would move its results."""
    weights = np.r_[np.ones(3), np.full(7, 0.05)]
    qp = HierarchySolver(np.diag(weights), 6)
    for seed in range(30):
        jac, b1, lo, hi, level2, *_ = random_problem(seed)
        qp.lower[:], qp.upper[:] = lo, hi
        f = weighted_objective(level2, weights)[1]
        x = qp.solve((jac, b1), f)
        expected = solve_level(jac, b1, lo, hi, weighted_objective(level2, weights))
        np.testing.assert_array_equal(x, expected)
        assert np.all(x >= lo) and np.all(x <= hi)


def test_the_velocity_box_writes_into_given_buffers():
    _, _, lo, hi, _, q_arm, prev = random_problem(7)
    out = (np.full(10, np.nan), np.full(10, np.nan))
    VelocityBox(LIMITS, 1e-3)(np.r_[np.zeros(3), q_arm], prev, out=out)
    np.testing.assert_array_equal(out[0], lo)
    np.testing.assert_array_equal(out[1], hi)
