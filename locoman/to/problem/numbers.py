"""The TO's numbers: the problem's own (:class:`Numbers`) and the per-node ones
(:func:`node_parameters`, the rows of
:attr:`locoman.to.problem.layout.NodeLayout.parameters`): the yaw reference, the keyframe
costs' switches and references (9), (10), the surface under each foot, the hands' contacts
on the object they touch, each object's support height and goal."""

from __future__ import annotations

import dataclasses

import numpy as np

from locoman.config.to import CollisionCfg, ContactCfg, CostWeights
from locoman.to.problem.inputs import TOInputs, base_yaw
from locoman.to.problem.layout import (
    NodeLayout,
    limb,
)
from locoman.to.problem.modes import node_modes, stood_on, supports_per_node
from locoman.to.problem.objects import ObjectModel, Obstacle
from locoman.to.problem.schedule import Schedule


def node_parameters(
    inputs: TOInputs, schedule: Schedule, *, keyframe_base: bool, keyframe_foot: bool
) -> np.ndarray:
    """(n_params, N): references and switches per node.

    The yaw reference goes linearly, over each subtask's nodes, from the previous keyframe's
    yaw to the subtask's. (9) is on at each keyframe node, (10) on the stance nodes around
    it (after the subtask's last step before it, before its next), where ``keyframe_base``
    and ``keyframe_foot`` switch them on; a keyframe that does not guide has neither. A
    subtask's goal holds its object at the subtask's last node. The hands' contacts are
    those on the object they touch, elsewhere on the first object a hand touches.
    """
    layout = NodeLayout.of(len(inputs.objects))
    par, opar = layout.parameters, layout.object_parameters
    n = schedule.nodes
    P = np.zeros((layout.n_params, n))
    kf_nodes = schedule.keyframe_nodes()
    yaw_before = base_yaw(inputs.q_start)
    for i, kf in enumerate(inputs.keyframes):
        nodes = [k for k in range(1, n) if schedule.subtask_of(k) == i]
        yaws = np.linspace(yaw_before, base_yaw(kf.q35), len(nodes) + 1)[1:]
        P[par["yaw_ref"], nodes] = yaws
        if i == 0:
            P[par["yaw_ref"], 0] = yaw_before
        yaw_before = base_yaw(kf.q35)
        node = kf_nodes[i]
        if keyframe_base and kf.guides:
            P[par["kf_base_on"], node] = 1.0
            P[par["kf_base"], node] = np.r_[kf.q35[2], kf.q35[3:6]]
        if keyframe_foot and kf.guides:
            # The stance around the keyframe: after the last step before it, up to the next
            # step (a push walks on after its keyframe).
            swings = [k for k in nodes if not schedule.phase(k).stance]
            after = max((k for k in swings if k < node), default=nodes[0] - 1)
            until = min((k for k in swings if k > node), default=nodes[-1] + 1)
            stance = [k for k in nodes if after < k < until]
            P[par["kf_foot_on"], stance] = 1.0
            P[par["kf_foot"], stance] = kf.foot_midpoint()[:, None]
        if kf.goal is not None:
            P[opar(kf.object, "goal"), nodes[-1]] = kf.goal
            P[opar(kf.object, "goal_on"), nodes[-1]] = 1.0
    for k, row in enumerate(supports_per_node(inputs, schedule)):
        for j, (_, height) in enumerate(row):
            P[opar(j, "support_z"), k] = height
    for k in range(n):
        phase, step = schedule.phase(k), stood_on(inputs, schedule.subtask_of(k))
        for i in range(2):
            # A raised foot stands on, or a swinging one lands on, the stepped-on top.
            if phase.feet_raised[i] and step is not None:
                P[limb(par["foot_surface_z"], i), k] = step.step_height
    modes = node_modes(inputs, schedule)
    first = next((j for m in modes for j in m.hands if j is not None), 0)
    # A free hand's numbers are its first object's (they enter no term while it is free);
    # a scene with no movable object (a step onto a fixed platform) leaves them zero.
    for k, mode in enumerate(modes if len(inputs.objects) else ()):
        for i, j in enumerate(mode.hands):
            j = first if j is None else j
            P[limb(par["hand_points"], i), k] = inputs.hand_points[j, i]
            P[limb(par["hand_frames"], i), k] = inputs.hand_frames[j, i].ravel(order="F")
    return P


@dataclasses.dataclass(frozen=True)
class Numbers:
    """The numbers of a problem that a sweep changes without changing which terms exist:
    cost weights, contact numbers, collision numbers, the objects' masses, sizes and
    frictions, the obstacles' boxes."""

    weights: CostWeights
    contact: ContactCfg
    collision: CollisionCfg
    objects: tuple[ObjectModel, ...]
    obstacles: tuple[Obstacle, ...]
