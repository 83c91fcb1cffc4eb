"""The whole-body tracking controller: a task-space inverse-dynamics QP (TSID's formulation).

Unknowns x = (a, w): the joint accelerations a (35,) [m/s^2, rad/s^2] and the wrench w_c (6,)
[N, N m] of each stance foot at its sole centre, world axes. The torques follow from them:

    M a + h = S^T tau + sum_c J_c^T w_c + sum_h J_h^T w_h         floating-base dynamics

where w_h is the TO's wrench of the held object on each hand (the object is not in the model;
the plan's force is fed forward and MuJoCo's contact returns what the object really pushes).

    min  sum_t weight_t |A_t a - b_t|^2 + force_weight |w - w_TO|_W^2 + eps |a|^2
    s.t. M_b a - J_c,b^T w = -h_b + J_h,b^T w_h           6 rows: the base is unactuated
         J_c a + J_dot_c v = -kd J_c v                    6 rows per stance foot
         C_c w_c <= d_c                                   the sole's contact wrench cone
         |M_j a + h_j - J_c,j^T w - J_h,j^T w_h| <= tau_max   29 rows: torque limits

W (:func:`wrench_metric`) weighs a moment as the force that makes it at the sole's edge. The
tasks t are those of :mod:`locoman.execute.tasks`: the centre of mass, the centroidal angular
momentum, the pelvis's and the torso's orientations, each swing foot's and each hand's pose,
the joints' posture. DAQP solves the dense QP (about 47 unknowns;
``benchmarks/execute_step.py`` measures it).
"""

from __future__ import annotations

import dataclasses
import time

import daqp
import numpy as np
import pinocchio as pin

from locoman.config.execute import ExecuteCfg, TaskCfg
from locoman.errors import SolverError
from locoman.execute.contacts import local_wrench_rows, world_wrench_rows, wrench_bounds
from locoman.execute.model import BASE, PALMS, SOLES, TORSO, torque_limits
from locoman.execute.reference import Reference
from locoman.execute.tasks import angular_momentum_rows, pd_target, pose_error, posture_rows

_WORLD = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
_EQUALITY = 5  # DAQP's sense: active and immutable
_REGULARISATION = 1e-6  # on a: keeps H positive definite where no task reaches a joint


@dataclasses.dataclass(frozen=True)
class Command:
    """One control step's result.

    Attributes:
        tau: (29,) joint torques [N m].
        a: (35,) the accelerations the QP chose [m/s^2, rad/s^2].
        foot_wrench: (2, 6) each foot's wrench (world axes, at the sole centre) [N, N m];
            zero for a swing foot.
        stance: (2,) which feet the QP held on the ground.
        limits_dropped: The QP had no solution within the torque limits and was solved
            without them (the torques are clipped to the limits all the same).
        solve_time_s: The QP's assembly and solve [s].
    """

    tau: np.ndarray
    a: np.ndarray
    foot_wrench: np.ndarray
    stance: np.ndarray
    limits_dropped: bool
    solve_time_s: float


def wrench_metric(moment_arm: np.ndarray, rotation: np.ndarray) -> np.ndarray:
    """(6, 6) W of the wrench regularisation |w - w_TO|_W^2, world axes: a moment counts as
    the force that makes it at the sole's edge (tau_x / Y, tau_y / X, tau_z / (mu max(X, Y))
    in the sole's frame ``rotation``). With an identity W a moment of 1 N m costs what 1 N
    does, the least-norm wrench puts each foot's CoP on its edge, and MuJoCo's foot rolls."""
    local = np.diag(np.r_[np.ones(3), 1.0 / np.asarray(moment_arm) ** 2])
    turn = np.zeros((6, 6))
    turn[:3, :3] = turn[3:, 3:] = rotation
    return turn @ local @ turn.T


