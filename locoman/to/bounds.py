"""The TO's variable bounds and its initial guess, Sec. IV-C.2's subtask-like warm start."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

from locoman.config.to import SolverCfg
from locoman.scene import g1
from locoman.scene.rotations import rpy_to_matrix
from locoman.to.inputs import TOInputs, guiding_keyframe
from locoman.to.layout import (
    ANGULAR,
    FORCE,
    JOINTS,
    LINEAR,
    MOMENT,
    ORIENTATION,
    POSITION,
    TILT,
    VERTICAL,
    NodeLayout,
    limb,
    part,
)
from locoman.to.modes import NodeMode
from locoman.to.schedule import Schedule

GRAVITY = 9.81  # [m/s^2]


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
    for q, v, tilt in pairs:
        lo[part(q, TILT)], hi[part(q, TILT)] = -tilt, tilt
        lo[part(v, LINEAR)], hi[part(v, LINEAR)] = -LINEAR_SPEED_MAX, LINEAR_SPEED_MAX
        lo[part(v, ANGULAR)], hi[part(v, ANGULAR)] = -ANGULAR_SPEED_MAX, ANGULAR_SPEED_MAX
    force = 2.0 * weight
    wrenches = [limb(var[name], i) for name in ("foot_wrench", "hand_wrench") for i in range(2)]
    wrenches += [layout.object_variables(j, "support_wrench") for j in range(layout.n_objects)]
    for wrench in wrenches:
        lo[part(wrench, FORCE)], hi[part(wrench, FORCE)] = -force, force
        moment = WRENCH_LEVER * force
        lo[part(wrench, MOMENT)], hi[part(wrench, MOMENT)] = -moment, moment


def _rest_wrench(mass: float) -> np.ndarray:
    """(6,) the support's wrench on an object of ``mass`` [kg] at rest."""
    return np.r_[0.0, 0.0, mass * GRAVITY, 0.0, 0.0, 0.0]


