"""The TO's variable bounds: the joints' limits from the model, and sanity boxes on the
base, the objects and the wrenches that keep IPOPT's iterates physical (the initial guess
is :mod:`locoman.to.solve.initial_guess`)."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

from locoman.config.to import SolverCfg
from locoman.scene import g1
from locoman.to.problem.inputs import TOInputs
from locoman.to.problem.layout import (
    ANGULAR,
    FORCE,
    JOINTS,
    LINEAR,
    MOMENT,
    TILT,
    VERTICAL,
    NodeLayout,
    limb,
    part,
)
from locoman.to.problem.modes import NodeMode
from locoman.to.problem.schedule import Schedule
from locoman.to.terms.dynamics import STANDARD_GRAVITY

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
    return np.r_[0.0, 0.0, mass * STANDARD_GRAVITY, 0.0, 0.0, 0.0]


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
    _sanity_bounds(layout, lo, hi, (pin.computeTotalMass(model) + sum(masses)) * STANDARD_GRAVITY)
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
