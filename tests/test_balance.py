"""The LIPM centre-of-mass reference (locoman.execute.balance): the ZMP path over the
footsteps, the hands' shift of it against a direct moment balance, the pendulum's fit, and the
reference the controller gets."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from test_execute import standing_trajectory

from locoman.config.execute import BalanceCfg, ExecuteCfg
from locoman.execute.balance import (
    GRAVITY,
    body_shift,
    effective_zmp,
    execution_reference,
    fit_com,
    support_height,
    zmp_path,
)
from locoman.execute.model import PALMS, SOLES
from locoman.execute.reference import (
    build_reference,
    carried,
    contact_blend,
    with_hand_clearance,
)
from locoman.execute.simulate import palm_torsion

LEFT, RIGHT = np.array([0.0, 0.1]), np.array([0.0, -0.1])


def test_the_zmp_path_stays_on_the_stance_sole_and_moves_straight_in_double_support():
    # Double support (start), right swing, double support, left swing, double support (end).
    contact = np.array([[1, 1]] * 4 + [[1, 0]] * 3 + [[1, 1]] * 4 + [[0, 1]] * 3 + [[1, 1]] * 2)
    soles = np.tile(np.stack([LEFT, RIGHT]), (len(contact), 1, 1))
    start = np.array([0.0, 0.0])
    path = zmp_path(contact.astype(bool), soles, start)
    np.testing.assert_allclose(path[4:7], np.tile(LEFT, (3, 1)))
    np.testing.assert_allclose(path[11:14], np.tile(RIGHT, (3, 1)))
    # From the start towards the left sole, reaching it as the right lifts.
    np.testing.assert_allclose(path[:4, 1], [0.02, 0.04, 0.06, 0.08])
    # Left to right in a straight line, strictly between them.
    assert np.all(np.diff(path[6:12, 1]) < 0)
    np.testing.assert_allclose(path[7:11, 0], 0.0)
    # The end: from the right sole to between the soles.
    np.testing.assert_allclose(path[-1], [0.0, 0.0])


@given(
    zmp=st.lists(st.floats(-0.3, 0.3), min_size=2, max_size=2),
    force=st.lists(st.floats(-40.0, 40.0), min_size=6, max_size=6),
    moment=st.lists(st.floats(-3.0, 3.0), min_size=6, max_size=6),
    palms=st.lists(st.floats(-0.5, 0.5), min_size=4, max_size=4),
    height=st.floats(0.5, 1.2),
    ground=st.floats(-0.1, 0.3),
)
@settings(max_examples=100, deadline=None)
def test_the_hands_shift_of_the_zmp_balances_the_moments_about_the_soles_cop(
    zmp, force, moment, palms, height, ground
):
    """A robot at rest whose own centre of mass stands over z_hat, its hands taking the
    wrenches, has the soles' reaction (the rest of the wrench) with no horizontal moment
    about the CoP ``zmp``: the soles' CoP is where the path asks."""
    mass = 30.0
    z = np.array([zmp])
    wrench = np.concatenate([np.reshape(force, (2, 3)), np.reshape(moment, (2, 3))], axis=1)
    position = np.column_stack([np.reshape(palms, (2, 2)), [ground + height] * 2])
    z_hat = effective_zmp(z, wrench[None], position[None], np.array([ground]), mass)[0]
    com = np.r_[z_hat, ground + 0.7]
    # The soles' wrench about the CoP: minus gravity's and the hands'.
    cop = np.r_[zmp, ground]
    moment_at_cop = np.cross(com - cop, [0.0, 0.0, -mass * GRAVITY])
    for k in range(2):
        moment_at_cop += np.cross(position[k] - cop, wrench[k, :3]) + wrench[k, 3:]
    np.testing.assert_allclose(moment_at_cop[:2], 0.0, atol=1e-9)


def test_the_fitted_pendulum_follows_its_zmp_target_from_rest_to_rest():
    dt = 0.001
    t = np.arange(0.0, 4.0, dt)
    target = np.zeros((len(t), 2))
    target[:, 1] = 0.08 * np.sin(np.pi * t / 1.0) * (t > 1.0) * (t < 3.0)  # a sway
    target[:, 0] = np.clip(t - 1.0, 0.0, 2.0) * 0.1  # 20 cm forward
    height = 0.7
    c, c_dot, c_ddot = fit_com(target, np.zeros((3, 2)), height, dt, 0.02, 1e-6)
    # The state integrates: c_dot and c_ddot are c's rates.
    np.testing.assert_allclose(np.diff(c, axis=0) / dt, (c_dot[1:] + c_dot[:-1]) / 2, atol=2e-5)
    zmp = c - height / GRAVITY * c_ddot
    assert np.abs(zmp - target).max() < 0.01
    np.testing.assert_allclose(c[0], 0.0, atol=1e-12)
    np.testing.assert_allclose(c_dot[0], 0.0, atol=1e-12)
    assert np.abs(c_dot[-1]).max() < 1e-3 and np.abs(c[-1] - [0.2, 0.0]).max() < 5e-3
    # The centre of mass anticipates: it moves before the ZMP's first change (t = 1 s)...
    assert np.abs(c[900]).max() > 1e-3
    # ... first away from it (the ZMP pushes it): y sways against the target's first half.
    assert c[1000:1300, 0].min() >= -0.02


