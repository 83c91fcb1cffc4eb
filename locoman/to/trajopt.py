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
from locoman.to.layout import NodeLayout, ObjectModel
from locoman.to.nlp import NLPResult, SolverBuildError, StageNLP, WarmStart
from locoman.to.parameters import GlobalParameters
from locoman.to.problem import ContactCfg, NodeMode, ObjectMode, StageBuilder
from locoman.to.schedule import Schedule, ScheduleCfg, step_count, subtask_phases
from locoman.to.supports import OnObject, Support

GRAVITY = 9.81  # [m/s^2]
# A surface up to this high is the floor: an object resting on it is in the feet's way
# (the ``feet_object`` kind) [m].
FLOOR_HEIGHT_MAX = 0.01


@dataclasses.dataclass(frozen=True)
class Keyframe:
    """What the TO takes from one subtask's keyframe.

    Attributes:
        predicate: The subtask's verb (``walk``, ``pick``, ``grab``, ``place``, ``push``,
            ``step``).
        q35: The retargeted configuration.
        object: Index of the subtask's object in :attr:`TOInputs.objects`; None for a walk
            towards a fixed object.
        object_poses: (M, 6) every object's (p, rpy) in the keyframe [m, rad].
        goal: (3,) x, y [m] and yaw [rad] the subtask's object must reach by the subtask's
            end, or None.
        support: What the object rests on once a ``place`` subtask sets it down (None for
            the other predicates).
        support_height: [m] that support's surface height (world z, or in the supporting
            object's frame for :class:`OnObject`).
        step_height: [m] world height of the top face a ``step`` puts the feet on.
    """

    predicate: str
    q35: np.ndarray
    object: int | None
    object_poses: np.ndarray
    goal: np.ndarray | None = None
    support: Support | None = None
    support_height: float = 0.0
    step_height: float = 0.0


