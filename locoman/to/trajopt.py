"""Paper A's whole-body TO of a scenario: schedule, parameters, bounds, the subtask-like warm
start (Sec. IV-C.2), and the solve, over the stage functions of :mod:`locoman.to.problem`.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pinocchio as pin

from locoman.retarget.robot import contact_frames
from locoman.scene import g1
from locoman.scene.rotations import matrix_to_rpy, rpy_to_matrix
from locoman.to.collision import CollisionCfg, Obstacle
from locoman.to.costs import CostWeights, averaged_over_nodes
from locoman.to.kinematics import SymbolicKinematics
from locoman.to.layout import N_PARAMS, PARAMETERS, VARIABLES, WIDTH, ObjectModel
from locoman.to.nlp import NLPResult, SolverBuildError, StageNLP, WarmStart
from locoman.to.parameters import GlobalParameters
from locoman.to.problem import ContactCfg, NodeMode, StageBuilder
from locoman.to.schedule import Schedule, ScheduleCfg, step_count, subtask_phases

GRAVITY = 9.81  # [m/s^2]


@dataclasses.dataclass(frozen=True)
class Keyframe:
    """What the TO takes from one subtask's keyframe.

    Attributes:
        predicate: The subtask's verb (``walk``, ``pick``, ``place``).
        q35: The retargeted configuration.
        object_pose: (6,) the object's (p, rpy) in the keyframe [m, rad].
        goal: (3,) object x, y [m] and yaw [rad] the subtask must reach, or None.
    """

    predicate: str
    q35: np.ndarray
    object_pose: np.ndarray
    goal: np.ndarray | None = None


@dataclasses.dataclass(frozen=True)
class TOInputs:
    """A scenario, as the TO needs it.

    Attributes:
        q_start: (35,) the robot at rest at the start.
        object_start: (6,) the object's (p, rpy) at the start.
        obj: The manipulated object.
        keyframes: One per subtask, in plan order.
        hand_points: (2, 3) left and right hand contacts in the object frame [m].
        hand_frames: (2, 3, 3) their contact frames in the object frame (z: outward normal).
        obstacles: The scene's fixed boxes (tables, shelves) for the collision terms.
    """

    q_start: np.ndarray
    object_start: np.ndarray
    obj: ObjectModel
    keyframes: Sequence[Keyframe]
    hand_points: np.ndarray
    hand_frames: np.ndarray
    obstacles: tuple[Obstacle, ...] = ()


# The solver backends (``solve.solver.backend``): IPOPT's options for each. MUMPS is the
# default: on ``tiny`` SPRAL took 3.0 s per iteration against MUMPS's 0.16 s
# (benchmarks/to_solvers.py). fatrop is not a backend: see the README's TO section.
BACKENDS: dict[str, dict[str, str]] = {
    "ipopt_mumps": {"linear_solver": "mumps"},
    "ipopt_spral": {"linear_solver": "spral"},
}


HESSIANS = ("gauss_newton", "exact")


@dataclasses.dataclass
class SolverCfg:
    """IPOPT and the time grid.

    Attributes:
        backend: A key of :data:`BACKENDS`: IPOPT with MUMPS or with SPRAL.
        dt_bounds: Bounds of each time step [s].
        max_iterations: IPOPT's max_iter.
        tolerance: IPOPT's tol, on its scaled optimality error. The collision penalties'
            Gauss-Newton Hessian converges linearly at the end: on ``tiny`` the cost is
            fixed to 8 digits from iteration 165, and 1e-6 took 55 more than 1e-4.
        constraint_tolerance: IPOPT's constr_viol_tol [SI units of each constraint]: the
            dynamics (1) hold to this, whatever ``tolerance``.
        compile: Compile the derivatives to C (cached by their hash, once per problem
            structure) instead of interpreting them: several times faster per iteration.
        compile_flags: The C compiler's flags (:mod:`locoman.to.compile`).
        print_level: IPOPT's print level (5: one line per iteration, the progress).
        warm_start: Sec. IV-C.2: each subtask's nodes start at its keyframe; otherwise
            every node starts at the initial state.
        max_wall_time_s: IPOPT's max_wall_time [s]: a solve stopped by it is a failed solve
            (status ``Maximum_WallTime_Exceeded``); None: no limit. The grids' time limit.
        hessian: The Hessian of the Lagrangian IPOPT gets (:data:`HESSIANS`).
            ``gauss_newton`` (default): the costs' exact Hessian, the penalties' Gauss-Newton
            one, and none of the constraints' second derivatives; ``exact``: with the
            constraints' lambda' nabla^2 g too. Both converge to the same KKT points (the
            Hessian is not in the KKT conditions); on ``tiny`` the exact one is indefinite
            (the products f dt and v dt of (1), the kinematics' trigonometry), IPOPT
            regularised it in nearly every iteration (2.3 factorisations each) and took 148
            iterations, 24 s, where Gauss-Newton takes 58, 4.6 s, to the same cost.
    """

    backend: str = "ipopt_mumps"
    dt_bounds: list[float] = dataclasses.field(default_factory=lambda: [0.02, 0.08])
    max_iterations: int = 500
    tolerance: float = 1e-4
    constraint_tolerance: float = 1e-8
    compile: bool = True
    compile_flags: list[str] = dataclasses.field(default_factory=lambda: ["-O1"])
    print_level: int = 5
    warm_start: bool = True
    max_wall_time_s: float | None = None
    hessian: str = "gauss_newton"

    def check(self) -> list[tuple[str, str]]:
        errors = []
        if len(self.dt_bounds) != 2 or not 0.0 < self.dt_bounds[0] <= self.dt_bounds[1]:
            errors.append(("dt_bounds", "needs [lower, upper] with 0 < lower <= upper [s]"))
        if self.max_iterations < 1 or self.tolerance <= 0.0:
            errors.append(("max_iterations", "needs max_iterations >= 1 and tolerance > 0"))
        if self.constraint_tolerance <= 0.0:
            errors.append(("constraint_tolerance", "must be > 0"))
        if not 0 <= self.print_level <= 12:
            errors.append(("print_level", "IPOPT's print level is 0..12"))
        if self.backend not in BACKENDS:
            errors.append(("backend", f"must be one of {sorted(BACKENDS)}"))
        if self.max_wall_time_s is not None and not self.max_wall_time_s > 0.0:
            errors.append(("max_wall_time_s", "must be > 0 s, or null for no limit"))
        if self.hessian not in HESSIANS:
            errors.append(("hessian", f"must be one of {list(HESSIANS)}"))
        return errors


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
    n_variables: int
    n_constraints: int
    max_constraint_violation: float
    cost: float
    q: np.ndarray  # (N, 35)
    v: np.ndarray  # (N, 35)
    foot_wrench: np.ndarray  # (N, 2, 6) force [N], moment [N m] at each sole centre
    hand_wrench: np.ndarray  # (N, 2, 6) the object's wrench on each hand, at the contact
    object_q: np.ndarray  # (N, 6)
    object_v: np.ndarray  # (N, 6)
    support_wrench: np.ndarray  # (N, 6) at the object's bottom centre
    foot_slack: np.ndarray  # (N, 2) [m]
    hand_slack: np.ndarray  # (N, 2, 3) [m]
    dt: np.ndarray  # (N,) [s]; the last is unused
    feet_contact: np.ndarray  # (N, 2) bool
    hands_contact: np.ndarray  # (N, 2) bool
    object_active: np.ndarray  # (N,) bool
    object_supported: np.ndarray  # (N,) bool
    phase: np.ndarray  # (N,) str
    subtask: np.ndarray  # (N,) int
    hand_points: np.ndarray  # (2, 3) hand contacts in the object frame [m]
    warm_start: WarmStart | None = None  # the primal-dual point, for the next grid cell

    @property
    def time(self) -> np.ndarray:
        """(N,) time of each node [s]."""
        return np.r_[0.0, np.cumsum(self.dt[:-1])]


def _yaw(q35: np.ndarray) -> float:
    return float(q35[5])


def sole_points(q35: np.ndarray) -> np.ndarray:
    """(2, 3) left and right sole centres [m] at a configuration."""
    model = g1.g1_pinocchio_model()
    data = model.createData()
    pin.framesForwardKinematics(model, data, g1.q35_to_pin(q35))
    centre = contact_frames().sole["left_sole"]
    return np.array([data.oMf[model.getFrameId(link)].act(centre) for link in g1.FOOT_LINKS])


def build_schedule(inputs: TOInputs, cfg: ScheduleCfg) -> Schedule:
    """Phases of every subtask; steps where the keyframes' feet move (Sec. IV)."""
    phases = []
    feet_before, yaw_before = sole_points(inputs.q_start)[:, :2], _yaw(inputs.q_start)
    for i, kf in enumerate(inputs.keyframes):
        feet = sole_points(kf.q35)[:, :2]
        steps = step_count(feet_before, feet, yaw_before, _yaw(kf.q35), cfg)
        # Lead with the foot on the side the robot moves or turns to.
        heading = np.array([math.cos(yaw_before), math.sin(yaw_before)])
        move = feet.mean(axis=0) - feet_before.mean(axis=0)
        lateral = heading[0] * move[1] - heading[1] * move[0]
        turn = math.remainder(_yaw(kf.q35) - yaw_before, math.tau)
        first_right = (lateral + 0.3 * turn) < 0.0
        phases += subtask_phases(kf.predicate, i, steps, first_right, cfg)
        feet_before, yaw_before = feet, _yaw(kf.q35)
    return Schedule.from_phases(phases)


def node_modes(schedule: Schedule) -> list[NodeMode]:
    """The contact mode of every node; the object is simulated from the first touch on."""
    touch = schedule.first_touch()
    modes = []
    for n in range(schedule.nodes):
        ph = schedule.phase(n)
        active = touch is not None and n >= touch
        supported = ph.object_supported or not active
        modes.append(NodeMode(ph.feet, ph.hands if n > 0 else (False, False), active, supported))
    return modes


def _frames_columns(frames: np.ndarray) -> np.ndarray:
    """(2, 3, 3) -> (18,), each matrix column-major as CasADi reshapes it."""
    return np.concatenate([f.ravel(order="F") for f in frames])


def node_parameters(
    inputs: TOInputs, schedule: Schedule, keyframe_costs: tuple[bool, bool]
) -> np.ndarray:
    """(N_PARAMS, N): references and switches per node.

    The yaw reference goes linearly, over each subtask's nodes, from the previous keyframe's
    yaw to the subtask's. (9) is on at each keyframe node, (10) on the stance nodes of each
    subtask after its last step; ``keyframe_costs`` = (base, foot) switches them.
    """
    n = schedule.nodes
    P = np.zeros((N_PARAMS, n))
    kf_nodes = schedule.keyframe_nodes()
    yaw_before = _yaw(inputs.q_start)
    support_z = float(inputs.object_start[2])
    for i, kf in enumerate(inputs.keyframes):
        nodes = [k for k in range(1, n) if schedule.subtask_of(k) == i]
        yaws = np.linspace(yaw_before, _yaw(kf.q35), len(nodes) + 1)[1:]
        P[PARAMETERS["yaw_ref"].start, nodes] = yaws
        if i == 0:
            P[PARAMETERS["yaw_ref"].start, 0] = yaw_before
        yaw_before = _yaw(kf.q35)
        node = kf_nodes[i]
        if keyframe_costs[0]:
            P[PARAMETERS["kf_base_on"], node] = 1.0
            P[PARAMETERS["kf_base"], node] = np.r_[kf.q35[2], kf.q35[3:6]]
        if keyframe_costs[1]:
            last_swing = max(
                (k for k in nodes if not schedule.phase(k).stance), default=nodes[0] - 1
            )
            stance = [k for k in nodes if k > last_swing and schedule.phase(k).stance]
            P[PARAMETERS["kf_foot_on"], stance] = 1.0
            P[PARAMETERS["kf_foot"], stance] = sole_points(kf.q35)[:, :2].mean(axis=0)[:, None]
        if kf.goal is not None:
            P[PARAMETERS["goal"], n - 1] = kf.goal
            P[PARAMETERS["goal_on"], n - 1] = 1.0
            support_z = float(kf.object_pose[2])
        for k in nodes:
            P[PARAMETERS["support_z"], k] = (
                support_z if schedule.phase(k).name == "set" else inputs.object_start[2]
            )
    P[PARAMETERS["support_z"], 0] = inputs.object_start[2]
    P[PARAMETERS["hand_points"], :] = inputs.hand_points.ravel()[:, None]
    P[PARAMETERS["hand_frames"], :] = _frames_columns(inputs.hand_frames)[:, None]
    return P


# Bounds that no motion of the task comes near; they keep IPOPT's steps where the model
# means something (a Newton step along a weakly penalised direction, such as a contact force
# [N], could otherwise jump by hundreds and tip the next iterate's Euler angles over).
TILT_MAX = math.pi / 3  # base and object roll, pitch [rad]
LINEAR_SPEED_MAX = 5.0  # base and object [m/s]
ANGULAR_SPEED_MAX = 2.0 * math.pi  # base and object Euler rates [rad/s]
WRENCH_LEVER = 0.5  # moment bound per newton of force bound [m]


def _sanity_bounds(lo: np.ndarray, hi: np.ndarray, weight: float) -> None:
    """:data:`TILT_MAX` and the speed bounds on the base and the object; every contact
    force within twice the weight of robot and object [N], every moment within that times
    :data:`WRENCH_LEVER`."""
    for q_name, v_name in (("q", "v"), ("object_q", "object_v")):
        q, v = VARIABLES[q_name].start, VARIABLES[v_name].start
        lo[q + 3 : q + 5], hi[q + 3 : q + 5] = -TILT_MAX, TILT_MAX
        lo[v : v + 3], hi[v : v + 3] = -LINEAR_SPEED_MAX, LINEAR_SPEED_MAX
        lo[v + 3 : v + 6], hi[v + 3 : v + 6] = -ANGULAR_SPEED_MAX, ANGULAR_SPEED_MAX
    force = 2.0 * weight
    for name, count in (("foot_wrench", 2), ("hand_wrench", 2), ("support_wrench", 1)):
        start = VARIABLES[name].start
        for i in range(count):
            f = start + 6 * i
            lo[f : f + 3], hi[f : f + 3] = -force, force
            lo[f + 3 : f + 6], hi[f + 3 : f + 6] = -WRENCH_LEVER * force, WRENCH_LEVER * force


def bounds(
    inputs: TOInputs, schedule: Schedule, modes: list[NodeMode], cfg: SolverCfg
) -> tuple[np.ndarray, np.ndarray]:
    """Variable bounds (WIDTH, N): joint position and velocity limits, the initial state,
    robot and object at rest at the end, inactive contacts' wrenches and slacks at zero,
    the untouched object at rest."""
    model = g1.g1_pinocchio_model()
    n = schedule.nodes
    lo, hi = np.full((WIDTH, n), -np.inf), np.full((WIDTH, n), np.inf)
    q, v = VARIABLES["q"], VARIABLES["v"]
    lo[q.start + 6 : q.stop], hi[q.start + 6 : q.stop] = (
        model.lowerPositionLimit[7:, None],
        model.upperPositionLimit[7:, None],
    )
    lo[v.start + 6 : v.stop], hi[v.start + 6 : v.stop] = (
        -model.velocityLimit[6:, None],
        model.velocityLimit[6:, None],
    )
    dt = VARIABLES["dt"].start
    lo[dt], hi[dt] = cfg.dt_bounds
    lo[dt, -1] = hi[dt, -1] = cfg.dt_bounds[0]
    _sanity_bounds(lo, hi, (pin.computeTotalMass(model) + inputs.obj.mass) * GRAVITY)
    lo[q, 0] = hi[q, 0] = inputs.q_start
    # The motion starts and ends at rest, the object too (evaluate checks it stands still
    # on its support at the end; without this tiny's box still turned at 0.37 rad/s).
    lo[v, 0] = hi[v, 0] = lo[v, -1] = hi[v, -1] = 0.0
    lo[VARIABLES["object_v"], -1] = hi[VARIABLES["object_v"], -1] = 0.0
    rest = np.r_[0.0, 0.0, inputs.obj.mass * GRAVITY, 0.0, 0.0, 0.0]
    for k, mode in enumerate(modes):
        last = k == n - 1
        for i in range(2):
            foot = slice(
                VARIABLES["foot_wrench"].start + 6 * i, VARIABLES["foot_wrench"].start + 6 * i + 6
            )
            hand = slice(
                VARIABLES["hand_wrench"].start + 6 * i, VARIABLES["hand_wrench"].start + 6 * i + 6
            )
            if not mode.feet[i] or last:
                lo[foot, k] = hi[foot, k] = 0.0
            if not mode.hands[i] or last:
                lo[hand, k] = hi[hand, k] = 0.0
            if not mode.feet[i] or k == 0:
                lo[VARIABLES["foot_slack"].start + i, k] = hi[
                    VARIABLES["foot_slack"].start + i, k
                ] = 0.0
            if not mode.hands[i] or not mode.object_active:
                s = VARIABLES["hand_slack"].start + 3 * i
                lo[s : s + 3, k] = hi[s : s + 3, k] = 0.0
        support = VARIABLES["support_wrench"]
        if not mode.object_active:
            lo[VARIABLES["object_q"], k] = hi[VARIABLES["object_q"], k] = inputs.object_start
            lo[VARIABLES["object_v"], k] = hi[VARIABLES["object_v"], k] = 0.0
            lo[support, k] = hi[support, k] = rest
        elif not mode.object_supported or last:
            lo[support, k] = hi[support, k] = 0.0
        if not (mode.object_active and mode.object_supported):
            s = VARIABLES["support_slack"].start
            lo[s, k] = hi[s, k] = 0.0
    return lo, hi


SQUEEZE_MARGIN = 2.0


def initial_guess(
    inputs: TOInputs, schedule: Schedule, modes: list[NodeMode], cfg: SolverCfg, robot_mass: float
) -> np.ndarray:
    """(WIDTH, N): Sec. IV-C.2's subtask-like warm start: each subtask's nodes at its
    keyframe (robot and object), at rest, the weight shared by the feet in contact and the
    carried object's weight by the hands, which squeeze it hard enough for their friction
    cones (3a) to hold it, :data:`SQUEEZE_MARGIN` times over."""
    n = schedule.nodes
    X = np.zeros((WIDTH, n))
    X[VARIABLES["dt"]] = 0.5 * sum(cfg.dt_bounds)
    for k in range(n):
        mode = modes[k]
        kf = inputs.keyframes[schedule.subtask_of(k)]
        use_kf = cfg.warm_start and k > 0
        X[VARIABLES["q"], k] = kf.q35 if use_kf else inputs.q_start
        X[VARIABLES["object_q"], k] = (
            kf.object_pose if (use_kf and mode.object_active) else inputs.object_start
        )
        weight = robot_mass * GRAVITY
        if mode.carried:
            weight += inputs.obj.mass * GRAVITY
            R_object = rpy_to_matrix(X[VARIABLES["object_q"], k][3:6])
            half = 0.5 * inputs.obj.mass * GRAVITY
            for i in range(2):
                s = VARIABLES["hand_wrench"].start + 6 * i
                normal = R_object @ inputs.hand_frames[i][:, 2]
                squeeze = SQUEEZE_MARGIN * half / inputs.obj.friction
                X[s : s + 3, k] = np.r_[0.0, 0.0, -half] + squeeze * normal
        elif mode.object_supported:
            X[VARIABLES["support_wrench"].start + 2, k] = inputs.obj.mass * GRAVITY
        down = [i for i in range(2) if mode.feet[i]]
        for i in down:
            X[VARIABLES["foot_wrench"].start + 6 * i + 2, k] = weight / len(down)
    return X


class TrajectoryOptimizer:
    """The TO of one scenario, built once: new parameters (the keyframe switches, and any
    :class:`GlobalParameters` of the same layout: masses, weights, frictions) re-solve
    without rebuilding.

    Args:
        inputs: The scenario.
        schedule_cfg, weights, contact, collision, solver: Settings.
        cache_dir: Where compiled derivatives are cached (``solver.compile``).
    """

    def __init__(
        self,
        inputs: TOInputs,
        schedule_cfg: ScheduleCfg,
        weights: CostWeights,
        contact: ContactCfg,
        collision: CollisionCfg,
        solver: SolverCfg,
        cache_dir: Path,
    ) -> None:
        self.schedule = build_schedule(inputs, schedule_cfg)
        if weights.average_over_nodes:
            weights = averaged_over_nodes(weights, self.schedule.nodes)
        self.inputs, self.cfg, self.weights = inputs, solver, weights
        self.modes = node_modes(self.schedule)
        model = g1.g1_pinocchio_model()
        self.kin = SymbolicKinematics(model)
        builder = StageBuilder(
            self.kin, inputs.obj, contact_frames(), weights, contact, collision, inputs.obstacles
        )
        n = self.schedule.nodes
        keys: dict[tuple, list[int]] = {}
        for k in range(n - 1):
            keys.setdefault((self.modes[k], self.modes[k + 1], k == n - 2), []).append(k)
        curvature = solver.hessian == "exact"
        groups = [builder.group(*key, np.array(stages), curvature) for key, stages in keys.items()]
        groups.append(builder.kinematics_group(np.arange(n), curvature))
        self_collision = builder.self_collision_group(np.arange(1, n))
        if self_collision is not None:
            groups.append(self_collision)
        self.kinematics = builder.kinematics
        self.parameters = builder.parameters
        ipopt = {
            **BACKENDS[solver.backend],
            "max_iter": solver.max_iterations,
            "tol": solver.tolerance,
            "constr_viol_tol": solver.constraint_tolerance,
            "print_level": solver.print_level,
            "print_frequency_iter": 1,
            "sb": "yes",
            "mu_strategy": "adaptive",
            "fixed_variable_treatment": "make_parameter",
        }
        if solver.max_wall_time_s is not None:
            ipopt["max_wall_time"] = float(solver.max_wall_time_s)
        self.nlp = StageNLP(
            WIDTH,
            n,
            N_PARAMS,
            builder.parameters.vector().size,
            groups,
            ipopt,
            cache_dir if solver.compile else None,
            solver.compile_flags,
        )

    def solve(
        self,
        keyframe_costs: tuple[bool, bool] = (True, True),
        parameters: GlobalParameters | None = None,
        warm_start: Trajectory | None = None,
    ) -> Trajectory:
        """Solve; a failed solve is a trajectory with ``success`` False, not an exception.

        Args:
            keyframe_costs: (9), (10) on.
            parameters: New values of the global parameters (same layout as
                :attr:`parameters`), e.g. another box mass; the compiled problem is reused.
            warm_start: A solution of this optimizer (another cell of a grid): IPOPT
                starts from its primal-dual point instead of Sec. IV-C.2's guess.
        """
        parameters = parameters or self.parameters
        if parameters.layout != self.parameters.layout:
            raise SolverBuildError(
                "the parameters' layout differs from the one this optimizer was built for "
                "(another obstacle count?): build a new TrajectoryOptimizer"
            )
        inputs = dataclasses.replace(self.inputs, obj=parameters.object(self.inputs.obj))
        schedule, modes = self.schedule, self.modes
        P = node_parameters(inputs, schedule, keyframe_costs)
        lo, hi = bounds(inputs, schedule, modes, self.cfg)
        X0 = np.clip(initial_guess(inputs, schedule, modes, self.cfg, self.kin.mass), lo, hi)
        q, v = X0[VARIABLES["q"]], X0[VARIABLES["v"]]
        X0[VARIABLES["kin"]] = np.asarray(self.kinematics.map(schedule.nodes)(q, v))
        result = self.nlp.solve(
            X0.ravel(order="F"),
            lo.ravel(order="F"),
            hi.ravel(order="F"),
            P,
            parameters.vector(),
            warm_start.warm_start if warm_start is not None else None,
        )
        return self._trajectory(result)

    def _trajectory(self, result: NLPResult) -> Trajectory:
        n = self.schedule.nodes
        Z = result.x.reshape(n, WIDTH)

        def part(name: str) -> np.ndarray:
            return Z[:, VARIABLES[name]]

        phases = [self.schedule.phase(k).name if k > 0 else "start" for k in range(n)]
        return Trajectory(
            status=result.status,
            success=result.success,
            iterations=result.iterations,
            solve_time_s=result.solve_time_s,
            build_time_s=self.nlp.build_time_s,
            n_variables=self.nlp.n_x,
            n_constraints=self.nlp.n_g,
            max_constraint_violation=result.max_constraint_violation,
            cost=result.cost,
            q=part("q"),
            v=part("v"),
            foot_wrench=part("foot_wrench").reshape(n, 2, 6),
            hand_wrench=part("hand_wrench").reshape(n, 2, 6),
            object_q=part("object_q"),
            object_v=part("object_v"),
            support_wrench=part("support_wrench"),
            foot_slack=part("foot_slack"),
            hand_slack=part("hand_slack").reshape(n, 2, 3),
            dt=part("dt")[:, 0],
            feet_contact=np.array([m.feet for m in self.modes]),
            hands_contact=np.array([m.hands for m in self.modes]),
            object_active=np.array([m.object_active for m in self.modes]),
            object_supported=np.array([m.object_supported for m in self.modes]),
            phase=np.array(phases),
            subtask=np.array([self.schedule.subtask_of(k) for k in range(n)]),
            hand_points=self.inputs.hand_points.copy(),
            warm_start=result.warm_start,
        )


def object_pose(T: np.ndarray) -> np.ndarray:
    """(6,) (p, rpy) of a 4x4 transform."""
    return np.r_[T[:3, 3], matrix_to_rpy(T[:3, :3])]