def test_support_height_is_the_lowest_stance_sole():
    contact = np.array([[True, True], [True, False], [False, False]])
    heights = np.array([[0.1, 0.0], [0.2, 0.0], [0.3, 0.05]])
    np.testing.assert_allclose(support_height(contact, heights), [0.0, 0.2, 0.05])


def test_the_palm_torsion_is_mu_times_the_patchs_mean_radius():
    half = np.array([0.04, 0.03])
    n = 800  # cell centres of an n x n grid over the patch
    u = (np.arange(n) + 0.5) / n * 2 - 1
    x, y = np.meshgrid(half[0] * u, half[1] * u)
    assert abs(palm_torsion(0.8, half) - 0.8 * np.hypot(x, y).mean()) < 1e-6


def test_a_hands_wrench_is_fed_forward_only_while_it_carries_its_object_alone():
    traj = {
        "hand_object": np.array([[-1, -1], [0, 0], [0, 0], [0, -1]]),
        "support_kind": np.array([["surface"], ["surface"], ["none"], ["none"]]),
    }
    np.testing.assert_array_equal(carried(traj, np.arange(4)), [[0, 0], [0, 0], [1, 1], [1, 0]])


def test_the_execution_reference_replans_only_the_horizontal_centre_of_mass():
    traj = standing_trajectory(sway_m=0.04)
    cfg = ExecuteCfg(hold_s=0.2)
    plan = build_reference(traj, cfg.timestep_s, cfg.settle_s, cfg.hold_s)
    ref = execution_reference(traj, cfg)
    np.testing.assert_array_equal(ref.q, plan.q)
    np.testing.assert_array_equal(ref.com[:, 2], plan.com[:, 2])
    np.testing.assert_array_equal(ref.foot_wrench, 0.0)
    # Standing on both soles the ZMP path goes straight from the standing centre of mass to
    # between the soles: the plan's sway (4 cm) is not followed.
    middle = np.stack([plan.frames[name].position[:, :2] for name in SOLES], axis=1).mean(1)
    assert np.abs(ref.com[:, 1] - middle[:, 1]).max() < 1e-3
    low, high = sorted([plan.com[0, 0], middle[0, 0]])
    assert np.all((ref.com[:, 0] > low - 1e-3) & (ref.com[:, 0] < high + 1e-3))
    same = execution_reference(traj, ExecuteCfg(hold_s=0.2, balance=BalanceCfg("plan")))
    np.testing.assert_array_equal(same.com, plan.com)


def test_the_contact_blend_is_zero_on_contact_one_far_from_it_and_smooth_between():
    dt = 0.01
    touching = np.zeros(200, dtype=bool)
    touching[100:120] = True
    w = contact_blend(touching, dt, 0.5)
    np.testing.assert_array_equal(w[100:120], 0.0)
    np.testing.assert_array_equal(w[:50], 1.0)
    np.testing.assert_array_equal(w[170:], 1.0)
    assert np.all(np.diff(w[50:101]) <= 0) and np.all(np.diff(w[119:171]) >= 0)
    # C1: its rate goes to zero where it meets 0 and 1 (a linear blend's would be 2 /s),
    # 1.5 / blend_s at most between.
    rate = np.diff(w) / dt
    assert abs(rate[50]) < 0.2 and abs(rate[99]) < 0.2 and np.abs(rate).max() <= 3.0 + 1e-9
    np.testing.assert_array_equal(contact_blend(np.zeros(5, dtype=bool), dt, 0.5), 1.0)


def test_a_free_hand_backs_off_its_normal_and_moves_with_the_body_a_holding_one_does_not():
    traj = standing_trajectory()
    nodes = len(traj["dt"])
    traj["hand_object"] = np.full((nodes, 2), -1)
    traj["hand_object"][6:, 0] = 0  # the left hand holds from node 6 (0.6 s) on
    traj["object_q"] = np.zeros((nodes, 1, 6))
    traj["support_kind"] = np.full((nodes, 1), "surface")
    cfg = ExecuteCfg(settle_s=0.2, hold_s=0.2, hand_clearance_m=0.05, hand_blend_s=0.3)
    plan = build_reference(traj, cfg.timestep_s, cfg.settle_s, cfg.hold_s)
    ref = with_hand_clearance(plan, cfg.hand_clearance_m, cfg.timestep_s, cfg.hand_blend_s)
    left, right = PALMS
    holding = plan.hand_object[:, 0] >= 0
    np.testing.assert_allclose(
        ref.frames[left].position[holding], plan.frames[left].position[holding]
    )
    offset = ref.frames[right].position - plan.frames[right].position
    normal = plan.frames[right].rotation[:, :, 2]
    np.testing.assert_allclose(offset, -0.05 * normal, atol=1e-12)
    # The velocity the QP tracks is the shifted position's rate.
    far = ~holding & (np.arange(len(holding)) < np.argmax(holding) - 400)
    rate = np.gradient(ref.frames[left].position[:, 1], cfg.timestep_s)
    np.testing.assert_allclose(ref.frames[left].velocity[:, 1], rate, atol=1e-6)
    assert far.any()
    # A free hand follows the replanned centre of mass; the holding one stays put.
    shift = np.ones((len(holding), 3))
    moved = body_shift(shift, holding, cfg.timestep_s, cfg.hand_blend_s)
    np.testing.assert_array_equal(moved[holding], 0.0)
    np.testing.assert_array_equal(moved[far], 1.0)
