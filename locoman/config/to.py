"""Typed configuration of the whole-body TO and its evaluation (paper A, Sec. IV and V).

Sections ``solve`` and ``evaluate``. The keyframe ablations of Sec. V-C (none, base, foot,
warm start, all) are the switches ``keyframe_base``, ``keyframe_foot`` and
``solver.warm_start``.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from locoman.config.cost import at_most
from locoman.contact.io import CONTACT_FIELDS
from locoman.errors import ConfigError
from locoman.scene import g1

# What a schedule may cost: a phase of more nodes, or a problem of more, than this is refused
# before anything is allocated (100000 swing nodes ran 2 min and died with std::bad_alloc).
MAX_PHASE_NODES = 50

MAX_NODES = 1000

TOO_MANY_NODES = "each node adds about 200 variables and their derivatives to the NLP"


@dataclasses.dataclass
class CostWeights:
    """Table I (stance, walking, regularisation, slack) and eqs. (9), (10).

    Attributes:
        com_over_feet: CoM (xy) over the feet's midpoint, stance [-].
        leg_symmetry: Hip pitch/knee alike, hip roll and opposite yaw zero, stance [-].
        foot_yaw_symmetry: Both feet's x axes alike, stance [-].
        base_pose_stance: Base pitch and yaw, stance [-]. The yaw is taken relative to a
            reference per node (the current subtask's keyframe yaw): Table I regularises
            the yaw, and a task that turns the robot needs a yaw to regularise towards.
        foot_clearance: Swing foot ``clearance_m`` above the surface it left, walking [-].
        clearance_m: [m].
        leg_roll: Hip roll angles, walking [-].
        base_pose_walking: Base pitch and yaw (relative, as in stance), walking [-].
        force: Contact forces and moments [-].
        base_linear_velocity: [-].
        base_angular_velocity: [-].
        leg_velocity: [-].
        arm_velocity: [-].
        arm_angle: Arm joint angles towards :data:`ARM_NOMINAL` [-].
        base_height: Base height towards ``base_height_m`` [-].
        base_height_m: [m].
        timestep: Time step towards ``timestep_s`` [-].
        timestep_s: [s].
        slack: Slacks of (2a) and (4) [-].
        keyframe_base: (9): base height and orientation at a keyframe node [-].
        keyframe_foot: (10): feet midpoint at a keyframe's stance [-].
        object_goal: Object position (xy) and yaw at the plan's target, last node; not in
            the paper, which states the target without its cost [-].
        object_upright: Object roll and pitch while it moves (ours) [-].
        collision: Penalties (12) of :mod:`locoman.to.terms.collisions` [-].
        homotopy: w_hom of (13b), on alpha^2 at every node [-] (the paper's 2e2).
        average_over_nodes: (14a): the stage and collision weights are divided by the
            number of nodes N (:func:`averaged_over_nodes`); off, they are summed at the
            weights given, as Table I lists them.
    """

    com_over_feet: float = 5e2
    leg_symmetry: float = 3e2
    foot_yaw_symmetry: float = 1e2
    base_pose_stance: float = 1e1
    foot_clearance: float = 2e3
    clearance_m: float = 0.07
    leg_roll: float = 1e1
    base_pose_walking: float = 1e2
    force: float = 1e-6
    base_linear_velocity: float = 1e-1
    base_angular_velocity: float = 1.0
    leg_velocity: float = 5e-1
    arm_velocity: float = 1.0
    arm_angle: float = 1.0
    base_height: float = 1e2
    base_height_m: float = 0.7
    timestep: float = 1e2
    timestep_s: float = 2e-2
    slack: float = 1e5
    keyframe_base: list[float] = dataclasses.field(default_factory=lambda: [1e2, 1e1])
    keyframe_foot: float = 5e2
    object_goal: float = 1e5
    object_upright: float = 1e2
    collision: float = 1e3
    homotopy: float = 2e2
    average_over_nodes: bool = False

    def check(self) -> list[tuple[str, str]]:
        values = [v for v in dataclasses.asdict(self).values() if isinstance(v, float)]
        errors = []
        if min(values) < 0.0 or min(self.keyframe_base) < 0.0:
            errors.append(("slack", "every weight must be >= 0"))
        if len(self.keyframe_base) != 2:
            errors.append(("keyframe_base", "needs two weights: base height, orientation"))
        if self.timestep_s <= 0.0:
            errors.append(("timestep_s", "must be > 0 s"))
        return errors


# (14a) averages the stage and collision costs over the nodes, the keyframe foot cost (10)
# with them (it is part of the stance cost L_st); the keyframe base cost (9) and the object
# goal are summed once. The rest of these fields are not weights.
SUMMED = ("keyframe_base", "object_goal")

NOT_WEIGHTS = ("clearance_m", "base_height_m", "timestep_s", "average_over_nodes")


def averaged_over_nodes(weights: CostWeights, nodes: int) -> CostWeights:
    """The weights of (14a): every stage and collision weight, (10)'s included, divided by N
    ``nodes``."""
    return dataclasses.replace(
        weights,
        **{
            f.name: getattr(weights, f.name) / nodes
            for f in dataclasses.fields(weights)
            if f.name not in SUMMED + NOT_WEIGHTS
        },
    )


# The links whose spheres the default self-collision pairs use; the pairs measured most in
# MuJoCo replays of tiny: the arms against the torso and the hips. Every arm link from the
# shoulder's yaw link to the palm: without the wrist's roll and pitch links, a solve started
# away from the keyframes (S2's NoKeyframe, 2.5 kg, 0.6 rad) swung the forearm through the
# torso between the modelled links (141 mm deep), and the found pairs' rounds spent 1600
# iterations on it (docs/trajectory-optimisation.md). The knees against each other are a
# kind of their own (paper A, S2: "between the knees when walking", with (11)).
_ARM_LINKS = g1.ARM_CHAIN[g1.ARM_CHAIN.index("shoulder_yaw_link") :]

_TRUNK_LINKS = ("torso_link", "pelvis", "{side}_hip_roll_link", "{side}_hip_yaw_link")

_THIGHS = ("hip_roll_link", "hip_yaw_link")

# How a collision kind enters the TO: not at all, as the penalty (12) on p, as the hard
# constraint (11) p >= 0, or through the homotopy (13) from a smooth stand-in body.
TREATMENTS = ("off", "penalty", "constraint", "homotopy")


def _default_self_pairs() -> list[list[str]]:
    pairs = []
    for side in ("left", "right"):
        for arm in _ARM_LINKS:
            for trunk in _TRUNK_LINKS:
                if arm == "shoulder_yaw_link" and trunk != "torso_link":
                    continue
                pairs.append([f"{side}_{arm}", trunk.format(side=side)])
    # The thighs against the trunk: a bend and a step up fold them onto it.
    pairs += [[f"{side}_{thigh}", "torso_link"] for side in ("left", "right") for thigh in _THIGHS]
    return pairs


@dataclasses.dataclass
class CollisionCfg:
    """The collision terms of the TO (paper A, Sec. IV-D). Each kind has a treatment of
    :data:`TREATMENTS`: ``off``, ``penalty`` (12), ``constraint`` (11) or ``homotopy``
    (13) (the kinds against boxes: a sphere pair is its own smooth stand-in). A treatment is
    data: changing one compiles nothing.

    The defaults follow Sec. V-A's minimal set, but with (12) for the legs against the
    objects and the knees against each other where the paper has (13) and (11): with those
    S2 diverged (``docs/trajectory-optimisation.md``). Pairs the solution needs beyond the
    set are found along it (``found``).

    Attributes:
        self_pairs: Link pairs of the G1 kept apart between their spheres (the arms and
            the trunk).
        self_collision: Treatment of ``self_pairs``.
        knee_pairs: Link pairs of the legs kept apart while walking.
        knee_collision: Treatment of ``knee_pairs``; not ``homotopy``.
        object_body: Between the trunk's body points (pelvis, torso) and each object (its
            box; a trolley's chassis and handle frame).
        hands_object: Between each palm while it does not touch the object, and the
            object; a non-solid object's parts check the forearms too; the elbows always.
            The forearms of the hands holding an open object (a basket) are kept out of
            its parts with the least margin (touching allowed); a free hand is kept out of
            a basket's bounding box (``ObjectModel.reached_from_outside``).
        legs_object: Between the hips', thighs' and shins' spheres and each object's boxes.
        feet_object: Between the feet (a heel and a toe sphere each) and every object
            resting on the floor, but for a foot whose sole rests on its top (S1's box,
            S2's wheels: a wheeled object's wheels, not its chassis box, which the feet
            pass under while pushing).
        hands_environment: Between the palms and forearms and every fixed object's
            bounding box.
        feet_environment: Between the feet and every fixed object's bounding box (off by
            default: with it S2's exact phase crawled).
        found: The pairs found along a solution (:mod:`locoman.to.rounds.search`): every pair
            of bodies that a replay of the solution in MuJoCo finds closer than
            ``audit_margin_m`` and the TO does not model joins the problem at the nodes
            around, and the solve goes on from where it stopped, at most ``rounds`` times;
            ``off``: no rounds, the minimal set alone.
        found_hard: The found pairs still penetrated after a round with them (the pairs that
            keep coming back: a hand through a post, a carried box into a platform) join
            again under this treatment; ``off``, or the same as ``found``: they stay as
            they are.
        rounds: The most rounds of :attr:`found` pairs after the first solve (and after
            each restart).
        restarts: When the rounds end with pairs missing or unfreed, or a round's solve
            fails, the solve starts again from Sec. IV-C.2's guess with every pair found so
            far (present from the first iteration, they keep the motion out of the minimum
            that held it), and the rounds go on from its solution; at most this many times
            (0: never).
        restart_arm_nodes: A restart keeps both arms whole out of each body (an object,
            a fixed object, the floor) that the checks found an arm's link against: every
            link from shoulder to palm against every box of that body, at up to this many
            nodes either side of where it was found while each hand's contact stays the
            same (``found_pairs.arm_pairs``); the rounds' pairs cover the one link and box,
            and moved the penetration to the next. 0 (the default): the pairs found, as
            they are; on S1's three Fig. 6 cells that restart, widening converged as often
            as not (docs/trajectory-optimisation.md).
        audit_margin_m: A pair of bodies closer than this in the replay is found [m].
        audit_substeps: Poses checked between two nodes (linear in q) besides the nodes.
        found_spacing_m: A carried object's found pairs take points along its edges (and
            along the other body's edges) at most this far apart [m]: an edge cuts about
            half this deep into a post between two points (its corners alone let a tilted
            box 30 mm into S2's trolley post).
        unfreed_m: A pair still deeper than this at the last check fails the solve
            (``Collision_Pairs_Unfreed``, the pairs in ``pairs_unfreed``), modelled or not:
            the rounds could not free it [m]. The evaluation's ``max_penetration_tol_m``.
        object_environment: Between the corners of the object, while no support holds it,
            and every fixed object's bounding box, and between the obstacles' vertical and
            top edges and the object (as (11) the bottom corners of a level box are
            dependent, and IPOPT stalled: keep it a penalty).
        object_object: Between the corners of a carried object and every other object's
            boxes, and between those boxes' vertical and top edges and the carried object.
            Off by default: on, S2's box no longer goes 88 mm through the trolley's post in
            the first solve of 7.5 kg, 1.2 rad (which then converges and passes), but S2's
            default solve ends ``Collision_Pairs_Missing``, its box cutting the table's
            corner between two nodes (docs/trajectory-optimisation.md).
        margin_m: Clearance added to every pair [m].
        smoothing_m: Log-sum-exp temperature of the box clearance [m]; it may overstate
            the clearance by up to ln(3) times this, so keep it below ``margin_m``.
        length_m: L, the length that scales a pair's penetration [m] (boxes and spheres).
        softness: Width, in p, over which (12)'s min(p, 0) is smoothed [-]
            (:func:`penetration_residual`); 0.01 is about a millimetre on a box.
    """

    self_pairs: list[list[str]] = dataclasses.field(default_factory=_default_self_pairs)
    self_collision: str = "penalty"
    knee_pairs: list[list[str]] = dataclasses.field(
        default_factory=lambda: [["left_knee_link", "right_knee_link"]]
    )
    knee_collision: str = "penalty"
    object_body: str = "penalty"
    hands_object: str = "penalty"
    legs_object: str = "penalty"
    feet_object: str = "penalty"
    hands_environment: str = "penalty"
    feet_environment: str = "off"
    object_environment: str = "penalty"
    object_object: str = "off"
    found: str = "penalty"
    found_hard: str = "constraint"
    rounds: int = 3
    restarts: int = 1
    restart_arm_nodes: int = 0
    audit_margin_m: float = 0.005
    audit_substeps: int = 3
    found_spacing_m: float = 0.04
    unfreed_m: float = 0.02
    margin_m: float = 0.01
    smoothing_m: float = 0.004
    length_m: float = 0.1
    softness: float = 0.01

    def check(self) -> list[tuple[str, str]]:
        errors = []
        # Pinocchio's link frames: the URDF read in 20 ms, where compiling the MuJoCo model
        # took a second of every stage's start-up.
        model = g1.g1_pinocchio_model()
        links = {f.name for f in model.frames if f.type == pin.FrameType.BODY}
        for name in ("self_pairs", "knee_pairs"):
            pairs = getattr(self, name)
            unknown = sorted({name for pair in pairs for name in pair} - links)
            if any(len(pair) != 2 for pair in pairs) or unknown:
                errors.append((name, f"needs pairs of G1 link names; unknown: {unknown}"))
        for kind in KINDS:
            value = getattr(self, kind)
            if value not in TREATMENTS:
                # YAML 1.1 reads an unquoted off as false.
                hint = ' (an unquoted off is YAML for false: write "off")' if value is False else ""
                errors.append((kind, f"must be one of {list(TREATMENTS)}, got {value!r}{hint}"))
        for kind in SPHERE_KINDS:
            if getattr(self, kind) == "homotopy":
                errors.append(
                    (kind, "spheres are their own smooth stand-in: use constraint, not homotopy")
                )
        if self.length_m <= 0.0:
            errors.append(("length_m", "must be > 0 m"))
        if not 0 <= self.rounds <= 20:
            errors.append(("rounds", "must be in 0 .. 20"))
        if not 0 <= self.restarts <= 5:
            errors.append(("restarts", "must be in 0 .. 5"))
        if self.restart_arm_nodes < 0:
            errors.append(("restart_arm_nodes", "must be >= 0 (0: no arm widened)"))
        if not 0 <= self.audit_substeps <= 20:
            errors.append(("audit_substeps", "must be in 0 .. 20"))
        if not 0.0 <= self.audit_margin_m <= 0.1:
            errors.append(("audit_margin_m", "must be in [0, 0.1] m"))
        if not 0.005 <= self.found_spacing_m <= 1.0:
            errors.append(("found_spacing_m", "must be in [0.005, 1] m"))
        if self.unfreed_m < 0.0:
            errors.append(("unfreed_m", "must be >= 0 m"))
        if self.softness <= 0.0:
            errors.append(("softness", "must be > 0"))
        if self.smoothing_m <= 0.0 or self.margin_m < np.log(3.0) * self.smoothing_m:
            errors.append(("margin_m", "needs smoothing_m > 0 and margin_m >= ln(3) smoothing_m"))
        return errors

    @property
    def homotopy(self) -> bool:
        """Some kind is treated by (13): the nodes carry its alpha."""
        return any(getattr(self, kind) == "homotopy" for kind in KINDS)


# The fields of CollisionCfg that hold a treatment; those between two of the G1's spheres.
SPHERE_KINDS = ("self_collision", "knee_collision")

KINDS = (
    *SPHERE_KINDS,
    "object_body",
    "hands_object",
    "legs_object",
    "feet_object",
    "hands_environment",
    "feet_environment",
    "object_environment",
    "object_object",
    "found",
    "found_hard",
)

# The Hessian flavours: without the constraints' curvature; with it, each call's projected
# onto the positive semidefinite cone (:mod:`locoman.to.nlp.convexify`); with it as it is.
HESSIANS = ("gauss_newton", "projected", "exact")


@dataclasses.dataclass
class ScheduleCfg:
    """Node counts of the phases.

    Attributes:
        double_support_nodes: Both feet down between steps.
        swing_nodes: One foot in the air per step.
        step_length_m: Longest step the schedule plans for [m].
        step_yaw_rad: Largest turn per step [rad].
        step_min_m: Feet that must move less than this between keyframes do not step [m].
        reach_nodes: Hands move to the object.
        grasp_nodes: Hands on the object, the object still on its support.
        lift_nodes: The object carried off its support.
        lower_nodes: The object carried down towards its target.
        set_nodes: The object on its target, hands still on it.
        end_lift_m: An object the plan ends holding ends at least this far above where
            it rested at its grasp keyframe [m] (S1: the basket clear of the shelf).
    """

    double_support_nodes: int = 2
    swing_nodes: int = 6
    step_length_m: float = 0.25
    step_yaw_rad: float = 0.45
    step_min_m: float = 0.15
    reach_nodes: int = 6
    grasp_nodes: int = 3
    lift_nodes: int = 4
    lower_nodes: int = 4
    set_nodes: int = 3
    end_lift_m: float = 0.06

    def check(self) -> list[tuple[str, str]]:
        counts = dataclasses.asdict(self)
        errors = [(k, "must be >= 1") for k, v in counts.items() if k.endswith("_nodes") and v < 1]
        errors += [
            (k, f"must be <= {MAX_PHASE_NODES}, got {v}: {TOO_MANY_NODES}")
            for k, v in counts.items()
            if k.endswith("_nodes") and v > MAX_PHASE_NODES
        ]
        if min(self.step_length_m, self.step_yaw_rad) <= 0.0:
            errors.append(("step_length_m", "step length and turn must be > 0"))
        if not 0.0 <= self.end_lift_m <= 0.5:
            errors.append(("end_lift_m", "must be in [0, 0.5] m"))
        return errors


SOLE_CONES = ("paper", "exact")  # ``solve.contact.sole_cone``: (3c) or the corners' rows


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
        sole_support_scale: The part of each sole (3b) lets the CoP use, as a fraction of
            its half length and half width: 1 is the whole foot box (the paper); below 1
            leaves a controller room to correct on a soft floor (``docs/execution.md``).
        sole_cone: The yaw moment a sole may carry: ``paper`` (3c), |tau_z| <= mu max(X, Y)
            f_z, or ``exact``, the rows of its four corners' friction pyramids (Caron et al.
            2015, the execution's cone), which (3c) exceeds near the sole's edges.
        arm_torque_margin: While a hand holds an object, each arm joint's static torque
            stays within this fraction of its URDF effort limit (beyond paper A:
            :mod:`locoman.to.terms.actuation`); 0 leaves the arms unbounded, as the paper.
    """

    floor_friction: float = 0.8
    stiffness: float = 50.0
    prehensile: bool = False
    palm_half_extents_m: list[float] = field(default_factory=lambda: [0.04, 0.03])
    slack_max_m: float | None = 0.004
    sole_support_scale: float = 1.0
    sole_cone: str = "paper"
    arm_torque_margin: float = 0.0

    def check(self) -> list[tuple[str, str]]:
        errors = []
        if not 0.0 <= self.arm_torque_margin <= 1.0:
            errors.append(("arm_torque_margin", "must be in [0, 1]: 0 off, else a fraction"))
        if self.sole_cone not in SOLE_CONES:
            errors.append(("sole_cone", f"must be one of {', '.join(SOLE_CONES)}"))
        if not 0.0 < self.sole_support_scale <= 1.0:
            errors.append(("sole_support_scale", "must be in (0, 1]: a fraction of the sole"))
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
        compile_flags: The C compiler's flags (:mod:`locoman.to.nlp.compile`). ``-O1`` by
            default, with gcc: the set is compiled once per robot (about 50 s, the G1's
            kinematics most of it) and every solve runs faster for it; ``-O0`` builds
            with tcc where it is installed (a few seconds), for slower evaluations
            (``benchmarks/results/to_solvers.json``).
        print_level: IPOPT's print level: 0 (default) prints nothing of IPOPT's own; 5
            its table, a line per iteration.
        progress_every: Iterations between two progress lines of a solve (iteration,
            objective, constraint violation, phase or round; the ``logging`` logger
            ``locoman.to.nlp.progress``); 0: none.
        warm_start: Sec. IV-C.2: each subtask's nodes start at its keyframe; otherwise
            every node starts at the initial state.
        max_wall_time_s: IPOPT's max_wall_time [s]: a solve stopped by it is a failed solve
            (status ``Maximum_WallTime_Exceeded``); None: no limit. The grids' time limit.
        hessian: The Hessian of the Lagrangian IPOPT gets (:data:`HESSIANS`).
            ``gauss_newton`` (default): the costs' Hessian and the penalties'
            Gauss-Newton one, without the constraints' second derivatives; ``exact``: with
            them and the penalties' r nabla^2 r (but the robot's own sphere pairs');
            ``projected``: the exact one with each term call's Hessian projected onto the
            positive semidefinite cone (:mod:`locoman.to.nlp.convexify`), so that IPOPT needs
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
            :class:`~locoman.config.to.CollisionCfg`); every other kind is off and no
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
            :mod:`locoman.to.problem.schedule` knows).
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
