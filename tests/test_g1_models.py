"""The G1's MuJoCo and Pinocchio models agree (link poses, CoM, mass)."""

from __future__ import annotations

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from locoman.scene import g1, rotations


@pytest.fixture(scope="module")
def models():
    return g1.g1_pinocchio_model(), g1.g1_mjmodel()


def _random_q35(rng: np.random.Generator, pmodel: pin.Model) -> np.ndarray:
    lo = pmodel.lowerPositionLimit[7:]
    hi = pmodel.upperPositionLimit[7:]
    base = np.r_[rng.uniform(-1, 1, 3), rng.uniform(-np.pi, np.pi, 3)]
    base[4] = rng.uniform(-1.4, 1.4)
    return np.r_[base, rng.uniform(lo, hi)]


@pytest.mark.parametrize("seed", range(5))
def test_link_poses_and_com_agree(models, seed):
    pmodel, mmodel = models
    pdata, mdata = pmodel.createData(), mujoco.MjData(mmodel)
    rng = np.random.default_rng(seed)
    q = g1.q35_to_pin(_random_q35(rng, pmodel))
    mdata.qpos[:] = g1.pin_to_mujoco_qpos(q, mmodel, mdata.qpos)
    mujoco.mj_forward(mmodel, mdata)
    pin.framesForwardKinematics(pmodel, pdata, q)
    com = pin.centerOfMass(pmodel, pdata, q)
    compared = 0
    for b in range(1, mmodel.nbody):
        name = mmodel.body(b).name
        if not pmodel.existFrame(name, pin.FrameType.BODY):
            continue
        oMf = pdata.oMf[pmodel.getFrameId(name, pin.FrameType.BODY)]
        np.testing.assert_allclose(mdata.xpos[b], oMf.translation, atol=1e-6, err_msg=name)
        np.testing.assert_allclose(
            mdata.xmat[b].reshape(3, 3), oMf.rotation, atol=1e-6, err_msg=name
        )
        compared += 1
    assert compared >= 30
    pelvis = mmodel.body(g1.BASE_LINK).id
    np.testing.assert_allclose(mdata.subtree_com[pelvis], com, atol=1e-6)


def test_total_mass_agrees(models):
    pmodel, mmodel = models
    pelvis = mmodel.body(g1.BASE_LINK).id
    assert mmodel.body_subtreemass[pelvis] == pytest.approx(pin.computeTotalMass(pmodel), abs=1e-9)


def test_q35_round_trip():
    rng = np.random.default_rng(3)
    q35 = np.r_[rng.uniform(-1, 1, 3), 0.3, -0.7, 2.5, rng.uniform(-1, 1, 29)]
    np.testing.assert_allclose(g1.pin_to_q35(g1.q35_to_pin(q35)), q35, atol=1e-12)
    rot = rotations.rpy_to_matrix(q35[3:6])
    np.testing.assert_allclose(rot, pin.rpy.rpyToMatrix(*q35[3:6]), atol=1e-12)


def test_standing_posture_puts_soles_on_floor():
    q35 = g1.standing_q35()
    np.testing.assert_allclose(g1.sole_heights(q35), [0.0, 0.0], atol=1e-9)
    assert 0.6 < q35[2] < 0.85


def test_collision_geometry_is_primitives_and_standing_pose_is_free(models):
    _, mmodel = models
    colliding = [i for i in range(mmodel.ngeom) if mmodel.geom_contype[i]]
    assert all(mmodel.geom_type[i] != mujoco.mjtGeom.mjGEOM_MESH for i in colliding)
    feet = {
        mmodel.geom(i).name for i in colliding if mmodel.geom_type[i] == mujoco.mjtGeom.mjGEOM_BOX
    }
    assert feet == {"left_foot", "right_foot"}
    data = mujoco.MjData(mmodel)
    data.qpos[:] = g1.pin_to_mujoco_qpos(g1.q35_to_pin(g1.standing_q35()), mmodel, data.qpos)
    mujoco.mj_forward(mmodel, data)
    assert data.ncon == 0, "the standing posture self-collides"


def test_capsule_fit_encloses_points():
    rng = np.random.default_rng(0)
    pts = rng.normal(size=(400, 3)) * [0.02, 0.03, 0.12] + [0.1, -0.2, 0.3]
    fit = g1.fit_capsule(pts)
    rot = np.zeros(9)
    mujoco.mju_quat2Mat(rot, fit.quat_wxyz)
    local = (pts - fit.pos) @ rot.reshape(3, 3)
    t = np.clip(local[:, 2], -fit.half_length, fit.half_length)
    dist = np.linalg.norm(local - np.c_[np.zeros((len(t), 2)), t], axis=1)
    assert dist.max() <= fit.radius + 1e-9
