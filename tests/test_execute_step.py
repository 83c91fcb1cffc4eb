"""The benchmark's least grip (benchmarks/execute_step.py): the load the plan puts on two
palms, carried by friction with no internal shear."""

from __future__ import annotations

import numpy as np
from execute_step import least_grip
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from locoman.execute.model import PALMS
from locoman.execute.reference import FrameReference, Reference

MU = 0.8


def _two_palm_reference(wrench: np.ndarray, tilt: float) -> Reference:
    """One sample, both palms holding object 0, facing each other along y (tilted by
    ``tilt`` [rad] about x), the plan's hand wrenches ``wrench`` (2, 6)."""
    c, s = np.cos(tilt), np.sin(tilt)
    # The palm's z axis is its normal into the object: +y for the left palm, -y the right.
    left = np.array([[1.0, 0.0, 0.0], [0.0, s, c], [0.0, -c, s]])
    right = np.diag([1.0, -1.0, -1.0]) @ left
    frames = {
        name: FrameReference(R[None], R[None], np.zeros((1, 6)), np.zeros((1, 6)))
        for name, R in zip(PALMS, (left, right), strict=True)
    }
    zeros = np.zeros((1, 3))
    return Reference(
        time=np.zeros(1),
        q=np.zeros((1, 36)),
        v=np.zeros((1, 35)),
        a=np.zeros((1, 35)),
        com=zeros,
        com_velocity=zeros,
        com_acceleration=zeros,
        frames=frames,
        foot_contact=np.ones((1, 2), dtype=bool),
        foot_wrench=np.zeros((1, 2, 6)),
        hand_object=np.zeros((1, 2), dtype=int),
        hand_wrench=wrench[None],
        object_q=np.zeros((1, 1, 6)),
    )


_forces = st.lists(st.floats(-60.0, 60.0), min_size=12, max_size=12)


@settings(max_examples=50, deadline=None)
@given(_forces, st.floats(-0.3, 0.3))
def test_the_least_grip_keeps_the_load_and_sits_on_the_friction_cone(values, tilt):
    wrench = np.array(values).reshape(2, 6)
    assume(np.abs(wrench).sum(axis=1).min() > 0.0)  # both palms carry
    ref = _two_palm_reference(wrench, tilt)
    grip = least_grip(ref, MU).hand_wrench[0]
    np.testing.assert_allclose(grip[:, :3].sum(axis=0), wrench[:, :3].sum(axis=0), atol=1e-9)
    np.testing.assert_array_equal(grip[:, 3:], 0.0)
    for k, name in enumerate(PALMS):
        n = ref.frames[name].rotation[0, :, 2]
        push = -grip[k, :3] @ n  # the object pushes the palm back along -n
        tangential = np.linalg.norm(grip[k, :3] + push * n)
        assert push >= tangential / MU - 1e-9  # inside the cone
    # The least squeeze: one palm on its cone's edge unless the load alone grips.
    slack = []
    for k, name in enumerate(PALMS):
        n = ref.frames[name].rotation[0, :, 2]
        push = -grip[k, :3] @ n
        slack.append(push - np.linalg.norm(grip[k, :3] + push * n) / MU)
    shared = wrench[:, :3].sum(axis=0) / 2
    if np.allclose(grip[:, :3], shared):
        assert min(slack) >= -1e-9
    else:
        assert abs(min(slack)) < 1e-6


def test_a_one_handed_hold_keeps_the_plans_wrench():
    wrench = np.array([[1.0, 20.0, -30.0, 0.5, 0.0, 0.0], [0.0] * 6])
    ref = _two_palm_reference(wrench, 0.0)
    ref = type(ref)(**{**ref.__dict__, "hand_object": np.array([[0, -1]])})
    np.testing.assert_array_equal(least_grip(ref, MU).hand_wrench, ref.hand_wrench)
