"""Every term kind of the TO for one robot: what is compiled, once, whatever the scenario.

The robot's kinematics and its links' sphere chains depend on the robot model; every other
kind is geometry and physics with its numbers as inputs. Building the library compiles (or
loads from the cache) all of them, so that a new scenario, schedule, collision pair or
treatment afterwards compiles nothing.
"""

from __future__ import annotations

import dataclasses
import functools

from locoman.config.to import TREATMENTS
from locoman.retarget.robot import ContactFrames, contact_frames
from locoman.scene import g1
from locoman.to.collisions.spheres import link_spheres
from locoman.to.problem.layout import (
    BODY_POINTS,
)
from locoman.to.terms.actuation import arm_torque_kind
from locoman.to.terms.collisions import GEOMETRIES, collision_kind, homotopy_weight_kind
from locoman.to.terms.contacts import (
    ONSETS,
    foot_cone_kind,
    foot_patch_kind,
    hand_contact_kind,
    object_face_cone_kind,
    sole_depth_kind,
)
from locoman.to.terms.costs import (
    keyframe_base_kind,
    keyframe_foot_kind,
    object_pose_kind,
    regularization_kind,
    squared_kind,
    stance_kind,
    walking_kind,
)
from locoman.to.terms.dynamics import (
    object_step_kind,
    robot_step_kind,
    same_object_wrench_kind,
    wrench_kind,
)
from locoman.to.terms.kinematics import (
    SymbolicKinematics,
    kinematics_kind,
    link_point_between_kind,
    link_point_kind,
    link_spheres_between_kind,
    link_spheres_kind,
)
from locoman.to.terms.supports import SUPPORT_KINDS, support_contact_kind, support_wrench_kind
from locoman.to.terms.term import TermKind


@dataclasses.dataclass(frozen=True)
class RobotTerms:
    """The robot-specific term kinds: its kinematics, its links' capsule spheres and points
    fixed to its links."""

    kinematics: TermKind
    link_spheres: dict[str, TermKind]
    link_points: dict[str, TermKind]
    link_spheres_between: dict[str, TermKind]
    link_points_between: dict[str, TermKind]
    mass: float  # [kg]
    frames: ContactFrames


def collision_links() -> tuple[str, ...]:
    """The G1's links with collision capsules (their spheres can be lifted)."""
    model = g1.g1_mjmodel()
    names = []
    for b in range(model.nbody):
        try:
            link_spheres(model.body(b).name)
        except ValueError:
            continue
        names.append(model.body(b).name)
    return tuple(names)


@functools.cache
def g1_terms() -> RobotTerms:
    """The G1's own kinds: kinematics (with its contact frames) and every link's spheres."""
    model = g1.g1_pinocchio_model()
    kin = SymbolicKinematics(model)
    frames = contact_frames()
    links = collision_links()
    pointed = (*g1.HAND_LINKS, *g1.FOOT_LINKS, *(link for link, _, _ in BODY_POINTS))
    return RobotTerms(
        kinematics_kind(kin, frames),
        {link: link_spheres_kind(kin, link) for link in links},
        {link: link_point_kind(kin, link) for link in pointed},
        {link: link_spheres_between_kind(kin, link) for link in links},
        {link: link_point_between_kind(kin, link) for link in pointed},
        kin.mass,
        frames,
    )


def generic_kinds() -> list[TermKind]:
    """Every kind that does not depend on the robot model."""
    kinds = [robot_step_kind(), object_step_kind(), same_object_wrench_kind()]
    kinds += [wrench_kind(at, about) for at, about in (("point", "point"), ("object", "point"))]
    kinds += [wrench_kind("point", "object")]
    kinds += [foot_patch_kind(o) for o in ONSETS] + [hand_contact_kind(o) for o in ONSETS]
    kinds += [sole_depth_kind(), foot_cone_kind(False), foot_cone_kind(True)]
    kinds.append(object_face_cone_kind())
    for support in SUPPORT_KINDS:
        kinds += [support_contact_kind(support, o) for o in ONSETS]
        kinds.append(support_wrench_kind(support))
    kinds += [stance_kind(False), stance_kind(True), walking_kind(), regularization_kind()]
    kinds += [squared_kind(1), squared_kind(6), keyframe_base_kind(), keyframe_foot_kind()]
    kinds += [object_pose_kind(), homotopy_weight_kind()]
    for geometry in GEOMETRIES:
        for treatment in TREATMENTS[1:]:
            if geometry == "sphere_sphere" and treatment == "homotopy":
                continue
            kinds += [collision_kind(geometry, treatment, between) for between in (False, True)]
    return kinds


def all_kinds(robot: RobotTerms) -> list[TermKind]:
    """The robot's kinds and the generic ones: the compiled set."""
    robot_kinds = [
        robot.kinematics,
        *robot.link_spheres.values(),
        *robot.link_points.values(),
        *robot.link_spheres_between.values(),
        *robot.link_points_between.values(),
        arm_torque_kind(0),
        arm_torque_kind(1),
    ]
    return [*robot_kinds, *generic_kinds()]
