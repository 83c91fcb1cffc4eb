"""A solved TO: the trajectory's nodes, times, configurations, velocities and wrenches,
with the solver's status and the primal-dual point to start a next solve from."""

from __future__ import annotations

import dataclasses

import numpy as np

from locoman.to.nlp.multipliers import WarmStart


@dataclasses.dataclass(frozen=True)
class Trajectory:
    """The TO's answer, per node (N nodes; dt[k] leads from node k to k + 1).

    Every array is in world axes and SI units; ``q`` and ``object_q`` are (p, rpy).
    """

    status: str
    success: bool
    iterations: int
    solve_time_s: float
    build_time_s: float
    function_time_s: float  # of ``solve_time_s``, IPOPT's calls of the NLP's functions
    exact_iterations: int  # of ``iterations``, those with the exact Hessian
    alpha_max: float  # the largest homotopy parameter alpha of (13) [-]; 0 without one
    n_variables: int
    n_constraints: int
    max_constraint_violation: float
    cost: float
    q: np.ndarray  # (N, 35)
    v: np.ndarray  # (N, 35)
    foot_wrench: np.ndarray  # (N, 2, 6) force [N], moment [N m] at each sole centre
    hand_wrench: np.ndarray  # (N, 2, 6) the touched object's wrench on each hand
    object_q: np.ndarray  # (N, M, 6)
    object_v: np.ndarray  # (N, M, 6)
    support_wrench: np.ndarray  # (N, M, 6) at each object's frame origin
    foot_slack: np.ndarray  # (N, 2) [m]
    hand_slack: np.ndarray  # (N, 2, 3) [m]
    support_slack: np.ndarray  # (N, M) [m]
    dt: np.ndarray  # (N,) [s]; the last is unused
    feet_contact: np.ndarray  # (N, 2) bool
    foot_object: np.ndarray  # (N, 2) index of the object a foot stands on, -1: the ground
    hand_object: np.ndarray  # (N, 2) index of the object each hand touches, -1: none
    object_active: np.ndarray  # (N, M) bool
    support_kind: np.ndarray  # (N, M) str: a Support's name, "none" while carried
    support_base: np.ndarray  # (N, M) int: the supporting object, -1: the world
    phase: np.ndarray  # (N,) str
    subtask: np.ndarray  # (N,) int
    hand_points: np.ndarray  # (M, 2, 3) hand contacts in each object's frame [m]
    collision_pairs: int = 0  # collision terms in the problem (over all nodes)
    warm_start: WarmStart | None = None  # the primal-dual point, for the next grid cell

    @property
    def time(self) -> np.ndarray:
        """(N,) time of each node [s]."""
        return np.r_[0.0, np.cumsum(self.dt[:-1])]
