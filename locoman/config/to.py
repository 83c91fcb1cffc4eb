"""Typed configuration of the whole-body TO and its evaluation (paper A, Sec. IV and V).

Sections ``solve`` and ``evaluate``. The keyframe ablations of Sec. V-C (none, base, foot,
warm start, all) are the switches ``keyframe_base``, ``keyframe_foot`` and
``solver.warm_start``.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

from locoman.config.cost import at_most
from locoman.contact.io import CONTACT_FIELDS
from locoman.errors import ConfigError
from locoman.to.assembly import HESSIANS
from locoman.to.collision import KINDS, TREATMENTS, CollisionCfg
from locoman.to.costs import CostWeights
from locoman.to.schedule import ScheduleCfg


@dataclass
class ContactCfg:
    """Contact parameters of the TO.

    Attributes:
        floor_friction: mu of the feet on the ground [-].
        stiffness: k_z of (2a) [1/s].
        prehensile: Hands grasp the object: (3) is dropped for them (paper A, Sec. IV-A.2).
        palm_half_extents_m: Half sizes of a palm's patch for the CoP of (3b) [m].
        slack_max_m: The most each slack s of (2a), (4) and the hands' contacts may take,
            |s| <= slack_max_m [m]: with the slack cost (Table I) alone a converged solve
            could sink a support or a hand by centimetres (``docs/deviations.md``). None:
            unbounded, the cost alone.
    """

    floor_friction: float = 0.8
    stiffness: float = 50.0
    prehensile: bool = False
    palm_half_extents_m: list[float] = field(default_factory=lambda: [0.04, 0.03])
    slack_max_m: float | None = 0.004

    def check(self) -> list[tuple[str, str]]:
        errors = []
        if self.floor_friction <= 0.0 or self.stiffness <= 0.0:
            errors.append(("stiffness", "friction and stiffness must be > 0"))
        if len(self.palm_half_extents_m) != 2 or min(self.palm_half_extents_m) <= 0.0:
            errors.append(("palm_half_extents_m", "needs two half sizes > 0 m"))
        if self.slack_max_m is not None and not self.slack_max_m > 0.0:
            errors.append(("slack_max_m", "must be > 0 m, or null for no bound"))
        return errors


# The solver backends (``solve.solver.backend``): IPOPT's options for each. MUMPS is the
# default, with the approximate minimum degree ordering: its automatic choice took twice as
# long in the linear algebra on tiny (18.9 s against 9.3 s, the same 85 iterations).
BACKENDS: dict[str, dict[str, object]] = {
    "ipopt_mumps": {"linear_solver": "mumps", "mumps_pivot_order": 0},
    "ipopt_spral": {"linear_solver": "spral"},
}


@dataclass
class SolverCfg:
    """IPOPT and the time grid.

    Attributes:
        backend: A key of :data:`BACKENDS`: IPOPT with MUMPS or with SPRAL.
        dt_bounds: Bounds of each time step [s].
        max_iterations: IPOPT's max_iter.
        tolerance: IPOPT's tol, on its scaled optimality error.
        constraint_tolerance: IPOPT's constr_viol_tol [SI units of each constraint]: the
            dynamics (1) hold to this, whatever ``tolerance``.
        compile: Compile the terms' derivatives to C (cached by their hash, once per
            robot) instead of interpreting them: several times faster per iteration.
        compile_flags: The C compiler's flags (:mod:`locoman.to.compile`). ``-O1`` by
            default, with gcc: the set is compiled once per robot (about 50 s, the G1's
            kinematics most of it) and every solve runs faster for it; ``-O0`` builds
            with tcc where it is installed (a few seconds), for slower evaluations
            (``benchmarks/results/to_solvers.json``).
        print_level: IPOPT's print level: 0 (default) prints nothing of IPOPT's own; 5
            its table, a line per iteration.
        progress_every: Iterations between two progress lines of a solve (iteration,
            objective, constraint violation, phase or round; the ``logging`` logger
            ``locoman.to.progress``); 0: none.
        warm_start: Sec. IV-C.2: each subtask's nodes start at its keyframe; otherwise
            every node starts at the initial state.
        max_wall_time_s: IPOPT's max_wall_time [s]: a solve stopped by it is a failed solve
            (status ``Maximum_WallTime_Exceeded``); None: no limit. The grids' time limit.
        hessian: The Hessian of the Lagrangian IPOPT gets (:data:`HESSIANS`).
            ``gauss_newton`` (default): the costs' Hessian and the penalties'
            Gauss-Newton one, without the constraints' second derivatives; ``exact``: with
            them and the penalties' r nabla^2 r (but the robot's own sphere pairs');
            ``projected``: the exact one with each term call's Hessian projected onto the
            positive semidefinite cone (:mod:`locoman.to.convexify`), so that IPOPT needs
            no inertia corrections (S1 in a third of the iterations; on S2 it can settle in
            a worse basin: ``docs/performance.md``). All lead to KKT points of the same
            problem; the exact one converges fast near an optimum and is indefinite far
            from it (``docs/trajectory-optimisation.md``).
        exact_after_iterations: With another Hessian than ``exact``: a solve that has not
            converged after this many iterations goes on from its primal-dual point with the
            ``exact`` one, up to ``max_iterations`` in all (the others converge linearly
            near an optimum where the constraints' curvature matters); None: never.
        exact_when_stalled: With another Hessian than ``exact``: the relative change of
            the objective per iteration [-] under which (for 10 iterations, near
            feasibility) the solve goes on with the exact Hessian before
            ``exact_after_iterations`` (1e-3 suits the projected Hessian); None: only
            after them.
        settled_change: The exact Hessian's solves end as converged at an acceptable
            level (IPOPT's ``Solved_To_Acceptable_Level``) after ``settled_iterations``
            iterations in a row with the objective changing by less than this relative
            amount [-], the constraints within ``constraint_tolerance`` and
            complementarity under 1e-9: a KKT point whose dual infeasibility stays above
            ``tolerance`` with IPOPT's barrier at its floor (S2's grid cells cycled there
            for hundreds of iterations); None: only at ``tolerance``.
        settled_iterations: How many such iterations in a row.
        mumps_scaling: With MUMPS: let it scale the KKT matrix and permute it to a
            maximum transversal before it factorises (IPOPT's ``mumps_scaling`` 77 and
            ``mumps_permuting_scaling`` 7, MUMPS's automatic choices). False (default):
            neither (both 0), since IPOPT scales the NLP already; the factorisations are
            a third cheaper on S2 (0.195 s an iteration against 0.312) and two fifths on
            ``tiny``, in as many iterations (``docs/performance.md``). SPRAL ignores it.
        second_order_corrections: IPOPT's ``max_soc``: how many times a trial step the
            filter rejects is corrected for the constraints' curvature before it is cut
            back. 0 (default) cuts it back at once: S2 in 456 iterations instead of 594 to
            the same optimum, S1 in 314 instead of 358, S1's Fig. 6 grid 48 of 48 passing
            either way (``docs/performance.md``); IPOPT's own default is 4.
    """

    backend: str = "ipopt_mumps"
    dt_bounds: list[float] = field(default_factory=lambda: [0.02, 0.08])
    max_iterations: int = 500
    tolerance: float = 1e-4
    constraint_tolerance: float = 1e-8
    compile: bool = True
    compile_flags: list[str] = field(default_factory=lambda: ["-O1"])
    print_level: int = 0
    progress_every: int = 25
    warm_start: bool = True
    max_wall_time_s: float | None = None
    hessian: str = "gauss_newton"
    exact_after_iterations: int | None = 150
    exact_when_stalled: float | None = None
    settled_change: float | None = 1e-7
    settled_iterations: int = 10
    mumps_scaling: bool = False
    second_order_corrections: int = 0

    def check(self) -> list[tuple[str, str]]:
        errors = []
        if len(self.dt_bounds) != 2 or not 0.0 < self.dt_bounds[0] <= self.dt_bounds[1]:
            errors.append(("dt_bounds", "needs [lower, upper] with 0 < lower <= upper [s]"))
        if self.max_iterations < 1 or self.tolerance <= 0.0:
            errors.append(("max_iterations", "needs max_iterations >= 1 and tolerance > 0"))
        errors += at_most("max_iterations", self.max_iterations, 100_000, "IPOPT needs hundreds")
        if self.constraint_tolerance <= 0.0:
            errors.append(("constraint_tolerance", "must be > 0"))
        if not 0 <= self.print_level <= 12:
            errors.append(("print_level", "IPOPT's print level is 0..12"))
        if self.progress_every < 0:
            errors.append(("progress_every", "must be >= 0 iterations (0: no progress lines)"))
        if self.backend not in BACKENDS:
            errors.append(("backend", f"must be one of {sorted(BACKENDS)}"))
        if self.max_wall_time_s is not None and not self.max_wall_time_s > 0.0:
            errors.append(("max_wall_time_s", "must be > 0 s, or null for no limit"))
        if self.hessian not in HESSIANS:
            errors.append(("hessian", f"must be one of {list(HESSIANS)}"))
        if self.settled_change is not None and not 0.0 < self.settled_change < 1.0:
            errors.append(("settled_change", "must be in (0, 1), or null for never"))
        if self.settled_iterations < 1:
            errors.append(("settled_iterations", "must be >= 1"))
        if self.second_order_corrections < 0:
            errors.append(("second_order_corrections", "must be >= 0 (IPOPT's default: 4)"))
        if self.exact_after_iterations is not None and self.exact_after_iterations < 1:
            errors.append(("exact_after_iterations", "must be >= 1, or null for never"))
        if self.exact_when_stalled is not None and not self.exact_when_stalled > 0.0:
            errors.append(("exact_when_stalled", "must be > 0, or null for never"))
        return errors


# ``solve.mode``: ``product`` runs the settings as given; ``paper_a`` runs each scenario as
# paper A's Sec. V-A and V-C did (``solve.paper_a``), for the faithful V-C grid.
MODES = ("product", "paper_a")


@dataclass
class PaperSetCfg:
    """One scenario's TO as paper A ran it in Sec. V-A and V-C (``solve.mode: paper_a``).

    Attributes:
        collision: Sec. V-A's minimal set: collision kind -> treatment (the kinds of
            :class:`~locoman.to.collision.CollisionCfg`); every other kind is off and no
            pairs are found along the solution.
        keyframes: The subtasks (plan indices) whose keyframes guide the TO; null: all
            (:attr:`SolveCfg.keyframes`).
    """

    collision: dict[str, str] = field(default_factory=dict)
    keyframes: list[int] | None = None

    def check(self) -> list[tuple[str, str]]:
        errors = []
        for kind, treatment in self.collision.items():
            if kind not in KINDS or kind.startswith("found"):
                known = [k for k in KINDS if not k.startswith("found")]
                errors.append(("collision", f"{kind!r} is not a collision kind; known: {known}"))
            elif treatment not in TREATMENTS:
                errors.append(("collision", f"{kind}: must be one of {list(TREATMENTS)}"))
        if self.keyframes is not None and (not self.keyframes or min(self.keyframes) < 0):
            errors.append(("keyframes", "needs subtask indices >= 0, or null for all"))
        return errors


@dataclass
class SolveCfg:
    """Stage ``solve``: the TO of each listed scenario.

    Attributes:
        scenarios: Humanoid scenarios the TO runs on (their plans must use the predicates
            :mod:`locoman.to.schedule` knows).
        keyframe_base: Keyframe base cost (9) on.
        keyframe_foot: Keyframe foot cost (10) on.
        contacts: Where the hands hold the object: ``registration`` (the transferred
            contacts, Sec. III-A.2) or ``naive`` (the geometry-unaware baseline, Sec. V-B,
            which swaps the feet on an object too).
        keyframes: The subtasks (plan indices) whose keyframes guide the TO: (9), (10) and
            the warm start; null: all. The others still give the contact schedule and
            the yaw reference; their nodes start at the next guiding keyframe.
        mode: A key of :data:`MODES`: ``product`` (these settings) or ``paper_a`` (each
            scenario as paper A ran it: :func:`scenario_solve`).
        paper_a: Per scenario, paper A's collision set and keyframes for ``paper_a``.
        schedule: Node counts of the contact schedule.
        contact: Contact parameters.
        collision: Collision terms (Sec. IV-D).
        weights: Table I, (9), (10) and the object goal.
        solver: IPOPT, the time grid and the warm start.
        cache_dir: Where compiled derivatives are kept between runs.
    """

    scenarios: list[str] = field(default_factory=lambda: ["tiny"])
    keyframe_base: bool = True
    keyframe_foot: bool = True
    contacts: str = "registration"
    keyframes: list[int] | None = None
    mode: str = "product"
    paper_a: dict[str, PaperSetCfg] = field(default_factory=dict)
    schedule: ScheduleCfg = field(default_factory=ScheduleCfg)
    contact: ContactCfg = field(default_factory=ContactCfg)
    collision: CollisionCfg = field(default_factory=CollisionCfg)
    weights: CostWeights = field(default_factory=CostWeights)
    solver: SolverCfg = field(default_factory=SolverCfg)
    cache_dir: str = ".cache/casadi"

    def check(self) -> list[tuple[str, str]]:
        errors = []
        if self.contacts not in CONTACT_FIELDS:
            errors.append(("contacts", f"must be one of {sorted(CONTACT_FIELDS)}"))
        if self.mode not in MODES:
            errors.append(("mode", f"must be one of {list(MODES)}"))
        if self.keyframes is not None and (not self.keyframes or min(self.keyframes) < 0):
            errors.append(("keyframes", "needs subtask indices >= 0, or null for all"))
        return errors


def scenario_solve(solve: SolveCfg, scenario: str) -> SolveCfg:
    """The ``solve`` settings that ``scenario`` runs with: in mode ``product`` as given; in
    ``paper_a`` paper A's (Sec. V-A, V-C, (14a)): the scenario's minimal collision set with
    every other kind off and no found pairs, the stage and collision costs and (10) averaged
    over the nodes, and the scenario's keyframes.

    Raises:
        ConfigError: ``paper_a`` for a scenario that ``solve.paper_a`` does not describe.
    """
    if solve.mode == "product":
        return solve
    if scenario not in solve.paper_a:
        raise ConfigError(
            f"solve.mode is paper_a, but solve.paper_a has no set for {scenario!r} (it has "
            f"{sorted(solve.paper_a)}): add one in conf/solve/, or run mode product"
        )
    paper = solve.paper_a[scenario]
    collision = dataclasses.replace(
        solve.collision, **(dict.fromkeys(KINDS, "off") | paper.collision)
    )
    return dataclasses.replace(
        solve,
        keyframes=paper.keyframes,
        collision=collision,
        weights=dataclasses.replace(solve.weights, average_over_nodes=True),
    )


@dataclass
class EvaluateCfg:
    """Stage ``evaluate``: the MuJoCo replay and the independent checks.

    Attributes:
        dynamics_tol: Largest residual of (1) that counts as physically consistent
            [kg m/s, kg m^2/s, m].
        friction_tol: Largest violation of (3) allowed [N, N m].
        slip_tol_m: Largest stance-foot slip allowed [m].
        penetration_tol_m: Largest average penetration allowed, paper A's (the robot's
            self, robot-object and robot-environment pairs, :mod:`locoman.sim.penetration`)
            [m].
        max_penetration_tol_m: Largest such penetration at any node, or at any of
            ``substeps`` poses between two (the average hides a deep one) [m].
        scheduled_contact_tol_m: Largest penetration of a scheduled contact (a standing
            sole into its support, a holding hand into its object) at any node: the TO
            holds these on the surface, so a few mm [m].
        object_penetration_tol_m: Largest penetration of an object into furniture, the
            floor or another object at any node [m].
        substeps: Poses checked between two nodes (q and the objects linear along the
            step): a body can pass through a thin one between two nodes.
        goal_tol_m: Largest distance of an object from its target [m], where its subtask
            ends.
        rest_height_tol_m: At the end each object's bottom lies this close to a support's
            top face (the floor or another object's) [m].
        rest_speed_tol: ... and every rate of its (p, rpy) is at most this [m/s, rad/s].
        rest_tilt_tol_rad: ... and its roll and pitch at most this [rad].
        nonholonomic_tol_mps: Largest lateral velocity of a chassis's rear wheels, (7a)
            over each step as the TO holds it [m/s].
        rider_slip_tol_m: Largest slide of a corner of an object's bottom on what supports
            it, a fixed surface or another object, from where it was set down [m].
        lift_tol_m: An object both hands hold at the end is at least this far above the
            support it was taken from (``<object>_lift_m``; S1: the basket) [m].
        filmstrip_frames: Frames in the PNG filmstrip.
    """

    dynamics_tol: float = 1e-6
    friction_tol: float = 1e-6
    slip_tol_m: float = 1e-3
    penetration_tol_m: float = 0.01
    max_penetration_tol_m: float = 0.02
    scheduled_contact_tol_m: float = 0.005
    object_penetration_tol_m: float = 0.02
    substeps: int = 3
    goal_tol_m: float = 0.02
    rest_height_tol_m: float = 0.01
    rest_speed_tol: float = 0.01
    rest_tilt_tol_rad: float = 0.1
    nonholonomic_tol_mps: float = 1e-4
    rider_slip_tol_m: float = 0.005
    lift_tol_m: float = 0.05
    filmstrip_frames: int = 8

    def check(self) -> list[tuple[str, str]]:
        tols = (
            "dynamics_tol",
            "friction_tol",
            "slip_tol_m",
            "penetration_tol_m",
            "max_penetration_tol_m",
            "scheduled_contact_tol_m",
            "object_penetration_tol_m",
            "goal_tol_m",
            "rest_height_tol_m",
            "rest_speed_tol",
            "rest_tilt_tol_rad",
            "nonholonomic_tol_mps",
            "rider_slip_tol_m",
            "lift_tol_m",
        )
        errors = [
            (name, f"must be finite and > 0, got {getattr(self, name)}")
            for name in tols
            if not (math.isfinite(getattr(self, name)) and getattr(self, name) > 0.0)
        ]
        if self.filmstrip_frames < 1:
            errors.append(("filmstrip_frames", "must be >= 1"))
        if not 0 <= self.substeps <= 20:
            errors.append(("substeps", "must be in 0 .. 20"))
        return errors