class InverseDynamicsQp:
    """Builds and solves the QP above at each control step.

    Args:
        model: The G1's Pinocchio model with the contact frames
            (:func:`locoman.execute.model.execution_model`).
        cfg: Gains, weights and limits.
        sole_half_extents: (2,) the sole's half length and half width [m].
        friction: The floor's friction coefficient the TO planned with [-].
    """

    def __init__(
        self, model: pin.Model, cfg: ExecuteCfg, sole_half_extents: np.ndarray, friction: float
    ) -> None:
        self.model = model
        self.data = model.createData()
        self.cfg = cfg
        self.nv = model.nv
        self.tau_max = cfg.torque_margin * torque_limits(model)
        self._soles = [model.getFrameId(name) for name in SOLES]
        self._palms = [model.getFrameId(name) for name in PALMS]
        self._base = model.getFrameId(BASE)
        self._torso = model.getFrameId(TORSO)
        self._cone = local_wrench_rows(
            friction, cfg.support_scale * np.asarray(sole_half_extents, dtype=float)
        )
        self._cone_bound = wrench_bounds(cfg.min_normal_force_n)
        half = np.asarray(sole_half_extents, dtype=float)
        # A moment about the sole's x axis moves the CoP along y, and so on (wrench_metric).
        self._moment_arm = np.array([half[1], half[0], friction * half.max()])
        self._zero = np.zeros(self.nv)

    def _frame(self, frame: int, q: np.ndarray) -> tuple[np.ndarray, ...]:
        """(J (6, nv), position, rotation, velocity (6,), drift (6,)) of a frame, world axes
        (after :meth:`_kinematics`)."""
        m, d = self.model, self.data
        jac = pin.getFrameJacobian(m, d, frame, _WORLD)
        pose = d.oMf[frame]
        velocity = pin.getFrameVelocity(m, d, frame, _WORLD).vector
        drift = pin.getFrameClassicalAcceleration(m, d, frame, _WORLD).vector
        return jac, pose.translation, pose.rotation, velocity, drift

    def _kinematics(self, q: np.ndarray, v: np.ndarray) -> None:
        m, d = self.model, self.data
        pin.computeAllTerms(m, d, q, v)  # M, h, joint Jacobians, com, vcom, Jcom
        pin.computeCentroidalMapTimeVariation(m, d, q, v)  # A_G, dA_G/dt
        pin.forwardKinematics(m, d, q, v, self._zero)  # drifts: accelerations at a = 0
        pin.updateFramePlacements(m, d)
        pin.centerOfMass(m, d, q, v, self._zero)

    def _task(
        self, rows: list, cfg: TaskCfg, frame: tuple[np.ndarray, ...], ref, i: int, sl: slice
    ) -> None:
        jac, p, R, vel, drift = frame
        error = pose_error(p, R, ref.position[i], ref.rotation[i])
        b = pd_target(cfg, error, vel, ref.velocity[i], ref.acceleration[i], drift)
        rows.append((cfg.weight, jac[sl], b[sl]))

    def step(self, q: np.ndarray, v: np.ndarray, ref: Reference, i: int) -> Command:
        """The torques at state (q (36,), v (35,)) for the reference's sample ``i``.

        Raises:
            SolverError: If DAQP finds the QP infeasible.
        """
        start = time.perf_counter()
        cfg, d, nv = self.cfg, self.data, self.nv
        self._kinematics(q, v)
        mass_matrix = np.triu(d.M) + np.triu(d.M, 1).T
        h = d.nle
        stance = ref.foot_contact[i]
        feet = [self._frame(f, q) for f in self._soles]
        palms = [self._frame(f, q) for f in self._palms]
        # Tasks.
        rows: list[tuple[float, np.ndarray, np.ndarray]] = []
        com_b = pd_target(
            cfg.com,
            ref.com[i] - d.com[0],
            d.vcom[0],
            ref.com_velocity[i],
            ref.com_acceleration[i],
            d.acom[0],
        )
        rows.append((cfg.com.weight, d.Jcom, com_b))
        base = self._frame(self._base, q)
        self._task(rows, cfg.base_orientation, base, ref.frames[BASE], i, slice(3, 6))
        torso = self._frame(self._torso, q)
        self._task(rows, cfg.torso_orientation, torso, ref.frames[TORSO], i, slice(3, 6))
        for k, name in enumerate(SOLES):
            if not stance[k]:
                self._task(rows, cfg.swing_foot, feet[k], ref.frames[name], i, slice(0, 6))
        for k, name in enumerate(PALMS):
            self._task(rows, cfg.hand, palms[k], ref.frames[name], i, slice(0, 6))
        a_mom, b_mom = angular_momentum_rows(cfg.angular_momentum, d.Ag, d.dAg, v)
        rows.append((cfg.angular_momentum.weight, a_mom, b_mom))
        a_post, b_post = posture_rows(cfg.posture, q, v, ref.q[i], ref.v[i], ref.a[i])
        rows.append((cfg.posture.weight, a_post, b_post))
        # Cost over x = (a, w).
        active = [k for k in range(2) if stance[k]]
        nw = 6 * len(active)
        n = nv + nw
        hessian = np.zeros((n, n))
        gradient = np.zeros(n)
        for weight, a_rows, b in rows:
            hessian[:nv, :nv] += weight * a_rows.T @ a_rows
            gradient[:nv] -= weight * a_rows.T @ b
        hessian[:nv, :nv] += _REGULARISATION * np.eye(nv)
        for c, k in enumerate(active):
            block = slice(nv + 6 * c, nv + 6 * c + 6)
            weight = cfg.force_weight * wrench_metric(self._moment_arm, feet[k][2])
            hessian[block, block] += weight
            gradient[block] -= weight @ ref.foot_wrench[i, k]
        # The held objects' planned wrenches, as generalised forces.
        external = np.zeros(nv)
        for k in range(2):
            if ref.hand_object[i, k] >= 0:
                external += palms[k][0].T @ ref.hand_wrench[i, k]
        contact_jt = np.zeros((nv, nw))
        for c, k in enumerate(active):
            contact_jt[:, 6 * c : 6 * c + 6] = feet[k][0].T
        # Constraints.
        dyn = np.hstack([mass_matrix, -contact_jt])  # M a - J_c^T w = S^T tau - h + J_h^T w_h
        bias = external - h
        blocks = [dyn[:6]]
        upper = [bias[:6]]
        lower = [bias[:6]]
        sense = [np.full(6, _EQUALITY)]
        for c, k in enumerate(active):
            jac, _, _, vel, drift = feet[k]
            rows_c = np.zeros((6, n))
            rows_c[:, :nv] = jac
            target = -drift - cfg.contact_kd * vel
            blocks.append(rows_c)
            upper.append(target)
            lower.append(target)
            sense.append(np.full(6, _EQUALITY))
            cone = np.zeros((len(self._cone), n))
            cone[:, nv + 6 * c : nv + 6 * c + 6] = world_wrench_rows(self._cone, feet[k][2])
            blocks.append(cone)
            upper.append(self._cone_bound)
            lower.append(np.full(len(self._cone), -1e20))
            sense.append(np.zeros(len(self._cone), dtype=int))
        blocks.append(dyn[6:])
        upper.append(self.tau_max + bias[6:])
        lower.append(-self.tau_max + bias[6:])
        sense.append(np.zeros(nv - 6, dtype=int))
        a_con = np.vstack(blocks)
        bu, bl = np.concatenate(upper), np.concatenate(lower)
        senses = np.concatenate(sense).astype(np.int32)
        x, _, flag, _ = daqp.solve(hessian, gradient, a_con, bu, bl, senses)
        dropped = flag < 0
        if dropped:
            # No torques within the limits can hold the contacts (a landing foot's impact,
            # a motion beyond a joint's limit): solve without the limits, MuJoCo's motors
            # clip the torques, and the step is counted (Command.limits_dropped).
            rows = len(a_con) - (nv - 6)
            x, _, flag, _ = daqp.solve(
                hessian, gradient, a_con[:rows], bu[:rows], bl[:rows], senses[:rows]
            )
        if flag < 0:
            raise SolverError(
                f"the inverse-dynamics QP has no solution at t = {ref.time[i]:.3f} s, even "
                f"without the torque limits (DAQP exit flag {flag}): the contact constraints "
                "contradict each other there"
            )
        a = x[:nv]
        tau = (dyn[6:] @ x) - bias[6:]
        tau = np.clip(tau, -self.tau_max, self.tau_max)
        wrench = np.zeros((2, 6))
        for c, k in enumerate(active):
            wrench[k] = x[nv + 6 * c : nv + 6 * c + 6]
        return Command(tau, a, wrench, stance.copy(), dropped, time.perf_counter() - start)
