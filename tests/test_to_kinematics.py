"""Symbolic kinematics for CasADi against Pinocchio at random configurations."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pinocchio as pin
import pytest

from locoman.scene import g1, rotations
from locoman.to.terms.kinematics import (
    SymbolicKinematics,
    euler_rates_to_world,
    pin_configuration,
    pin_velocity,
    rpy_matrix,
)

FRAMES = ("pelvis", "torso_link", "left_rubber_hand", "right_ankle_roll_link", "head_link")


@pytest.fixture(scope="module")
def kinematics() -> SymbolicKinematics:
    return SymbolicKinematics(g1.g1_pinocchio_model())


@pytest.fixture(scope="module")
def functions(kinematics):
    k = kinematics
    outputs = [k.com(), k.centroidal_momentum()]
    for name in FRAMES:
        R, p = k.frame_pose(name)
        outputs += [R, p]
    for name in FRAMES:
        outputs += list(k.frame_velocity(name))
    return ca.Function("kinematics", [k.q, k.v], outputs)


def _random_state(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    model = g1.g1_pinocchio_model()
    lo, hi = model.lowerPositionLimit[7:], model.upperPositionLimit[7:]
    q = np.concatenate([rng.uniform(-1, 1, 3), rng.uniform(-1.2, 1.2, 3), rng.uniform(lo, hi)])
    return q, rng.normal(size=35)


def test_rpy_and_euler_rate_map_match_finite_differences():
    rng = np.random.default_rng(0)
    rpy, rate = rng.uniform(-1.2, 1.2, 3), rng.normal(size=3)
    R = rpy_matrix(ca.DM(rpy)).full()
    np.testing.assert_allclose(R, rotations.rpy_to_matrix(rpy), atol=1e-12)
    h = 1e-6
    R_dot = (rotations.rpy_to_matrix(rpy + h * rate) - rotations.rpy_to_matrix(rpy - h * rate)) / (
        2 * h
    )
    skew = R_dot @ R.T
    omega = np.array([skew[2, 1], skew[0, 2], skew[1, 0]])
    np.testing.assert_allclose(euler_rates_to_world(ca.DM(rpy)).full() @ rate, omega, atol=1e-8)


def test_frames_and_com_match_pinocchio(kinematics, functions):
    model = g1.g1_pinocchio_model()
    data = model.createData()
    rng = np.random.default_rng(1)
    for _ in range(5):
        q, v = _random_state(rng)
        out = functions(q, v)
        q_pin = pin_configuration(q)
        pin.framesForwardKinematics(model, data, q_pin)
        np.testing.assert_allclose(
            out[0].full().ravel(), pin.centerOfMass(model, data, q_pin), atol=1e-9
        )
        for k, name in enumerate(FRAMES):
            pose = data.oMf[model.getFrameId(name)]
            np.testing.assert_allclose(out[2 + 2 * k].full(), pose.rotation, atol=1e-9)
            np.testing.assert_allclose(out[3 + 2 * k].full().ravel(), pose.translation, atol=1e-9)


def test_centroidal_momentum_matches_pinocchio(functions):
    model = g1.g1_pinocchio_model()
    data = model.createData()
    rng = np.random.default_rng(2)
    for _ in range(5):
        q, v = _random_state(rng)
        h = functions(q, v)[1].full().ravel()
        momentum = pin.computeCentroidalMomentum(
            model, data, pin_configuration(q), pin_velocity(q, v)
        )
        np.testing.assert_allclose(h[:3], momentum.linear, atol=1e-8)
        np.testing.assert_allclose(h[3:], momentum.angular, atol=1e-8)


def test_frame_velocities_match_pinocchio(functions):
    model = g1.g1_pinocchio_model()
    data = model.createData()
    rng = np.random.default_rng(3)
    first = 2 + 2 * len(FRAMES)
    for _ in range(3):
        q, v = _random_state(rng)
        out = functions(q, v)
        pin.forwardKinematics(model, data, pin_configuration(q), pin_velocity(q, v))
        pin.updateFramePlacements(model, data)
        for k, name in enumerate(FRAMES):
            motion = pin.getFrameVelocity(
                model, data, model.getFrameId(name), pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
            )
            np.testing.assert_allclose(out[first + 2 * k].full().ravel(), motion.angular, atol=1e-9)
            np.testing.assert_allclose(
                out[first + 2 * k + 1].full().ravel(), motion.linear, atol=1e-9
            )


def test_unknown_frame_is_named(kinematics):
    with pytest.raises(KeyError, match="no_such_link"):
        kinematics.frame_pose("no_such_link")
