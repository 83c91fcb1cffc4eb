"""The TO's arm torque bound (locoman.to.terms.actuation): the static torques it bounds
against Pinocchio's RNEA with the hand's wrench as an external force."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pinocchio as pin
from hypothesis import given, settings
from hypothesis import strategies as st

from locoman.config.to import ContactCfg
from locoman.retarget.robot import contact_frames
from locoman.scene import g1
from locoman.to.terms.actuation import ARM_JOINTS, arm_columns, arm_limits, arm_torques

_MODEL = g1.g1_pinocchio_model()


def _pinocchio_arm_torques(q: np.ndarray, side: int, wrench: np.ndarray) -> tuple:
    """(tau of the arm's joints by RNEA at rest, the palm's frame R, the contact point in
    it) with ``wrench`` (world axes, about the contact point) on the hand."""
    data = _MODEL.createData()
    pin.framesForwardKinematics(_MODEL, data, q)
    frames = contact_frames()
    name = ("left_palm", "right_palm")[side]
    hand = _MODEL.getFrameId(g1.HAND_LINKS[side])
    R = data.oMf[hand].rotation @ frames.palm_axes[name]
    point = np.array([0.0, 0.0, frames.palm_radius])
    contact = data.oMf[hand].act(frames.palm[name]) + R @ point
    joint = _MODEL.frames[hand].parentJoint
    placement = data.oMi[joint]
    moment = wrench[3:] + np.cross(contact - placement.translation, wrench[:3])
    fext = [pin.Force.Zero() for _ in range(_MODEL.njoints)]
    fext[joint] = pin.Force(placement.rotation.T @ wrench[:3], placement.rotation.T @ moment)
    zero = np.zeros(_MODEL.nv)
    tau = pin.rnea(_MODEL, data, q, zero, zero, fext)
    columns = [_MODEL.joints[_MODEL.getJointId(n)].idx_v for n in ARM_JOINTS[side]]
    return tau[columns], R, point


@settings(max_examples=20, deadline=None)
@given(st.integers(0, 10_000), st.sampled_from([0, 1]))
def test_the_static_arm_torques_are_pinocchios(seed, side):
    rng = np.random.default_rng(seed)
    q = pin.neutral(_MODEL)
    q[:3] = rng.normal(0.0, 0.3, 3)
    q[3:7] = pin.Quaternion(pin.rpy.rpyToMatrix(*rng.normal(0.0, 0.4, 3))).coeffs()
    q[7:] = rng.normal(0.0, 0.5, _MODEL.nq - 7)
    wrench = np.r_[rng.normal(0.0, 30.0, 3), rng.normal(0.0, 3.0, 3)]
    expected, R, point = _pinocchio_arm_torques(q, side, wrench)
    q_arm = g1.pin_to_q35(q)[arm_columns(side)]
    ours = arm_torques(_MODEL, side, ca.DM(q_arm), ca.DM(R), ca.DM(wrench), ca.DM(point))
    np.testing.assert_allclose(np.array(ca.evalf(ours)).ravel(), expected, atol=1e-9)


def test_the_arms_limits_are_the_urdfs():
    np.testing.assert_array_equal(arm_limits(0), [25.0, 25.0, 25.0, 25.0, 25.0, 5.0, 5.0])
    np.testing.assert_array_equal(arm_limits(1), arm_limits(0))


def test_an_arm_torque_margin_outside_zero_to_one_is_refused():
    assert [n for n, _ in ContactCfg(arm_torque_margin=1.5).check()] == ["arm_torque_margin"]
    assert ContactCfg(arm_torque_margin=0.0).check() == []
