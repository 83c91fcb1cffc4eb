"""Whole-body TO of the G1 with both feet in patch contact: the first slice of paper A's
formulation (Sec. IV) that runs end to end (no stage yet), used to check the pieces
together and to time IPOPT as the horizon grows (``benchmarks/to_stance.py``).

Per node k: q_k, v_k (35 each), per foot the force f and moment tau at the sole centre, the
slack of (2a); per interval the time step dt_k. Constraints: the centroidal dynamics (1)
with h = A_G(q) v from :mod:`.kinematics`, the patch contact (2a)-(2c) of both soles on the
floor (not (2d): see :func:`~locoman.to.contacts.no_rolling`), the friction cone and CoP
(3), joint limits, and time-step bounds. Costs: Table I's stance
and regularisation terms, the slack penalty, and the keyframe base cost (9) at the last
node. Each node's residuals and costs are one SX function, mapped over the nodes inside an
MX graph, as the prototype in issue 6 found fastest.
"""

from __future__ import annotations

import dataclasses
import time

import casadi as ca
import numpy as np

from locoman.scene import g1
from locoman.to.contacts import friction_cone_cop, patch_contact
from locoman.to.costs import CostWeights, keyframe_base_cost, regularization_cost, stance_cost
from locoman.to.dynamics import wrench_sum
from locoman.to.kinematics import SymbolicKinematics, euler_rates_to_world

FEET = ("left_ankle_roll_link", "right_ankle_roll_link")
FLOOR_Z = 0.0  # [m]


@dataclasses.dataclass(frozen=True)
class StanceCfg:
    """Settings of the stance problem.

    Attributes:
        nodes: Shooting nodes N.
        mu: Friction coefficient of the floor [-].
        stiffness: k_z of (2a) [1/s].
        dt_bounds: Time-step bounds [s].
        max_iterations: IPOPT iterations.
        tolerance: IPOPT's tol.
        verbose: IPOPT prints one line per iteration.
    """

    nodes: int = 30
    mu: float = 0.8
    stiffness: float = 50.0
    dt_bounds: tuple[float, float] = (0.01, 0.05)
    max_iterations: int = 300
    tolerance: float = 1e-6
    verbose: bool = False


@dataclasses.dataclass(frozen=True)
class StanceSolution:
    """A solved (or failed) stance problem; ``status`` is IPOPT's return status."""

    status: str
    iterations: int
    build_time_s: float
    solve_time_s: float
    n_variables: int
    n_constraints: int
    q: np.ndarray  # (N, 35)
    v: np.ndarray  # (N, 35)
    forces: np.ndarray  # (N, 2, 3) [N], at the sole centres, world
    moments: np.ndarray  # (N, 2, 3) [N m]
    slack: np.ndarray  # (N, 2) [m]
    dt: np.ndarray  # (N - 1,) [s]

    @property
    def success(self) -> bool:
        return self.status == "Solve_Succeeded"


def sole_frame() -> tuple[np.ndarray, np.ndarray]:
    """Sole centre (3,) in the ankle roll link frame [m], and the patch half-sizes (2,)."""
    corners = next(iter(g1.foot_sole_corners().values()))
    return corners.mean(axis=0), 0.5 * (corners.max(axis=0) - corners.min(axis=0))[:2]


def node_functions(
    kin: SymbolicKinematics, cfg: StanceCfg, w: CostWeights
) -> dict[str, ca.Function]:
    """The per-node SX functions: kinematics, dynamics, contact, cone and cost."""
    q, v = kin.q, kin.v
    q1, v1 = ca.SX.sym("q1", kin.nq), ca.SX.sym("v1", kin.nq)
    f, tau, slack, dt = ca.SX.sym("f", 6), ca.SX.sym("tau", 6), ca.SX.sym("s", 2), ca.SX.sym("dt")
    centre, half = sole_frame()
    soles = []
    for k, link in enumerate(FEET):
        R_ankle, p_ankle = kin.frame_pose(link)
        omega, v_ankle = kin.frame_velocity(link)
        r = p_ankle + R_ankle @ ca.DM(centre)
        r_dot = v_ankle + ca.cross(omega, R_ankle @ ca.DM(centre))
        soles.append((r, r_dot, R_ankle, f[3 * k : 3 * k + 3], tau[3 * k : 3 * k + 3]))
    h, com = kin.centroidal_momentum(), kin.com()
    momentum = ca.Function("momentum", [q, v], [h, com])
    h1, _ = momentum(q1, v1)
    wrench = wrench_sum(com, [(r, fk, tk) for r, _, _, fk, tk in soles], kin.mass)
    dynamics = ca.vertcat(h1 - h - wrench * dt, q1 - q - v1 * dt)  # (1a), (1b)
    contact = ca.vertcat(
        *[
            patch_contact(r, r_dot, R, FLOOR_Z, cfg.stiffness, slack[k])
            for k, (r, r_dot, R, _, _) in enumerate(soles)
        ]
    )
    cone = ca.vertcat(
        *[friction_cone_cop(fk, tk, R, cfg.mu, half[0], half[1]) for _, _, R, fk, tk in soles]
    )
    (r_l, _, R_l, _, _), (r_r, _, R_r, _, _) = soles
    base_omega = euler_rates_to_world(q[3:6]) @ v[3:6]
    cost = (
        stance_cost(w, q, com, r_l, r_r, R_l, R_r)
        + regularization_cost(w, q, v, ca.vertcat(f, tau), base_omega, dt)
        + w.slack * ca.sumsqr(slack)
    )
    return {
        "dynamics": ca.Function("dynamics", [q, v, q1, v1, f, tau, dt], [dynamics]),
        "contact": ca.Function("contact", [q, v, slack], [contact]),
        "cone": ca.Function("cone", [q, f, tau], [cone]),
        "cost": ca.Function("cost", [q, v, f, tau, slack, dt], [cost]),
        "momentum": momentum,
        "soles": ca.Function("soles", [q], [ca.horzcat(r_l, r_r)]),
    }


