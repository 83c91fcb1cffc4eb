"""Sec. IV-C.2's initial guess: the robot's configurations interpolated between the
keyframes, the objects along their schedule, the contact wrenches carrying each body's
weight. (IPOPT's primal-dual start from an earlier solve is :mod:`locoman.to.nlp.multipliers`.)"""

from __future__ import annotations

import numpy as np

from locoman.config.to import SolverCfg
from locoman.scene.rotations import rpy_to_matrix
from locoman.to.problem.inputs import TOInputs, guiding_keyframe
from locoman.to.problem.layout import (
    FORCE,
    ORIENTATION,
    POSITION,
    VERTICAL,
    NodeLayout,
    limb,
    part,
)
from locoman.to.problem.modes import NodeMode
from locoman.to.problem.schedule import Schedule
from locoman.to.terms.dynamics import STANDARD_GRAVITY

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
        weight = robot_mass * STANDARD_GRAVITY
        pushed = [kf.object, *mode.riders(kf.object)] if kf.object is not None else []
        for j, obj in enumerate(inputs.objects):
            active = use_kf and mode.objects[j].active
            X[ovar(j, "q"), k] = kf.object_poses[j] if active else inputs.object_starts[j]
            if active and j in pushed:
                X[part(ovar(j, "q"), POSITION), k] += shift
            if mode.carried(j):
                weight += obj.mass * STANDARD_GRAVITY
                R_object = rpy_to_matrix(X[part(ovar(j, "q"), ORIENTATION), k])
                half = 0.5 * obj.mass * STANDARD_GRAVITY
                for i in range(2):
                    normal = R_object @ inputs.hand_frames[j, i][:, 2]
                    squeeze = SQUEEZE_MARGIN * half / obj.friction
                    force = part(limb(var["hand_wrench"], i), FORCE)
                    X[force, k] = np.r_[0.0, 0.0, -half] + squeeze * normal
            elif mode.supported(j):
                load = _carried_load(inputs, mode, j)
                X[part(ovar(j, "support_wrench"), VERTICAL), k] = load * STANDARD_GRAVITY
        down = [i for i in range(2) if mode.feet[i]]
        for i in down:
            X[part(limb(var["foot_wrench"], i), VERTICAL), k] = weight / len(down)
            if mode.feet_on[i] is not None:  # the object stood on carries it to its support
                support = ovar(mode.feet_on[i], "support_wrench")
                X[part(support, VERTICAL), k] += weight / len(down)
    return X
