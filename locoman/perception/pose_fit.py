"""3D human pose from 2D keypoints: the demonstrator's model fitted to R_g (paper A, [25]).

An image from outside the renderer (the ``folder`` backend, a diffusion model) has no true
pose. This estimator fits the root pose and the 36 joint angles of the human model that the
rest of the pipeline uses to the 2D keypoints, through intrinsics K, in the manner of
SMPLify: minimise the confidence-weighted reprojection error [px] with the joint limits as
bounds and a pull towards the seed posture. The model's fixed limb lengths give the depth:
with paper A's heuristic K (focal length = resolution) a wrong focal length becomes a wrong
distance, which contact transfer's anchoring to the depth cloud absorbs.

Monocular fitting is ambiguous (a forearm towards or away from the camera projects alike), so
the fit starts from several seeds (facing directions about the camera's up, upright and
crouched) and keeps the one with the smallest reprojection error.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
from scipy.optimize import lsq_linear

from locoman.errors import InputError
from locoman.perception.demonstrator import (
    CROUCH,
    KEYPOINTS,
    LOCAL_FORWARD,
    LOCAL_UP,
    REACH,
    keypoints_world,
    point_jacobian,
)
from locoman.scene import human

SEED_ELEVATION_RAD = np.deg2rad(15.0)  # the camera looks down at the person by about this
SEED_FACINGS = 8  # facing directions tried about the camera's up
MIN_KEYPOINTS = 6  # fewer keypoints leave the root pose undetermined


@dataclass(frozen=True)
class PoseFitCfg:
    """Settings of the fit.

    Attributes:
        iterations: Gauss-Newton iterations per seed.
        posture_weight_px_per_rad: A joint 1 rad from its seed costs as much as this
            reprojection error [px/rad].
        damping: Levenberg-Marquardt damping of every step [px^2 per unit^2].
        tol_px: Stop a seed when a step lowers the cost by less than this squared [px^2].
    """

    iterations: int = 60
    posture_weight_px_per_rad: float = 10.0
    damping: float = 1.0
    tol_px: float = 1e-3


@dataclass(frozen=True)
class PoseFit:
    """A fitted pose.

    Attributes:
        qpos: MuJoCo qpos (43,) of the human model in R_g's camera frame: pelvis position
            [m], quaternion (w, x, y, z), 36 joint angles [rad].
        rms_px: Weighted RMS reprojection error of the keypoints found [px].
    """

    qpos: np.ndarray
    rms_px: float


def _seed_rotation(facing_angle: float) -> np.ndarray:
    """Root rotation (3, 3) in the camera frame: the model's up along the camera's estimate
    of the world's up, its facing ``facing_angle`` [rad] about it (0: towards the camera)."""
    e = SEED_ELEVATION_RAD
    up = np.array([0.0, -np.cos(e), -np.sin(e)])
    towards_camera = np.array([0.0, np.sin(e), -np.cos(e)])  # horizontal, at the camera
    side = np.cross(up, towards_camera)
    facing = np.cos(facing_angle) * towards_camera + np.sin(facing_angle) * side
    # Columns: where the model's local axes go. Model: LOCAL_FORWARD = x, LOCAL_UP = y.
    local = np.column_stack([LOCAL_FORWARD, LOCAL_UP, np.cross(LOCAL_FORWARD, LOCAL_UP)])
    world = np.column_stack([facing, up, np.cross(facing, up)])
    return world @ local.T


def _initial_depth(px: np.ndarray, ok: np.ndarray, K: np.ndarray, model: mujoco.MjModel) -> float:
    """Distance [m] at which the least foreshortened bone of the upright model spans its
    length in pixels: z = f L / l."""
    q = np.zeros(model.nq)
    q[3:7] = human.UPRIGHT_QUAT_WXYZ
    rest = keypoints_world(model, q)
    names = list(KEYPOINTS)
    bones = [
        ("left_shoulder", "right_shoulder"),
        ("left_hip", "right_hip"),
        ("pelvis", "neck"),
        ("left_hip", "left_knee"),
        ("right_hip", "right_knee"),
        ("left_shoulder", "left_elbow"),
        ("right_shoulder", "right_elbow"),
    ]
    f = 0.5 * (K[0, 0] + K[1, 1])
    depths = []
    for a, b in bones:
        i, j = names.index(a), names.index(b)
        if ok[i] and ok[j]:
            span = float(np.linalg.norm(px[i] - px[j]))
            if span > 1.0:
                depths.append(f * float(np.linalg.norm(rest[i] - rest[j])) / span)
    if not depths:
        raise InputError("too few keypoints on the body's bones to place the person")
    return float(min(depths))


def _seed_qpos(
    model: mujoco.MjModel,
    rotation: np.ndarray,
    pelvis_cam: np.ndarray,
    joints: dict[str, float],
) -> np.ndarray:
    q = np.zeros(model.nq)
    q[:3] = pelvis_cam
    mujoco.mju_mat2Quat(q[3:7], rotation.ravel())
    for name, value in joints.items():
        q[model.jnt_qposadr[model.joint(name).id]] = value
    return q


