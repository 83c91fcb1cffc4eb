"""The physics rows of the transcription: the lifted kinematics, the dynamics (1) of the
robot and each object, the contacts (2)-(5) and friction cones (3) of each node's mode, and
each contact's wrench on the bodies it joins (6)."""

from __future__ import annotations

import numpy as np

from locoman.errors import ConfigError
from locoman.to.collisions.pairs import prehensile
from locoman.to.problem.layout import (
    ORIENTATION,
    POSITION,
    limb,
)
from locoman.to.problem.modes import NodeMode
from locoman.to.terms.actuation import arm_columns, arm_limits, arm_torque_kind
from locoman.to.terms.contacts import (
    foot_cone_kind,
    foot_patch_kind,
    hand_contact_kind,
    object_face_cone_kind,
    sole_depth_kind,
)
from locoman.to.terms.dynamics import (
    object_step_kind,
    robot_step_kind,
    same_object_wrench_kind,
    wrench_kind,
)
from locoman.to.terms.library import RobotTerms
from locoman.to.terms.supports import object_numbers, support_contact_kind, support_wrench_kind
from locoman.to.transcription.builder import BlockBuilder
from locoman.to.transcription.index import NodeIndex
from locoman.to.transcription.section import Section


def kinematics_rows(b: BlockBuilder, at: NodeIndex, robot: RobotTerms, n: int) -> None:
    """The kinematics and the sphere centres at every node: virtual variables."""
    calls = b.calls(robot.kinematics)
    for k in range(n):
        calls.add({"q": at.var(k, "q"), "v": at.var(k, "v"), "kin": at.kinematics(k)})
    b.define(robot.kinematics)
    for link in at.spheres.links:
        calls = b.calls(robot.link_spheres[link])
        for k in range(n):
            calls.add({"q": at.var(k, "q"), "c": at.link_spheres(k, link)})
        b.define(robot.link_spheres[link])
    for point in at.spheres.points:
        calls = b.calls(robot.link_points[point.link])
        for k in range(n):
            calls.add({"q": at.var(k, "q"), "c": at.sphere(k, point)}, {"offset": point.offset})
    for kind in {id(k): k for k in robot.link_points.values()}.values():
        b.define(kind)