@dataclasses.dataclass(frozen=True)
class TOInputs:
    """A scenario, as the TO needs it.

    Attributes:
        q_start: (35,) the robot at rest at the start.
        objects: The scene's movable objects.
        object_starts: (M, 6) each object's (p, rpy) at the start.
        supports: What each object rests on at the start.
        support_heights: (M,) [m] the height of each of those supports' surface.
        keyframes: One per subtask, in plan order.
        hand_points: (M, 2, 3) left and right hand contacts in each object's frame [m].
        hand_frames: (M, 2, 3, 3) their contact frames in the object's frame (z: outward
            normal).
        obstacles: The scene's fixed boxes (tables, shelves) for the collision terms.
    """

    q_start: np.ndarray
    objects: tuple[ObjectModel, ...]
    object_starts: np.ndarray
    supports: tuple[Support, ...]
    support_heights: np.ndarray
    keyframes: Sequence[Keyframe]
    hand_points: np.ndarray
    hand_frames: np.ndarray
    obstacles: tuple[Obstacle, ...] = ()

    @property
    def layout(self) -> NodeLayout:
        return NodeLayout.of(len(self.objects))


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
        compile_flags: The C compiler's flags (:mod:`locoman.to.compile`). ``-O0`` by
            default: a pipeline compiles each structure once and solves it once, and gcc's
            optimiser costs more than it saves there (``tiny``: 27 s to build against 147 s
            with ``-O1``, for 0.133 against 0.108 s per iteration; S2's exact libraries
            took 37 min with ``-O1``). A grid that repeats many solves may want ``-O1``.
        print_level: IPOPT's print level (5: one line per iteration, the progress).
        warm_start: Sec. IV-C.2: each subtask's nodes start at its keyframe; otherwise
            every node starts at the initial state.
        max_wall_time_s: IPOPT's max_wall_time [s]: a solve stopped by it is a failed solve
            (status ``Maximum_WallTime_Exceeded``); None: no limit. The grids' time limit.
        hessian: The Hessian of the Lagrangian IPOPT gets (:data:`HESSIANS`).
            ``gauss_newton`` (default): the costs' exact Hessian, the penalties' Gauss-Newton
            one, and none of the constraints' second derivatives; ``exact``: with the
            constraints' lambda' nabla^2 g and the stage penalties' r nabla^2 r too (the
            self-collision penalties stay Gauss-Newton). Both converge to the same KKT
            points (the Hessian is not in the KKT conditions), but only the exact one
            converges fast where penalties are active at the optimum: S1's exact phase with
            the penalties' Gauss-Newton Hessian crawled (1000 iterations, scaled dual
            infeasibility 1e-3 .. 1e-2, regularised in every iteration), and from where it
            stopped the exact one converged in 107. On ``tiny`` the exact one is indefinite
            (the products f dt and v dt of (1), the kinematics' trigonometry), IPOPT
            regularised it in nearly every iteration (2.3 factorisations each) and took 148
            iterations, 24 s, where Gauss-Newton takes 58, 4.6 s, to the same cost
            (measured before the penalties' curvature was in it).
        exact_after_iterations: With the ``gauss_newton`` Hessian: a solve that has not
            converged after this many iterations goes on from its primal-dual point with the
            ``exact`` one (built, and compiled, the first time it is needed), up to
            ``max_iterations`` in all; None: Gauss-Newton throughout. Gauss-Newton leaves
            out the constraints' curvature, and where that curvature matters IPOPT cycles
            near the optimum: S2's pick alone (30 nodes) repeated one 100-iteration cycle
            at cost 217.4 until iteration 500, where the exact Hessian converged in 86
            (cost 213.5); on all of S2 (208 nodes) the exact Hessian from the start was at
            cost 1.8e4 after 480 iterations, Gauss-Newton cycled at 2096 with a violation
            of 1e-4 .. 1e-1, and 300 Gauss-Newton iterations then 68 exact ones converged
            (cost 2096.4; measured before the trolley's collision boxes). ``tiny``
            converges before the switch.
    """

    backend: str = "ipopt_mumps"
    dt_bounds: list[float] = dataclasses.field(default_factory=lambda: [0.02, 0.08])
    max_iterations: int = 500
    tolerance: float = 1e-4
    constraint_tolerance: float = 1e-8
    compile: bool = True
    compile_flags: list[str] = dataclasses.field(default_factory=lambda: ["-O0"])
    print_level: int = 5
    warm_start: bool = True
    max_wall_time_s: float | None = None
    hessian: str = "gauss_newton"
    exact_after_iterations: int | None = 150

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
        if self.exact_after_iterations is not None and self.exact_after_iterations < 1:
            errors.append(("exact_after_iterations", "must be >= 1, or null for never"))
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


def push_steps(inputs: TOInputs, keyframe: Keyframe, cfg: ScheduleCfg) -> int:
    """Steps of a ``push`` after its keyframe: each foot steps often enough to follow the
    object from its keyframe pose to its goal with steps of at most ``step_length_m``."""
    if keyframe.goal is None:
        return 0
    travel = float(np.linalg.norm(keyframe.goal[:2] - keyframe.object_poses[keyframe.object][:2]))
    return 2 * math.ceil(travel / cfg.step_length_m)


def build_schedule(inputs: TOInputs, cfg: ScheduleCfg) -> Schedule:
    """Phases of every subtask; steps where the keyframes' feet move (Sec. IV); a ``step``'s
    two swings onto its object cover two of them."""
    phases = []
    feet_before, yaw_before = sole_points(inputs.q_start)[:, :2], _yaw(inputs.q_start)
    raised = False
    for i, kf in enumerate(inputs.keyframes):
        feet = sole_points(kf.q35)[:, :2]
        steps = step_count(feet_before, feet, yaw_before, _yaw(kf.q35), cfg)
        if kf.predicate == "step":
            steps = max(steps - 2, 0)
        # Lead with the foot on the side the robot moves or turns to.
        heading = np.array([math.cos(yaw_before), math.sin(yaw_before)])
        move = feet.mean(axis=0) - feet_before.mean(axis=0)
        lateral = heading[0] * move[1] - heading[1] * move[0]
        turn = math.remainder(_yaw(kf.q35) - yaw_before, math.tau)
        first_right = (lateral + 0.3 * turn) < 0.0
        pushed = push_steps(inputs, kf, cfg) if kf.predicate == "push" else 0
        phases += subtask_phases(kf.predicate, i, steps, first_right, cfg, pushed, raised)
        raised = raised or kf.predicate == "step"
        feet_before, yaw_before = feet, _yaw(kf.q35)
        if pushed:  # the feet follow the object to its goal
            feet_before = feet_before + (kf.goal[:2] - kf.object_poses[kf.object][:2])
    return Schedule.from_phases(phases)


def _supports(inputs: TOInputs, schedule: Schedule) -> list[list[tuple[Support | None, float]]]:
    """Per node, each object's (support, surface height [m]): where the scene has it until
    a subtask carries it, None while carried, then what its ``place`` subtask sets it on."""
    current = list(zip(inputs.supports, inputs.support_heights, strict=True))
    out = []
    for n in range(schedule.nodes):
        phase = schedule.phase(n)
        kf = inputs.keyframes[phase.subtask]
        if n == 0 or kf.object is None:
            pass
        elif phase.carried:
            current[kf.object] = (None, 0.0)
        elif current[kf.object][0] is None:
            if kf.support is None:
                raise ValueError(
                    f"subtask {phase.subtask} ({kf.predicate}) sets object {kf.object} down "
                    "without a support to set it on"
                )
            current[kf.object] = (kf.support, kf.support_height)
        out.append(list(current))
    return out


def _active_from(inputs: TOInputs, schedule: Schedule, supports) -> list[int]:
    """Per object, the first node at which it is simulated: a hand touches it, or it rests
    on, or carries, a simulated object (the trolley once the box is set on it); never:
    the node count."""
    n = schedule.nodes
    first = [n] * len(inputs.objects)
    for k in range(1, n):
        phase = schedule.phase(k)
        if any(phase.hands):
            j = inputs.keyframes[phase.subtask].object
            first[j] = min(first[j], k)
    changed = True
    while changed:
        changed = False
        for k in range(n):
            for j, (support, _) in enumerate(supports[k]):
                if not isinstance(support, OnObject):
                    continue
                b = support.base
                if min(first[j], first[b]) <= k < max(first[j], first[b]):
                    # The later of the two joins the simulation here; the earlier keeps
                    # its start (the box stays simulated from its pick on).
                    first[j if first[j] > k else b] = k
                    changed = True
    return first


def stood_on(inputs: TOInputs, subtask: int) -> Keyframe | None:
    """The keyframe of the last ``step`` up to ``subtask``: where raised feet stand."""
    steps = [kf for kf in inputs.keyframes[: subtask + 1] if kf.predicate == "step"]
    return steps[-1] if steps else None


def node_modes(inputs: TOInputs, schedule: Schedule) -> list[NodeMode]:
    """The contact mode of every node."""
    supports = _supports(inputs, schedule)
    first = _active_from(inputs, schedule, supports)
    modes = []
    for n in range(schedule.nodes):
        phase = schedule.phase(n)
        touched = inputs.keyframes[phase.subtask].object
        hands = tuple(touched if (h and n > 0) else None for h in phase.hands)
        step = stood_on(inputs, phase.subtask)
        feet_on = tuple(
            step.object if (on and down and step is not None) else None
            for on, down in zip(phase.feet_raised, phase.feet, strict=True)
        )
        objects = tuple(
            ObjectMode(n >= first[j], supports[n][j][0]) for j in range(len(inputs.objects))
        )
        underfoot = tuple(
            j
            for j, (support, height) in enumerate(supports[n])
            if support is not None and support.base is None and height <= FLOOR_HEIGHT_MAX
        )
        modes.append(NodeMode(phase.feet, hands, objects, feet_on, underfoot))
    return modes


def node_parameters(
    inputs: TOInputs, schedule: Schedule, keyframe_costs: tuple[bool, bool]
) -> np.ndarray:
    """(n_params, N): references and switches per node.

    The yaw reference goes linearly, over each subtask's nodes, from the previous keyframe's
    yaw to the subtask's. (9) is on at each keyframe node, (10) on the stance nodes around
    it (after the subtask's last step before it, before its next); ``keyframe_costs`` =
    (base, foot) switches them. A
    subtask's goal holds its object at the subtask's last node. The hands' contacts are
    those on the object they touch, elsewhere on the first object a hand touches.
    """
    layout = inputs.layout
    par, opar = layout.parameters, layout.object_parameters
    n = schedule.nodes
    P = np.zeros((layout.n_params, n))
    kf_nodes = schedule.keyframe_nodes()
    yaw_before = _yaw(inputs.q_start)
    for i, kf in enumerate(inputs.keyframes):
        nodes = [k for k in range(1, n) if schedule.subtask_of(k) == i]
        yaws = np.linspace(yaw_before, _yaw(kf.q35), len(nodes) + 1)[1:]
        P[par["yaw_ref"].start, nodes] = yaws
        if i == 0:
            P[par["yaw_ref"].start, 0] = yaw_before
        yaw_before = _yaw(kf.q35)
        node = kf_nodes[i]
        if keyframe_costs[0]:
            P[par["kf_base_on"], node] = 1.0
            P[par["kf_base"], node] = np.r_[kf.q35[2], kf.q35[3:6]]
        if keyframe_costs[1]:
            # The stance around the keyframe: after the last step before it, up to the next
            # step (a push walks on after its keyframe).
            swings = [k for k in nodes if not schedule.phase(k).stance]
            after = max((k for k in swings if k < node), default=nodes[0] - 1)
            until = min((k for k in swings if k > node), default=nodes[-1] + 1)
            stance = [k for k in nodes if after < k < until]
            P[par["kf_foot_on"], stance] = 1.0
            P[par["kf_foot"], stance] = sole_points(kf.q35)[:, :2].mean(axis=0)[:, None]
        if kf.goal is not None:
            P[opar(kf.object, "goal"), nodes[-1]] = kf.goal
            P[opar(kf.object, "goal_on"), nodes[-1]] = 1.0
    for k, row in enumerate(_supports(inputs, schedule)):
        for j, (_, height) in enumerate(row):
            P[opar(j, "support_z"), k] = height
    surface = par["foot_surface_z"].start
    for k in range(n):
        phase, step = schedule.phase(k), stood_on(inputs, schedule.subtask_of(k))
        for i in range(2):
            # A raised foot stands on, or a swinging one lands on, the stepped-on top.
            if phase.feet_raised[i] and step is not None:
                P[surface + i, k] = step.step_height
    modes = node_modes(inputs, schedule)
    first = next((j for m in modes for j in m.hands if j is not None), 0)
    points, frames = par["hand_points"].start, par["hand_frames"].start
    for k, mode in enumerate(modes):
        for i, j in enumerate(mode.hands):
            j = first if j is None else j
            P[points + 3 * i : points + 3 * i + 3, k] = inputs.hand_points[j, i]
            P[frames + 9 * i : frames + 9 * i + 9, k] = inputs.hand_frames[j, i].ravel(order="F")
    return P


# Bounds that no motion of the task comes near; they keep IPOPT's steps where the model
# means something (a Newton step along a weakly penalised direction, such as a contact force
# [N], could otherwise jump by hundreds and tip the next iterate's Euler angles over).
TILT_MAX = math.pi / 3  # object roll, pitch [rad]
# Base roll, pitch [rad]: a G1 bending to a box on the floor pitches its pelvis to ~77 deg;
# 83 deg keeps the Euler-rate map of (1) well conditioned (cos 83 deg = 0.12).
BASE_TILT_MAX = 1.45
LINEAR_SPEED_MAX = 5.0  # base and object [m/s]
ANGULAR_SPEED_MAX = 2.0 * math.pi  # base and object Euler rates [rad/s]
WRENCH_LEVER = 0.5  # moment bound per newton of force bound [m]


def _sanity_bounds(layout: NodeLayout, lo: np.ndarray, hi: np.ndarray, weight: float) -> None:
    """:data:`BASE_TILT_MAX`, :data:`TILT_MAX` and the speed bounds on the base and the
    objects; every contact force within twice the weight of robot and objects [N], every
    moment within that times :data:`WRENCH_LEVER`."""
    var = layout.variables
    pairs = [(var["q"], var["v"], BASE_TILT_MAX)] + [
        (layout.object_variables(j, "q"), layout.object_variables(j, "v"), TILT_MAX)
        for j in range(layout.n_objects)
    ]
    for q_slice, v_slice, tilt in pairs:
        q, v = q_slice.start, v_slice.start
        lo[q + 3 : q + 5], hi[q + 3 : q + 5] = -tilt, tilt
        lo[v : v + 3], hi[v : v + 3] = -LINEAR_SPEED_MAX, LINEAR_SPEED_MAX
        lo[v + 3 : v + 6], hi[v + 3 : v + 6] = -ANGULAR_SPEED_MAX, ANGULAR_SPEED_MAX
    force = 2.0 * weight
    wrenches = [var["foot_wrench"], var["hand_wrench"]] + [
        layout.object_variables(j, "support_wrench") for j in range(layout.n_objects)
    ]
    for block in wrenches:
        for f in range(block.start, block.stop, 6):
            lo[f : f + 3], hi[f : f + 3] = -force, force
            lo[f + 3 : f + 6], hi[f + 3 : f + 6] = -WRENCH_LEVER * force, WRENCH_LEVER * force


def _rest_wrench(mass: float) -> np.ndarray:
    """(6,) the support's wrench on an object of ``mass`` [kg] at rest."""
    return np.r_[0.0, 0.0, mass * GRAVITY, 0.0, 0.0, 0.0]


def bounds(
    inputs: TOInputs,
    schedule: Schedule,
    modes: list[NodeMode],
    cfg: SolverCfg,
    homotopy: bool = False,
    end_lift_m: float = 0.0,
) -> tuple[np.ndarray, np.ndarray]:
    """Variable bounds (width, N): joint position and velocity limits, the initial state,
    robot and objects at rest at the end, an object still carried at the end at least
    ``end_lift_m`` [m] above where it rested at its grasp keyframe, inactive contacts'
    wrenches and slacks at zero, the objects not yet simulated at rest where the scene has
    them; (13)'s alpha in [0, 1] with a ``homotopy`` kind, else 0."""
    layout = inputs.layout
    var, ovar = layout.variables, layout.object_variables
    model = g1.g1_pinocchio_model()
    n = schedule.nodes
    lo, hi = np.full((layout.width, n), -np.inf), np.full((layout.width, n), np.inf)

    def fix(where, k, value=0.0) -> None:
        lo[where, k] = hi[where, k] = value

    q, v = var["q"], var["v"]
    lo[q.start + 6 : q.stop], hi[q.start + 6 : q.stop] = (
        model.lowerPositionLimit[7:, None],
        model.upperPositionLimit[7:, None],
    )
    lo[v.start + 6 : v.stop], hi[v.start + 6 : v.stop] = (
        -model.velocityLimit[6:, None],
        model.velocityLimit[6:, None],
    )
    dt = var["dt"].start
    lo[dt], hi[dt] = cfg.dt_bounds
    lo[var["alpha"]], hi[var["alpha"]] = 0.0, 1.0 if homotopy else 0.0
    fix(dt, -1, cfg.dt_bounds[0])
    masses = [obj.mass for obj in inputs.objects]
    _sanity_bounds(layout, lo, hi, (pin.computeTotalMass(model) + sum(masses)) * GRAVITY)
    fix(q, 0, inputs.q_start)
    # The motion starts and ends at rest, the objects too (evaluate checks that they stand
    # still on a support at the end; without this tiny's box still turned at 0.37 rad/s).
    fix(v, 0)
    fix(v, -1)
    for j in range(layout.n_objects):
        fix(ovar(j, "v"), -1)
        if modes[-1].carried(j):
            grasped = inputs.keyframes[schedule.subtask_of(n - 1)].object_poses[j]
            lo[ovar(j, "q").start + 2, -1] = grasped[2] + end_lift_m
    for k, mode in enumerate(modes):
        last = k == n - 1
        for i in range(2):
            foot = var["foot_wrench"].start + 6 * i
            hand = var["hand_wrench"].start + 6 * i
            if not mode.feet[i] or last:
                fix(slice(foot, foot + 6), k)
            if mode.hands[i] is None or last:
                fix(slice(hand, hand + 6), k)
            if not mode.feet[i] or k == 0:
                fix(var["foot_slack"].start + i, k)
            if mode.hands[i] is None:
                s = var["hand_slack"].start + 3 * i
                fix(slice(s, s + 3), k)
        for j, obj_mode in enumerate(mode.objects):
            support = ovar(j, "support_wrench")
            if not obj_mode.active:
                fix(ovar(j, "q"), k, inputs.object_starts[j])
                fix(ovar(j, "v"), k)
                fix(support, k, _rest_wrench(masses[j]))
            elif obj_mode.support is None or last:
                fix(support, k)
            if not mode.supported(j):
                fix(ovar(j, "support_slack"), k)
    return lo, hi


SQUEEZE_MARGIN = 2.0


def push_shift(inputs: TOInputs, schedule: Schedule, k: int) -> np.ndarray:
    """(3,) [m] how far the warm start moves node k of a ``push`` after its keyframe: the
    fraction of the subtask's nodes after the keyframe times the way to the goal (xy)."""
    subtask = schedule.subtask_of(k)
    kf = inputs.keyframes[subtask]
    node = schedule.keyframe_nodes()[subtask]
    if kf.predicate != "push" or kf.goal is None or k <= node:
        return np.zeros(3)
    last = max(m for m in range(schedule.nodes) if schedule.subtask_of(m) == subtask)
    way = kf.goal[:2] - kf.object_poses[kf.object][:2]
    return np.r_[(k - node) / (last - node) * way, 0.0]


def _carried_load(inputs: TOInputs, mode: NodeMode, j: int) -> float:
    """[kg] object j's mass and what rests on it, transitively."""
    return inputs.objects[j].mass + sum(_carried_load(inputs, mode, r) for r in mode.riders(j))


def initial_guess(
    inputs: TOInputs,
    schedule: Schedule,
    modes: list[NodeMode],
    cfg: SolverCfg,
    robot_mass: float,
    homotopy: bool = False,
) -> np.ndarray:
    """(width, N): Sec. IV-C.2's subtask-like warm start: each subtask's nodes at its
    keyframe (robot and objects), at rest, the weight shared by the feet in contact, each
    supported object's load by its support, and a carried object's weight by the hands,
    which squeeze it hard enough for their friction cones (3a) to hold it,
    :data:`SQUEEZE_MARGIN` times over. After a ``push`` keyframe the robot, the pushed object
    and what rides on it move towards the goal, evenly over the nodes (:func:`push_shift`)."""
    layout = inputs.layout
    var, ovar = layout.variables, layout.object_variables
    n = schedule.nodes
    X = np.zeros((layout.width, n))
    X[var["dt"]] = 0.5 * sum(cfg.dt_bounds)
    X[var["alpha"]] = 1.0 if homotopy else 0.0
    for k in range(n):
        mode = modes[k]
        kf = inputs.keyframes[schedule.subtask_of(k)]
        use_kf = cfg.warm_start and k > 0
        shift = push_shift(inputs, schedule, k) if use_kf else np.zeros(3)
        X[var["q"], k] = kf.q35 if use_kf else inputs.q_start
        X[var["q"].start : var["q"].start + 3, k] += shift
        weight = robot_mass * GRAVITY
        pushed = [kf.object, *mode.riders(kf.object)] if kf.object is not None else []
        for j, obj in enumerate(inputs.objects):
            active = use_kf and mode.objects[j].active
            X[ovar(j, "q"), k] = kf.object_poses[j] if active else inputs.object_starts[j]
            if active and j in pushed:
                X[ovar(j, "q").start : ovar(j, "q").start + 3, k] += shift
            if mode.carried(j):
                weight += obj.mass * GRAVITY
                R_object = rpy_to_matrix(X[ovar(j, "q"), k][3:6])
                half = 0.5 * obj.mass * GRAVITY
                for i in range(2):
                    s = var["hand_wrench"].start + 6 * i
                    normal = R_object @ inputs.hand_frames[j, i][:, 2]
                    squeeze = SQUEEZE_MARGIN * half / obj.friction
                    X[s : s + 3, k] = np.r_[0.0, 0.0, -half] + squeeze * normal
            elif mode.supported(j):
                load = _carried_load(inputs, mode, j)
                X[ovar(j, "support_wrench").start + 2, k] = load * GRAVITY
        down = [i for i in range(2) if mode.feet[i]]
        for i in down:
            X[var["foot_wrench"].start + 6 * i + 2, k] = weight / len(down)
            if mode.feet_on[i] is not None:  # the object stood on carries it to its support
                X[ovar(mode.feet_on[i], "support_wrench").start + 2, k] += weight / len(down)
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
        self.end_lift_m = schedule_cfg.end_lift_m
        if weights.average_over_nodes:
            weights = averaged_over_nodes(weights, self.schedule.nodes)
        self.inputs, self.cfg, self.weights = inputs, solver, weights
        self.collision = collision
        self.modes = node_modes(inputs, self.schedule)
        self.layout = inputs.layout
        model = g1.g1_pinocchio_model()
        self.kin = SymbolicKinematics(model)
        builder = StageBuilder(
            self.kin,
            inputs.objects,
            contact_frames(),
            weights,
            contact,
            collision,
            inputs.obstacles,
        )
        n = self.schedule.nodes
        keys: dict[tuple, list[int]] = {}
        for k in range(n - 1):
            keys.setdefault((self.modes[k], self.modes[k + 1], k == n - 2), []).append(k)
        self._builder, self._stage_keys = builder, keys
        self.kinematics = builder.kinematics
        self.parameters = builder.parameters
        self._cache_dir = cache_dir
        exact = solver.hessian == "exact"
        self.switch_at = None if exact else solver.exact_after_iterations
        if self.switch_at is not None and self.switch_at >= solver.max_iterations:
            self.switch_at = None
        self._ipopt = {
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
            self._ipopt["max_wall_time"] = float(solver.max_wall_time_s)
        first = {} if self.switch_at is None else {"max_iter": self.switch_at}
        self.nlp = self._build_nlp(exact, first)
        self._exact_nlp: StageNLP | None = self.nlp if exact else None

    def _build_nlp(self, curvature: bool, limits: dict) -> StageNLP:
        """The NLP with the constraints' and penalties' curvature in its Hessian or not
        (Gauss-Newton),
        compiled or loaded from the cache."""
        builder, n = self._builder, self.schedule.nodes
        groups = [
            builder.group(*key, np.array(stages), curvature)
            for key, stages in self._stage_keys.items()
        ]
        groups.append(builder.kinematics_group(np.arange(n), curvature))
        self_collision = builder.self_collision_group(np.arange(1, n))
        if self_collision is not None:
            groups.append(self_collision)
        return StageNLP(
            self.layout.width,
            n,
            self.layout.n_params,
            builder.parameters.vector().size,
            groups,
            self._ipopt | limits,
            self._cache_dir if self.cfg.compile else None,
            self.cfg.compile_flags,
        )

    @property
    def exact_nlp(self) -> StageNLP:
        """The NLP with the exact Hessian, built the first time a solve switches to it."""
        if self._exact_nlp is None:
            self._exact_nlp = self._build_nlp(True, {})
        return self._exact_nlp

    @property
    def build_time_s(self) -> float:
        """Time spent building (and compiling) the NLPs so far [s]."""
        built = [self.nlp] + ([self._exact_nlp] if self._exact_nlp not in (None, self.nlp) else [])
        return sum(nlp.build_time_s for nlp in built)

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
        inputs = dataclasses.replace(self.inputs, objects=parameters.objects(self.inputs.objects))
        schedule, modes = self.schedule, self.modes
        P = node_parameters(inputs, schedule, keyframe_costs)
        homotopy = self.collision.homotopy
        lo, hi = bounds(inputs, schedule, modes, self.cfg, homotopy, self.end_lift_m)
        X0 = initial_guess(inputs, schedule, modes, self.cfg, self.kin.mass, homotopy)
        X0 = np.clip(X0, lo, hi)
        var = self.layout.variables
        q, v = X0[var["q"]], X0[var["v"]]
        X0[var["kin"]] = np.asarray(self.kinematics.map(schedule.nodes)(q, v))
        args = (X0.ravel(order="F"), lo.ravel(order="F"), hi.ravel(order="F"), P)
        theta = parameters.vector()
        result = self.nlp.solve(
            *args, theta, warm_start.warm_start if warm_start is not None else None
        )
        if result.success or self.switch_at is None or result.iterations < self.switch_at:
            return self._trajectory(result)
        # Gauss-Newton used its share of the iterations without converging: the exact
        # Hessian goes on from its primal-dual point with what is left.
        limits = {"max_iter": self.cfg.max_iterations - result.iterations}
        if self.cfg.max_wall_time_s is not None:
            limits["max_wall_time"] = max(self.cfg.max_wall_time_s - result.solve_time_s, 1.0)
        print(
            f"[solve] not converged after {result.iterations} Gauss-Newton iterations "
            f"({result.status}): on with the exact Hessian",
            flush=True,
        )
        polished = self.exact_nlp.solve(*args, theta, result.warm_start, limits)
        return self._trajectory(polished, before=result)

    def _trajectory(self, result: NLPResult, before: NLPResult | None = None) -> Trajectory:
        """The trajectory of ``result``; ``before``: the Gauss-Newton phase it went on from."""
        n, layout = self.schedule.nodes, self.layout
        Z = result.x.reshape(n, layout.width)

        def part(name: str) -> np.ndarray:
            return Z[:, layout.variables[name]]

        def per_object(quantity: str) -> np.ndarray:
            return np.stack(
                [Z[:, layout.object_variables(j, quantity)] for j in range(layout.n_objects)],
                axis=1,
            )

        objects = [m.objects for m in self.modes]
        phases = [self.schedule.phase(k).name if k > 0 else "start" for k in range(n)]
        return Trajectory(
            status=result.status,
            success=result.success,
            iterations=result.iterations + (before.iterations if before else 0),
            solve_time_s=result.solve_time_s + (before.solve_time_s if before else 0.0),
            build_time_s=self.build_time_s,
            exact_iterations=(
                result.iterations if before is not None or self.cfg.hessian == "exact" else 0
            ),
            alpha_max=float(part("alpha").max()),
            n_variables=self.nlp.n_x,
            n_constraints=self.nlp.n_g,
            max_constraint_violation=result.max_constraint_violation,
            cost=result.cost,
            q=part("q"),
            v=part("v"),
            foot_wrench=part("foot_wrench").reshape(n, 2, 6),
            hand_wrench=part("hand_wrench").reshape(n, 2, 6),
            object_q=per_object("q"),
            object_v=per_object("v"),
            support_wrench=per_object("support_wrench"),
            foot_slack=part("foot_slack"),
            hand_slack=part("hand_slack").reshape(n, 2, 3),
            support_slack=per_object("support_slack")[:, :, 0],
            dt=part("dt")[:, 0],
            feet_contact=np.array([m.feet for m in self.modes]),
            foot_object=np.array(
                [[-1 if j is None else j for j in m.feet_on] for m in self.modes], dtype=int
            ),
            hand_object=np.array(
                [[-1 if j is None else j for j in m.hands] for m in self.modes], dtype=int
            ),
            object_active=np.array([[o.active for o in row] for row in objects]),
            support_kind=np.array(
                [[o.support.name if o.support else "none" for o in row] for row in objects]
            ),
            support_base=np.array(
                [[_base_index(o.support) for o in row] for row in objects],
                dtype=int,
            ),
            phase=np.array(phases),
            subtask=np.array([self.schedule.subtask_of(k) for k in range(n)]),
            hand_points=self.inputs.hand_points.copy(),
            warm_start=result.warm_start,
        )


def _base_index(support: Support | None) -> int:
    """The supporting object's index, -1 for the world or none."""
    base = getattr(support, "base", None)
    return -1 if base is None else base


def object_pose(T: np.ndarray) -> np.ndarray:
    """(6,) (p, rpy) of a 4x4 transform."""
    return np.r_[T[:3, 3], matrix_to_rpy(T[:3, :3])]
