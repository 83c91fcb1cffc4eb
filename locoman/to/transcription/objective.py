"""The cost calls of the transcription: Table I's stance, walking and regularisation
costs per node, the keyframe costs (9), (10) and the objects' goal and upright costs."""

from __future__ import annotations

import numpy as np

from locoman.to.terms.costs import (
    REGULARIZATION_WEIGHTS,
    STANCE_WEIGHTS,
    WALKING_WEIGHTS,
    keyframe_base_kind,
    keyframe_foot_kind,
    object_pose_kind,
    regularization_kind,
    squared_kind,
    stance_kind,
    walking_kind,
    weight_values,
)
from locoman.to.transcription.physics import carried_objects
from locoman.to.transcription.section import Section


def cost_rows(section: Section) -> None:
    """(8) per node by its mode, L_reg, L_slack, (9), (10) and the objects' poses."""
    b, at, modes = section.builder, section.at, section.modes
    numbers, robot, P, par, opar = (
        section.numbers,
        section.robot,
        section.P,
        section.par,
        section.opar,
    )
    w = numbers.weights
    stance_w = weight_values(w, STANCE_WEIGHTS)
    walking_w = weight_values(w, WALKING_WEIGHTS)
    reg_w = weight_values(w, REGULARIZATION_WEIGHTS)
    for k, mode in enumerate(modes):
        q, yaw_ref = at.var(k, "q"), P[par["yaw_ref"], k][0]
        surface = P[par["foot_surface_z"], k]
        if mode.stance:
            x = {
                "q": q,
                "com": at.kin(k, "com"),
                "r_l": at.foot(k, 0, "r"),
                "r_r": at.foot(k, 1, "r"),
                "R_l": at.foot(k, 0, "R"),
                "R_r": at.foot(k, 1, "R"),
            }
            p = stance_w | {"yaw_ref": yaw_ref}
            carried = carried_objects(mode, k)
            if carried:
                obj = numbers.objects[carried[0]]
                x |= {"q_o": at.obj(k, carried[0], "q")}
                p |= {"robot_mass": robot.mass, "object_mass": obj.mass, "object_com": obj.com}
            b.own(stance_kind(bool(carried))).add(x, p)
            x = {"r_l": at.foot(k, 0, "r"), "r_r": at.foot(k, 1, "r")}
            p = {
                "weight": w.keyframe_foot * P[par["kf_foot_on"], k][0],
                "target": P[par["kf_foot"], k],
            }
            b.own(keyframe_foot_kind()).add(x, p)
        else:
            swing = next(i for i in range(2) if not mode.feet[i])
            x = {"q": q, "r_swing": at.foot(k, swing, "r")}
            p = walking_w | {"yaw_ref": yaw_ref, "surface_z": surface[swing]}
            b.own(walking_kind()).add(x, p)
        # The base height is over the surface the feet stand on (the floor, or a box's top).
        down = [i for i in range(2) if mode.feet[i]]
        ground = sum(surface[i] for i in down) / len(down)
        x = {
            "q": q,
            "v": at.var(k, "v"),
            "foot_wrench": at.var(k, "foot_wrench"),
            "hand_wrench": at.var(k, "hand_wrench"),
            "dt": at.var(k, "dt"),
        }
        b.own(regularization_kind()).add(x, reg_w | {"ground": ground})
        slacks = [at.var(k, "foot_slack"), at.var(k, "hand_slack")]
        slacks += [at.obj(k, j, "support_slack") for j in range(len(numbers.objects))]
        for s in np.concatenate(slacks):
            b.own(squared_kind(1)).add({"x": s}, {"weight": w.slack})
        on = P[par["kf_base_on"], k][0]
        height, orientation = w.keyframe_base
        p = {
            "w_height": height * on,
            "w_orientation": orientation * on,
            "reference": P[par["kf_base"], k],
        }
        b.own(keyframe_base_kind()).add({"base": q[2:6]}, p)
        for j in range(len(numbers.objects)):
            if not mode.objects[j].active:
                continue
            b.own(squared_kind(6)).add({"x": at.obj(k, j, "support_wrench")}, {"weight": w.force})
            p = {
                "w_goal": w.object_goal * P[opar(j, "goal_on"), k][0],
                "goal": P[opar(j, "goal"), k],
                "w_upright": w.object_upright,
            }
            b.own(object_pose_kind()).add({"q": at.obj(k, j, "q")}, p)