def solve_stance(
    q_start: np.ndarray, q_keyframe: np.ndarray, cfg: StanceCfg, weights: CostWeights | None = None
) -> StanceSolution:
    """Move the standing G1 from ``q_start`` (35,) at rest towards the keyframe base of
    ``q_keyframe`` (35,) with both feet where they are; a failed solve is returned with its
    status, not raised."""
    w = weights or CostWeights()
    tic = time.perf_counter()
    model = g1.g1_pinocchio_model()
    kin = SymbolicKinematics(model)
    fn = node_functions(kin, cfg, w)
    n = cfg.nodes
    opti = ca.Opti()
    Q, V = opti.variable(kin.nq, n), opti.variable(kin.nq, n)
    F, T, S = opti.variable(6, n), opti.variable(6, n), opti.variable(2, n)
    DT = opti.variable(1, n - 1)
    opti.subject_to(Q[:, 0] == q_start)
    opti.subject_to(V[:, 0] == 0)
    opti.subject_to(
        fn["dynamics"].map(n - 1)(
            Q[:, :-1], V[:, :-1], Q[:, 1:], V[:, 1:], F[:, :-1], T[:, :-1], DT
        )
        == 0
    )
    opti.subject_to(fn["contact"].map(n - 1)(Q[:, 1:], V[:, 1:], S[:, 1:]) == 0)
    opti.subject_to(ca.vec(fn["cone"].map(n)(Q, F, T)) >= 0)
    lo, hi = model.lowerPositionLimit[7:], model.upperPositionLimit[7:]
    opti.subject_to(
        opti.bounded(np.tile(lo[:, None], (1, n)), Q[6:, :], np.tile(hi[:, None], (1, n)))
    )
    opti.subject_to(opti.bounded(cfg.dt_bounds[0], DT, cfg.dt_bounds[1]))
    dt_last = ca.horzcat(DT, DT[:, -1])
    cost = ca.sum2(fn["cost"].map(n)(Q, V, F, T, S, dt_last))
    cost += keyframe_base_cost(w, Q[:, -1], ca.DM(q_keyframe))
    opti.minimize(cost)
    # Warm start: every node at the start, feet sharing the weight.
    opti.set_initial(Q, np.tile(q_start[:, None], (1, n)))
    weight = np.zeros((6, n))
    weight[[2, 5], :] = 0.5 * kin.mass * 9.81
    opti.set_initial(F, weight)
    opti.set_initial(DT, w.timestep_s)
    options = {"print_time": False, "expand": True}
    ipopt = {
        "max_iter": cfg.max_iterations,
        "tol": cfg.tolerance,
        "print_level": 5 if cfg.verbose else 0,
        "sb": "yes",
        "mu_strategy": "adaptive",
    }
    opti.solver("ipopt", options, ipopt)
    build = time.perf_counter() - tic
    tic = time.perf_counter()
    try:
        sol = opti.solve()
        value = sol.value
    except RuntimeError:
        value = opti.debug.value
    solve = time.perf_counter() - tic
    stats = opti.stats()
    forces, moments = (
        np.asarray(value(F)).T.reshape(n, 2, 3),
        np.asarray(value(T)).T.reshape(n, 2, 3),
    )
    return StanceSolution(
        status=str(stats["return_status"]),
        iterations=int(stats["iter_count"]),
        build_time_s=build,
        solve_time_s=solve,
        n_variables=int(opti.nx),
        n_constraints=int(opti.ng),
        q=np.asarray(value(Q)).T,
        v=np.asarray(value(V)).T,
        forces=forces,
        moments=moments,
        slack=np.asarray(value(S)).T,
        dt=np.atleast_1d(np.asarray(value(DT)).ravel()),
    )