def dynamics_rows(section: Section) -> None:
    """(1) of the robot and of each object simulated at k + 1, with the wrenches of node
    k's contacts, over every step."""
    b, at, modes = section.builder, section.at, section.modes
    numbers, robot, P, par = section.numbers, section.robot, section.P, section.par
    objects = numbers.objects
    robot_step, object_step = robot_step_kind(), object_step_kind()
    steps = b.own(robot_step)
    object_steps = b.own(object_step)
    which: list[tuple[int, int]] = []
    for k in range(len(modes) - 1):
        steps.add(
            {
                "h": at.kin(k, "h"),
                "h1": at.kin(k + 1, "h"),
                "q": at.var(k, "q"),
                "q1": at.var(k + 1, "q"),
                "v1": at.var(k + 1, "v"),
                "dt": at.var(k, "dt"),
            },
            {"mass": robot.mass},
        )
        for j, obj in enumerate(objects):
            if not modes[k + 1].objects[j].active:
                continue
            object_steps.add(
                {
                    "q": at.obj(k, j, "q"),
                    "v": at.obj(k, j, "v"),
                    "q1": at.obj(k + 1, j, "q"),
                    "v1": at.obj(k + 1, j, "v"),
                    "dt": at.var(k, "dt"),
                },
                {"mass": obj.mass, "inertia": obj.inertia, "com": obj.com},
            )
            which.append((k, j))
    robot_rows = b.flush_owned(robot_step)[:, 0:6]
    object_rows = {
        kj: rows[0:6] for kj, rows in zip(which, b.flush_owned(object_step), strict=True)
    }
    on_lifted = wrench_kind("point", "point")
    at_object = wrench_kind("object", "point")
    on_object = wrench_kind("point", "object")
    same_object = same_object_wrench_kind()
    for k, mode in enumerate(modes[:-1]):
        dt = at.var(k, "dt")
        for i in range(2):
            foot = at.limb(k, "foot_wrench", i)
            if mode.feet[i]:
                r = at.foot(k, i, "r")
                x = {"wrench": foot, "r": r, "c": at.kin(k, "com"), "dt": dt}
                b.onto(on_lifted, x, {"sign": 1.0}, robot_rows[k])
                j = mode.feet_on[i]
                if j is not None and (k, j) in object_rows:
                    x = {"wrench": foot, "r": r, "c_q": at.obj(k, j, "q"), "dt": dt}
                    p = {"sign": -1.0, "c_local": objects[j].com}
                    b.onto(on_object, x, p, object_rows[(k, j)])
            j = mode.hands[i]
            if j is None:
                continue
            hand = at.limb(k, "hand_wrench", i)
            point = P[limb(par["hand_points"], i), k]
            x = {"wrench": hand, "r_q": at.obj(k, j, "q"), "c": at.kin(k, "com"), "dt": dt}
            b.onto(at_object, x, {"sign": 1.0, "r_local": point}, robot_rows[k])
            if (k, j) in object_rows:
                x = {"wrench": hand, "q": at.obj(k, j, "q"), "dt": dt}
                p = {"sign": -1.0, "r_local": point, "c_local": objects[j].com}
                b.onto(same_object, x, p, object_rows[(k, j)])
        for j, obj in enumerate(objects):
            if (k, j) not in object_rows:
                continue
            # An object not yet simulated rests on its support's fixed wrench: the step
            # into its first simulated node needs it.
            if mode.objects[j].support is not None:
                x = {"wrench": at.obj(k, j, "support_wrench"), "q": at.obj(k, j, "q"), "dt": dt}
                p = {"sign": 1.0, "r_local": np.zeros(3), "c_local": obj.com}
                b.onto(same_object, x, p, object_rows[(k, j)])
            for rider in mode.riders(j):
                x = {
                    "wrench": at.obj(k, rider, "support_wrench"),
                    "r": at.obj(k, rider, "q")[POSITION],
                    "c_q": at.obj(k, j, "q"),
                    "dt": dt,
                }
                b.onto(on_object, x, {"sign": -1.0, "c_local": obj.com}, object_rows[(k, j)])


def contact_rows(section: Section) -> None:
    """The contacts of node k + 1: feet, hands, supports."""
    b, at, modes = section.builder, section.at, section.modes
    numbers, robot, P, par, opar = (
        section.numbers,
        section.robot,
        section.P,
        section.par,
        section.opar,
    )
    k_z = numbers.contact.stiffness
    # A landing sole sinks no deeper than its slack may (sole_depth_kind: why touchdown).
    depth_max = numbers.contact.slack_max_m
    palm_radius = float(robot.frames.palm_radius)
    for k in range(len(modes) - 1):
        m, m1, k1 = modes[k], modes[k + 1], k + 1
        for i in range(2):
            if not m1.feet[i]:
                continue
            onset = "held" if m.feet[i] else "touchdown"
            x = {
                "r": at.foot(k1, i, "r"),
                "r_dot": at.foot(k1, i, "r_dot"),
                "R": at.foot(k1, i, "R"),
                "slack": at.var(k1, "foot_slack")[i],
            }
            x |= (
                {"w": at.foot(k1, i, "w")}
                if onset == "touchdown"
                else {"r_before": at.foot(k, i, "r")}
            )
            surface_z = P[par["foot_surface_z"], k1][i]
            b.own(foot_patch_kind(onset)).add(x, {"surface_z": surface_z, "k_z": k_z})
            if depth_max is not None and onset == "touchdown":
                p = {"surface_z": surface_z, "depth_max": depth_max}
                b.own(sole_depth_kind()).add({"r": x["r"]}, p)
        for i in range(2):
            j = m1.hands[i]
            if j is None:
                continue
            onset = "held" if m.hands[i] == j else "touchdown"
            x = {
                "r": at.hand(k1, i, "r"),
                "R": at.hand(k1, i, "R"),
                "w": at.hand(k1, i, "w"),
                "slack": at.limb(k1, "hand_slack", i),
                "q_o": at.obj(k1, j, "q"),
                "v_o": at.obj(k1, j, "v"),
            }
            p = {
                "point": P[limb(par["hand_points"], i), k1],
                "face": P[limb(par["hand_frames"], i), k1],
                "palm_radius": palm_radius,
            }
            b.own(hand_contact_kind(onset)).add(x, p)
        for j, obj in enumerate(numbers.objects):
            # Where an object starts to move its state at k and the wrenches on it are
            # fixed, so (1) alone fixes its state at k + 1: a support contact there too
            # would repeat it and make the constraint Jacobian rank-deficient.
            support = m1.objects[j].support
            if support is None or not (m.objects[j].active and m1.objects[j].active):
                continue
            held = m.objects[j].support == support
            x = {
                "q": at.obj(k1, j, "q"),
                "v": at.obj(k1, j, "v"),
                "slack": at.obj(k1, j, "support_slack"),
            }
            if held:
                x |= {"q_before": at.obj(k, j, "q"), "v_before": at.obj(k, j, "v")}
            base = getattr(support, "base", None)
            if base is not None:
                x |= {"base_q": at.obj(k1, base, "q"), "base_v": at.obj(k1, base, "v")}
                if held:
                    x |= {
                        "base_q_before": at.obj(k, base, "q"),
                        "base_v_before": at.obj(k, base, "v"),
                    }
            p = {"height": P[opar(j, "support_z"), k1][0], "k_z": k_z, **object_numbers(obj)}
            kind = support_contact_kind(type(support), "held" if held else "touchdown")
            b.own(kind).add(x, p)


