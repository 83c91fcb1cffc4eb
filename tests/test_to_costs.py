"""Table I and the keyframe costs (9), (10) on numbers worked by hand."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from locoman.config.to import CostWeights, averaged_over_nodes
from locoman.scene import g1
from locoman.to.terms.costs import (
    ARM_NOMINAL,
    ARMS,
    keyframe_base_cost,
    keyframe_foot_cost,
    regularization_cost,
    stance_cost,
)

W = CostWeights()


def _value(expr) -> float:
    return float(ca.evalf(expr))


def test_keyframe_costs_are_the_papers_weighted_squares():
    q = ca.DM(np.r_[0.0, 0.0, 0.7, 0.1, 0.0, 0.2, np.zeros(29)])
    q_kf = ca.DM(np.r_[1.0, 1.0, 0.6, 0.0, 0.0, 0.0, np.zeros(29)])
    assert _value(keyframe_base_cost(W, q, q_kf)) == pytest.approx(100 * 0.01 + 10 * 0.05)
    r_lf, r_rf = ca.DM([0.0, 0.1, 0.0]), ca.DM([0.2, -0.1, 0.0])
    assert _value(keyframe_foot_cost(W, r_lf, r_rf, ca.DM([0.1, 0.3, 0.0]))) == pytest.approx(
        500 * 0.09
    )


def test_stance_cost_vanishes_for_a_symmetric_stance_over_the_feet():
    q = ca.DM(g1.standing_q35())  # symmetric legs, zero hip roll and yaw, level base
    r_lf, r_rf = ca.DM([0.0, 0.12, 0.0]), ca.DM([0.0, -0.12, 0.0])
    com = ca.DM([0.0, 0.0, 0.7])
    assert _value(stance_cost(W, q, com, r_lf, r_rf, ca.DM.eye(3), ca.DM.eye(3))) == pytest.approx(
        0
    )
    off = ca.DM([0.1, 0.0, 0.7])
    assert _value(stance_cost(W, q, off, r_lf, r_rf, ca.DM.eye(3), ca.DM.eye(3))) == pytest.approx(
        500 * 0.01
    )


def test_regularization_penalises_the_timestep_and_base_height():
    q = np.r_[0.0, 0.0, 0.8, np.zeros(32)]
    q[[6 + k for k in ARMS]] = ARM_NOMINAL  # arms at their nominal: no arm cost
    q = ca.DM(q)
    cost = regularization_cost(W, q, ca.DM.zeros(35), ca.DM.zeros(12), ca.DM.zeros(3), 0.03)
    assert _value(cost) == pytest.approx(100 * 0.01 + 100 * 0.01**2)


def test_averaging_over_nodes_divides_stage_weights_but_not_9_or_references():
    """(14a): (10) is part of the stance cost L_st, so it is averaged; (9) is summed."""
    averaged = averaged_over_nodes(W, 50)
    assert averaged.com_over_feet == pytest.approx(W.com_over_feet / 50)
    assert averaged.slack == pytest.approx(W.slack / 50)
    assert averaged.collision == pytest.approx(W.collision / 50)
    assert averaged.keyframe_base == W.keyframe_base
    assert averaged.keyframe_foot == pytest.approx(W.keyframe_foot / 50)
    assert averaged.object_goal == W.object_goal
    assert (averaged.clearance_m, averaged.base_height_m, averaged.timestep_s) == (
        W.clearance_m,
        W.base_height_m,
        W.timestep_s,
    )
