"""The G1 stance slice of the TO: it converges, its dynamics hold by Pinocchio's account,
the feet stay put, and a failed solve is returned with its status."""

from __future__ import annotations

import numpy as np
import pytest

from locoman.scene import g1
from locoman.to.residuals import contact_points, dynamics_residual
from locoman.to.stance import FEET, StanceCfg, sole_frame, solve_stance


@pytest.fixture(scope="module")
def squat():
    q_start = g1.standing_q35()
    q_keyframe = q_start.copy()
    q_keyframe[2] -= 0.12
    return q_start, solve_stance(q_start, q_keyframe, StanceCfg(nodes=5))


def test_stance_converges_and_the_keyframe_cost_moves_the_base(squat):
    q_start, down = squat
    assert down.success, down.status
    assert down.q.shape == (5, 35) and down.dt.shape == (4,)
    q_up = q_start.copy()
    q_up[2] += 0.12
    up = solve_stance(q_start, q_up, StanceCfg(nodes=5))
    assert up.success, up.status
    # Over 5 nodes (0.1-0.2 s) from rest the base moves a fraction of a millimetre, but
    # towards the keyframe height of (9).
    assert down.q[-1, 2] < up.q[-1, 2] - 1e-4


def test_dynamics_hold_by_pinocchio_and_feet_do_not_slip(squat):
    _, s = squat
    model = g1.g1_pinocchio_model()
    centre, _ = sole_frame()
    offsets = [centre, centre]
    residual = dynamics_residual(model, s.q, s.v, s.forces, s.moments, s.dt, FEET, offsets)
    assert residual.max() <= 1e-6
    soles = np.array([contact_points(model, q, FEET, offsets) for q in s.q])
    assert np.abs(soles[:, :, :2] - soles[0, :, :2]).max() <= 1e-3
    assert np.abs(soles[:, :, 2]).max() <= 1e-3
    assert s.forces[:-1, :, 2].sum(axis=1).min() > 0.0


def test_a_failed_solve_is_returned_with_its_status():
    q_start = g1.standing_q35()
    solution = solve_stance(q_start, q_start, StanceCfg(nodes=4, max_iterations=1))
    assert not solution.success
    assert solution.status == "Maximum_Iterations_Exceeded"
    assert solution.iterations == 1