def wrench_rows(section: Section) -> None:
    """Node k's rows on its wrenches: the friction cones and CoP (3), the supports' rows."""
    b, at, modes = section.builder, section.at, section.modes
    numbers, robot, P, par = section.numbers, section.robot, section.P, section.par
    contact = numbers.contact
    sole_half = contact.sole_support_scale * np.asarray(robot.frames.sole_half_extents, dtype=float)
    arm_bounds = [contact.arm_torque_margin * arm_limits(i) for i in range(2)]
    for k, mode in enumerate(modes[:-1]):
        for i in range(2):
            if mode.feet[i]:
                x = {"wrench": at.limb(k, "foot_wrench", i), "R": at.foot(k, i, "R")}
                p = {"mu": contact.floor_friction, "half": sole_half}
                b.own(foot_cone_kind(contact.sole_cone == "exact")).add(x, p)
            j = mode.hands[i]
            if j is not None and not prehensile(contact, numbers.objects[j]):
                x = {"wrench": at.limb(k, "hand_wrench", i), "rpy": at.obj(k, j, "q")[ORIENTATION]}
                p = {
                    "mu": numbers.objects[j].friction,
                    "half": contact.palm_half_extents_m,
                    "face": P[limb(par["hand_frames"], i), k],
                }
                b.own(object_face_cone_kind()).add(x, p)
            if j is not None and contact.arm_torque_margin > 0.0:
                x = {
                    "wrench": at.limb(k, "hand_wrench", i),
                    "R": at.hand(k, i, "R"),
                    "q_arm": at.var(k, "q")[arm_columns(i)],
                }
                p = {"limit": arm_bounds[i]}
                b.own(arm_torque_kind(i)).add(x, p)
        for j, obj in enumerate(numbers.objects):
            if mode.supported(j):
                support = mode.objects[j].support
                x = {"wrench": at.obj(k, j, "support_wrench"), "q": at.obj(k, j, "q")}
                b.own(support_wrench_kind(type(support))).add(x, object_numbers(obj))


def carried_objects(mode: NodeMode, k: int) -> list[int]:
    carried = [j for j in range(len(mode.objects)) if mode.carried(j)]
    if len(carried) > 1:
        raise ConfigError(
            f"node {k} carries objects {carried}: the stance cost's CoM c_all takes one "
            "carried object at most"
        )
    return carried
