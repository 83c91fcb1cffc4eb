"""The hierarchical QP (paper B, Sec. III-B) solved with DAQP's native hierarchy.

DAQP solves a lexicographic least-squares problem in one call: the simple bounds form the
first level, then each task level in order. A level's optimal residual is imposed on every
level below it (strict hierarchy, Kanoun et al. 2011), so level 2 can only use the freedom
level 1 leaves, and the minimum-norm velocity breaks the remaining ties.
"""

from __future__ import annotations

import daqp
import numpy as np

from locoman.errors import SolverError
from locoman.hqp.limits import JointLimits, VelocityBox
from locoman.hqp.tasks import ClikTask, wrap_angle

Task = tuple[np.ndarray, np.ndarray]


def weighted_objective(task: Task, weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(H, f) of min 1/2 ||W^{1/2} (A x - b)||^2 = 1/2 x^T H x + f^T x + const."""
    a, b = task
    return a.T @ (weights[:, None] * a), -a.T @ (weights * b)


class HierarchySolver:
    """Lexicographic least squares: the bounds, then one task level, then a weighted
    objective of fixed Hessian, with DAQP's workspace allocated once (``daqp.Model``): the
    1 kHz loop solves the same structure with new numbers, and the set-up is most of a
    solve's time.

    DAQP measures the residual of each row of a constraint level in that row's own norm
    (rows are normalised), so a level cannot weight its rows: the weighted lowest level is
    DAQP's objective (:func:`weighted_objective`), minimised over the optimal set of the
    levels above.

    Fill :attr:`lower` and :attr:`upper` (views into the QP's own bound vectors, so nothing
    is copied), then call :meth:`solve`.

    Args:
        hessian: (n, n) positive definite H of the objective 1/2 x^T H x + f^T x.
        rows: Rows m of the task level.

    Attributes:
        lower: (n,) lower bounds on x.
        upper: (n,) upper bounds on x.
    """

    def __init__(self, hessian: np.ndarray, rows: int) -> None:
        n = len(hessian)
        self._hessian = np.ascontiguousarray(hessian, dtype=float)
        self._n = n
        self._upper = np.zeros(n + rows)
        self._lower = np.zeros(n + rows)
        self.lower, self.upper = self._lower[:n], self._upper[:n]
        self._sense = np.zeros(n + rows, dtype=np.int32)
        self._breaks = np.array([n, n + rows], dtype=np.int32)
        self._model: daqp.Model | None = None

    def solve(self, level: Task, f: np.ndarray) -> np.ndarray:
        """x (n,) of the bounds, then ``level`` (A (m, n), b (m,)), then the objective's
        gradient f (n,).

        Raises:
            SolverError: If DAQP fails.
        """
        a, b = level
        n = self._n
        self._upper[n:] = b  # the level is an equality: b <= A x <= b
        self._lower[n:] = b
        if self._model is None:
            self._model = daqp.Model()
            self._model.setup(
                self._hessian, f, a, self._upper, self._lower, self._sense, self._breaks
            )
        else:
            # sense resets DAQP's working set: a warm start changes the last bits of qdot,
            # which the replay's grasp amplifies into 5e-6 m of RMSE (measured).
            # Positional (H unchanged): keyword parsing costs 0.7 us of a 30 us step.
            self._model.update(None, f, a, self._upper, self._lower, self._sense)
        x, _, flag, _ = self._model.solve()
        if flag < 0:
            raise SolverError(f"DAQP failed on the hierarchical QP (exit flag {flag})")
        return np.minimum(np.maximum(x, self.lower, out=x), self.upper, out=x)


class WholeBodyHqp:
    """The two-level stack of the mobile manipulator, with its integrated optimal state.

    Level 1: CLIK of the end-effector pose and velocity, eq. (4). Level 2: the learned base
    pose plus the arm's mid-range posture, eq. (6), as a weighted least-squares objective
    over level 1's optimal set. Both under the limits (7)-(9).

    Attributes:
        q_star: (10,) integrated optimal configuration q* (base x, y, yaw, arm 1..7).
        qdot_star: (10,) optimal velocity of the last step qdot*.
        last_level1: Level 1 (A, b) of the last step; overwritten by the next step.
    """

    def __init__(
        self,
        limits: JointLimits,
        dt: float,
        q0: np.ndarray,
        kp: float,
        kv: float,
        level2_gain: float,
        arm_mid_range_weight: float,
        measured_velocity_feedback: bool = False,
    ) -> None:
        self.limits = limits
        self.dt = dt
        self.kp = kp
        self.kv = kv
        self.level2_gain = level2_gain
        self.measured_velocity_feedback = measured_velocity_feedback
        self.weights = np.r_[np.ones(3), np.full(7, arm_mid_range_weight)]
        # Level 2's A stacks H_b and H_a: the identity, so its objective Hessian is W.
        self._qp = HierarchySolver(np.diag(self.weights), 6)
        # Level 2's goal (q_b,d, q_a,mid); f = -W g (goal - q*) is its objective's gradient.
        self._goal = np.r_[np.zeros(3), limits.arm_mid]
        self._f_scale = -self.weights * level2_gain
        self._f = np.zeros(10)
        self._dq = np.zeros(10)
        self._box = VelocityBox(limits, dt)
        self._clik = ClikTask(kp, kv)
        self.q_star = np.asarray(q0, dtype=float).copy()
        self.qdot_star = np.zeros(10)
        self.last_level1: Task | None = None

    def step(
        self,
        jacobian: np.ndarray,
        x_desired: tuple[np.ndarray, np.ndarray],
        xdot_desired: np.ndarray,
        x_actual: tuple[np.ndarray, np.ndarray],
        q_base_desired: np.ndarray,
        xdot_actual: np.ndarray | None = None,
    ) -> np.ndarray:
        """Solve the stack, integrate q* and return qdot* (10,)."""
        feedback = xdot_actual if self.measured_velocity_feedback else None
        level1 = self._clik(jacobian, x_desired, xdot_desired, x_actual, feedback)
        # Level 2's rows are the identity (H_b, H_a stacked), so only its target
        # g (goal - q*) is needed, as f = -W target (see weighted_objective).
        self._goal[:3] = q_base_desired
        f = np.subtract(self._goal, self.q_star, out=self._f)
        f[2] = wrap_angle(float(f[2]))
        f *= self._f_scale
        self._box(self.q_star, self.qdot_star, out=(self._qp.lower, self._qp.upper))
        qdot = self._qp.solve(level1, f)
        self.last_level1 = level1
        self.qdot_star = qdot
        # q* + qdot* dt in place: the same bits as the expression, without its allocations.
        np.add(self.q_star, np.multiply(qdot, self.dt, out=self._dq), out=self.q_star)
        return qdot