def bounds(
    layout: NodeLayout,
    inputs: TOInputs,
    schedule: Schedule,
    modes: list[NodeMode],
    cfg: SolverCfg,
    homotopy: bool = False,
    end_lift_m: float = 0.0,
    slack_max_m: float | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Variable bounds (width, N): joint position and velocity limits, the initial state,
    robot and objects at rest at the end, an object still carried at the end at least
    ``end_lift_m`` [m] above where it rested at its grasp keyframe, inactive contacts'
    wrenches and slacks at zero, the other slacks within ``slack_max_m`` [m] (None: free),
    the objects not yet simulated at rest where the scene has them; (13)'s alpha in [0, 1]
    with a ``homotopy`` kind, else 0."""
    var, ovar = layout.variables, layout.object_variables
    model = g1.g1_pinocchio_model()
    n = schedule.nodes
    lo, hi = np.full((layout.width, n), -np.inf), np.full((layout.width, n), np.inf)

    def fix(where, k, value=0.0) -> None:
        lo[where, k] = hi[where, k] = value

    q, v, dt = var["q"], var["v"], var["dt"]
    lo[part(q, JOINTS)], hi[part(q, JOINTS)] = (
        model.lowerPositionLimit[7:, None],
        model.upperPositionLimit[7:, None],
    )
    lo[part(v, JOINTS)], hi[part(v, JOINTS)] = (
        -model.velocityLimit[6:, None],
        model.velocityLimit[6:, None],
    )
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
            lo[part(ovar(j, "q"), VERTICAL), -1] = grasped[VERTICAL] + end_lift_m
    if slack_max_m is not None:
        slacks = [var["foot_slack"], var["hand_slack"]]
        slacks += [ovar(j, "support_slack") for j in range(layout.n_objects)]
        for s in slacks:
            lo[s], hi[s] = -slack_max_m, slack_max_m
    for k, mode in enumerate(modes):
        last = k == n - 1
        for i in range(2):
            if not mode.feet[i] or last:
                fix(limb(var["foot_wrench"], i), k)
            if mode.hands[i] is None or last:
                fix(limb(var["hand_wrench"], i), k)
            if not mode.feet[i] or k == 0:
                fix(limb(var["foot_slack"], i), k)
            if mode.hands[i] is None:
                fix(limb(var["hand_slack"], i), k)
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
    if kf.predicate != "push" or not kf.guides or kf.goal is None or k <= node:
        return np.zeros(3)
    last = max(m for m in range(schedule.nodes) if schedule.subtask_of(m) == subtask)
    way = kf.goal[:2] - kf.object_poses[kf.object][:2]
    return np.r_[(k - node) / (last - node) * way, 0.0]


def _carried_load(inputs: TOInputs, mode: NodeMode, j: int) -> float:
    """[kg] object j's mass and what rests on it, transitively."""
    return inputs.objects[j].mass + sum(_carried_load(inputs, mode, r) for r in mode.riders(j))


def initial_guess(
    layout: NodeLayout,
    inputs: TOInputs,
    schedule: Schedule,
    modes: list[NodeMode],
    cfg: SolverCfg,
    robot_mass: float,
    homotopy: bool = False,
) -> np.ndarray:
    """(width, N): Sec. IV-C.2's subtask-like warm start: each subtask's nodes at its
    keyframe (robot and objects; a keyframe that does not guide: the next that does), at
    rest, the weight shared by the feet in contact, each
    supported object's load by its support, and a carried object's weight by the hands,
    which squeeze it hard enough for their friction cones (3a) to hold it,
    :data:`SQUEEZE_MARGIN` times over. After a ``push`` keyframe the robot, the pushed object
    and what rides on it move towards the goal, evenly over the nodes (:func:`push_shift`)."""
    var, ovar = layout.variables, layout.object_variables
    n = schedule.nodes
    X = np.zeros((layout.width, n))
    X[var["dt"]] = 0.5 * sum(cfg.dt_bounds)
    X[var["alpha"]] = 1.0 if homotopy else 0.0
    for k in range(n):
        mode = modes[k]
        kf = guiding_keyframe(inputs, schedule.subtask_of(k))
        use_kf = cfg.warm_start and k > 0
        shift = push_shift(inputs, schedule, k) if use_kf else np.zeros(3)
        X[var["q"], k] = kf.q35 if use_kf else inputs.q_start
        X[part(var["q"], POSITION), k] += shift
        weight = robot_mass * GRAVITY
        pushed = [kf.object, *mode.riders(kf.object)] if kf.object is not None else []
        for j, obj in enumerate(inputs.objects):
            active = use_kf and mode.objects[j].active
            X[ovar(j, "q"), k] = kf.object_poses[j] if active else inputs.object_starts[j]
            if active and j in pushed:
                X[part(ovar(j, "q"), POSITION), k] += shift
            if mode.carried(j):
                weight += obj.mass * GRAVITY
                R_object = rpy_to_matrix(X[part(ovar(j, "q"), ORIENTATION), k])
                half = 0.5 * obj.mass * GRAVITY
                for i in range(2):
                    normal = R_object @ inputs.hand_frames[j, i][:, 2]
                    squeeze = SQUEEZE_MARGIN * half / obj.friction
                    force = part(limb(var["hand_wrench"], i), FORCE)
                    X[force, k] = np.r_[0.0, 0.0, -half] + squeeze * normal
            elif mode.supported(j):
                load = _carried_load(inputs, mode, j)
                X[part(ovar(j, "support_wrench"), VERTICAL), k] = load * GRAVITY
        down = [i for i in range(2) if mode.feet[i]]
        for i in down:
            X[part(limb(var["foot_wrench"], i), VERTICAL), k] = weight / len(down)
            if mode.feet_on[i] is not None:  # the object stood on carries it to its support
                support = ovar(mode.feet_on[i], "support_wrench")
                X[part(support, VERTICAL), k] += weight / len(down)
    return X
