"""The centroidal angular momentum task, the fall check and the touchdown heights
(locoman.execute): the task's rows against Pinocchio's momentum and its finite differences,
the tilt from the plan's pelvis, a sole's height where the plan puts it down."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
from hypothesis import given, settings
from hypothesis import strategies as st

from locoman.config.execute import ExecuteCfg, MomentumCfg
from locoman.execute.metrics import touchdown_heights
from locoman.execute.model import execution_model
from locoman.execute.simulate import tilt_from
from locoman.execute.tasks import angular_momentum_rows
from locoman.scene import g1
from locoman.scene.rotations import rpy_to_matrix

_MODEL = execution_model()


def _state(seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    q = g1.q35_to_pin(g1.standing_q35() + np.r_[np.zeros(3), rng.normal(0, 0.2, 32)])
    return q, rng.normal(0.0, 1.0, _MODEL.nv), rng.normal(0.0, 5.0, _MODEL.nv)


def _momentum(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    data = _MODEL.createData()
    return pin.computeCentroidalMomentum(_MODEL, data, q, v).angular.copy()


@settings(max_examples=10, deadline=None)
@given(st.integers(0, 10_000))
def test_the_rows_give_the_momentums_rate_as_finite_differences_do(seed):
    """A a - (b + gain L) = dL/dt, the momentum about the moving centre of mass."""
    q, v, a = _state(seed)
    data = _MODEL.createData()
    pin.computeCentroidalMapTimeVariation(_MODEL, data, q, v)
    cfg = MomentumCfg(weight=1.0, gain=10.0)
    rows, b = angular_momentum_rows(cfg, data.Ag, data.dAg, v)
    np.testing.assert_allclose(rows @ v, _momentum(q, v), atol=1e-9)
    h = 1e-6
    forward = _momentum(pin.integrate(_MODEL, q, h * v + 0.5 * h * h * a), v + h * a)
    backward = _momentum(pin.integrate(_MODEL, q, -h * v + 0.5 * h * h * a), v - h * a)
    rate = (forward - backward) / (2 * h)
    np.testing.assert_allclose(rows @ a - (b + cfg.gain * _momentum(q, v)), rate, atol=1e-4)


def test_the_task_asks_the_momentum_to_decay():
    """At a = the task's least-squares solution the momentum's rate is -gain L."""
    q, v, _ = _state(7)
    data = _MODEL.createData()
    pin.computeCentroidalMapTimeVariation(_MODEL, data, q, v)
    cfg = MomentumCfg(weight=1.0, gain=4.0)
    rows, b = angular_momentum_rows(cfg, data.Ag, data.dAg, v)
    a = np.linalg.lstsq(rows, b, rcond=None)[0]
    drift = data.dAg[3:] @ v
    np.testing.assert_allclose(rows @ a + drift, -4.0 * _momentum(q, v), atol=1e-8)


@given(st.floats(-1.2, 1.2), st.floats(-1.2, 1.2), st.floats(-3.0, 3.0), st.floats(0.0, 0.5))
def test_the_tilt_is_measured_from_the_plans_pelvis(roll, pitch, yaw, extra):
    planned = rpy_to_matrix(np.array([roll, pitch, yaw]))
    assert tilt_from(planned, planned) < 1e-6
    # A further lean about the planned pelvis's own x axis by `extra` tilts it by that much.
    leaned = planned @ rpy_to_matrix(np.array([extra, 0.0, 0.0]))
    assert abs(tilt_from(leaned, planned) - extra) < 1e-6
    # A turn about the vertical is no tilt.
    turned = rpy_to_matrix(np.array([0.0, 0.0, 0.7])) @ rpy_to_matrix(np.array([0, 0, yaw]))
    assert tilt_from(turned, rpy_to_matrix(np.array([0, 0, yaw]))) < 1e-6


def test_a_negative_momentum_gain_is_refused():
    cfg = ExecuteCfg(angular_momentum=MomentumCfg(weight=1.0, gain=-1.0))
    assert [name for name, _ in cfg.check()] == ["angular_momentum"]


def test_touchdown_heights_are_read_where_the_plan_puts_a_foot_down():
    contact = np.array([[1, 1], [1, 0], [1, 0], [1, 1], [0, 1], [1, 1]], dtype=bool)
    planned = np.zeros((6, 2, 3))
    soles = np.zeros((6, 2, 3))
    soles[3, 1, 2] = 0.02  # the right foot 2 cm up when the plan lands it at sample 3
    soles[5, 0, 2] = -0.001  # the left one 1 mm into the floor at sample 5
    heights = touchdown_heights(contact, soles, planned)
    assert heights == [0.02, -0.001]