def _reprojection(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    q: np.ndarray,
    keypoints: list[tuple[int, np.ndarray]],
    px: np.ndarray,
    K: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Reprojection errors px - uv(q) (2 n,) [px] of the keypoints (body, offset) and the
    Jacobian d uv / d v (2 n, nv) [px per unit of v]."""
    data.qpos[:] = q
    mujoco.mj_kinematics(model, data)
    mujoco.mj_comPos(model, data)
    rows, errs = [], []
    for (body, offset), target in zip(keypoints, px, strict=True):
        p, jac = point_jacobian(model, data, body, offset)
        z = max(p[2], 0.05)  # a point behind the camera pulls forward, not across
        uv = K[:2, :2] @ (p[:2] / z) + K[:2, 2] - 0.5  # pixel index coordinates
        d_uv = np.array(
            [
                [K[0, 0] / z, 0.0, -K[0, 0] * p[0] / z**2],
                [0.0, K[1, 1] / z, -K[1, 1] * p[1] / z**2],
            ]
        )
        rows.append(d_uv @ jac)
        errs.append(target - uv)
    return np.concatenate(errs), np.vstack(rows)


def _fit_from(
    model: mujoco.MjModel,
    q0: np.ndarray,
    px: np.ndarray,
    weight: np.ndarray,
    K: np.ndarray,
    cfg: PoseFitCfg,
) -> tuple[np.ndarray, float]:
    """Levenberg-Marquardt from ``q0`` with the joint limits as bounds on every step.

    Cost: sum_k w_k |px_k - project(p_k(q))|^2 + posture_weight^2 |q_joints - q0_joints|^2.
    Returns the qpos and the weighted RMS reprojection error [px].
    """
    data = mujoco.MjData(model)
    hinges = [j for j in range(model.njnt) if model.jnt_limited[j]]
    dof, adr = model.jnt_dofadr[hinges], model.jnt_qposadr[hinges]
    lo_q, hi_q = model.jnt_range[hinges, 0], model.jnt_range[hinges, 1]
    used = np.flatnonzero(weight > 0.0)
    names = np.array(list(KEYPOINTS))[used]
    keypoints = [(model.body(KEYPOINTS[n][0]).id, KEYPOINTS[n][1]) for n in names]
    sqrt_w = np.repeat(np.sqrt(weight[used]), 2)
    wp = cfg.posture_weight_px_per_rad

    def cost(q: np.ndarray) -> tuple[float, np.ndarray, np.ndarray, np.ndarray]:
        err, jac = _reprojection(model, data, q, keypoints, px[used], K)
        to_seed = np.zeros(model.nv)
        mujoco.mj_differentiatePos(model, to_seed, 1.0, q, q0)
        prior = wp * to_seed[6:]
        err = sqrt_w * err
        return float(err @ err + prior @ prior), err, sqrt_w[:, None] * jac, prior

    q, damping = q0.copy(), cfg.damping
    c, err, jac, prior = cost(q)
    for _ in range(cfg.iterations):
        # Minimise |err - jac dq|^2 + |prior - wp dq_joints|^2 + damping |dq|^2.
        A = np.vstack([jac, wp * np.eye(model.nv)[6:], np.sqrt(damping) * np.eye(model.nv)])
        b = np.concatenate([err, prior, np.zeros(model.nv)])
        lo, hi = np.full(model.nv, -np.inf), np.full(model.nv, np.inf)
        lo[dof], hi[dof] = lo_q - q[adr], hi_q - q[adr]
        dq = lsq_linear(A, b, bounds=(np.minimum(lo, 0.0), np.maximum(hi, 0.0))).x
        trial = q.copy()
        mujoco.mj_integratePos(model, trial, dq, 1.0)
        trial[adr] = np.clip(trial[adr], lo_q, hi_q)
        trial[2] = max(trial[2], 0.3)  # the person stays in front of the camera
        c_new, err_new, jac_new, prior_new = cost(trial)
        if c_new < c:
            improvement = c - c_new
            q, c, err, jac, prior = trial, c_new, err_new, jac_new, prior_new
            damping = max(damping / 3.0, 1e-3)
            if improvement < cfg.tol_px**2:
                break
        else:
            damping *= 10.0
            if damping > 1e8:
                break
    rms = float(np.sqrt(np.sum(err**2) / np.sum(weight[used])))
    return q, rms


def fit_pose(
    model: mujoco.MjModel,
    keypoints_px: np.ndarray,
    confidence: np.ndarray,
    K: np.ndarray,
    cfg: PoseFitCfg = PoseFitCfg(),
) -> PoseFit:
    """Fit the human model to the 2D keypoints (K, 2) [px] of :data:`KEYPOINTS` (NaN: not
    found), weighted by ``confidence`` [0, 1], through intrinsics ``K`` [px].

    Raises:
        InputError: When fewer than :data:`MIN_KEYPOINTS` keypoints were found.
    """
    ok = np.all(np.isfinite(keypoints_px), axis=1) & (confidence > 0.0)
    if ok.sum() < MIN_KEYPOINTS:
        raise InputError(
            f"the 3D pose fit needs at least {MIN_KEYPOINTS} 2D keypoints, found {int(ok.sum())}: "
            "check the person is in the image (or add keypoints_px to its annotations)"
        )
    px = np.where(ok[:, None], keypoints_px, 0.0)
    weight = np.where(ok, confidence, 0.0)
    z = _initial_depth(px, ok, K, model)
    names = list(KEYPOINTS)
    pelvis_px = px[names.index("pelvis")] if ok[names.index("pelvis")] else px[ok].mean(axis=0)
    ray = np.linalg.solve(K, np.array([pelvis_px[0] + 0.5, pelvis_px[1] + 0.5, 1.0]))
    best: tuple[np.ndarray, float] | None = None
    for joints in (REACH, CROUCH):
        for k in range(SEED_FACINGS):
            rotation = _seed_rotation(2.0 * np.pi * k / SEED_FACINGS)
            seed = _seed_qpos(model, rotation, ray * z, joints)
            q, rms = _fit_from(model, seed, px, weight, K, cfg)
            if best is None or rms < best[1]:
                best = (q, rms)
    assert best is not None
    return PoseFit(qpos=best[0], rms_px=best[1])


def human_model() -> mujoco.MjModel:
    """The demonstrator's MuJoCo model (names without prefix), as the fit uses it."""
    return human.human_mjspec(prefix="").compile()
