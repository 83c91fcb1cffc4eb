"""The robot's collision spheres as the TO sees them.

Every sphere the collision terms (11)-(13) use has its centre among the variables of each
node, so that a pair's term is a function of two centres (or a centre and an object's pose)
and nothing else: adding a pair compiles nothing and differentiates no kinematics. A
sphere's centre is one of a link's capsule spheres (:func:`link_spheres`,
defined by that link's term :func:`locoman.to.terms.kinematics.link_spheres_kind`, all of a
link's spheres together) or a point fixed to a link (a palm's capsule centre and ends, a
sole's heel and toe, the trunk's body points: :func:`locoman.to.terms.kinematics.link_point_kind`).

They are virtual variables of the NLP (:class:`locoman.to.nlp.ipopt.BlockNLP`): functions of
q whose derivatives reach q by the chain rule, not variables IPOPT sees.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Iterable

import mujoco
import numpy as np

from locoman.retarget.robot import ContactFrames
from locoman.scene import g1
from locoman.to.problem.layout import BODY_POINTS, FEET, HANDS


@dataclasses.dataclass(frozen=True)
class Sphere:
    """A collision sphere fixed to a link: centre in the link frame [m], radius [m]."""

    link: str
    centre: np.ndarray
    radius: float


# The G1's collision geoms the TO covers with spheres: its fitted capsules and spheres, and
# the shoulders' cylinders (a chain of spheres along the axis, which rounds their ends).
_SPHERED = tuple(
    int(t)
    for t in (
        mujoco.mjtGeom.mjGEOM_CAPSULE,
        mujoco.mjtGeom.mjGEOM_SPHERE,
        mujoco.mjtGeom.mjGEOM_CYLINDER,
    )
)


@functools.cache
def link_spheres(link: str) -> tuple[Sphere, ...]:
    """The spheres of a G1 link's collision geoms (but the feet's boxes, which the TO covers
    with its sole frames' heel and toe spheres)."""
    model = g1.g1_mjmodel()
    body = model.body(link).id
    spheres = []
    for geom in range(model.ngeom):
        if model.geom_bodyid[geom] != body or model.geom_group[geom] != g1.COLLISION_GROUP:
            continue
        if int(model.geom_type[geom]) not in _SPHERED:
            continue
        spheres += [Sphere(link, c, r) for c, r in _axis_spheres(model, geom)]
    if not spheres:
        raise ValueError(f"the G1 link {link!r} has no collision capsule, sphere or cylinder")
    return tuple(spheres)


def _axis_spheres(model: mujoco.MjModel, geom: int) -> list[tuple[np.ndarray, float]]:
    """A capsule or sphere as :func:`g1.capsule_spheres` has it; a cylinder as the capsule
    of its radius and axis."""
    if model.geom_type[geom] != mujoco.mjtGeom.mjGEOM_CYLINDER:
        return g1.capsule_spheres(model, geom)
    radius, half = model.geom_size[geom][:2]
    rot = np.zeros(9)
    mujoco.mju_quat2Mat(rot, model.geom_quat[geom])
    axis = rot.reshape(3, 3)[:, 2]
    count = int(np.ceil(2.0 * half / radius)) + 1
    pos = model.geom_pos[geom]
    return [(pos + t * half * axis, float(radius)) for t in np.linspace(-1.0, 1.0, count)]


FOREARM_LINKS = ("left_wrist_roll_link", "right_wrist_roll_link")

ELBOW_LINKS = ("left_elbow_link", "right_elbow_link")

# The hips, thighs and shins (``legs_object``), as their capsules' sphere chains. The hip
# roll links stand out sideways from the pelvis: without them, S2's carried box went 7 cm
# into one unseen.
LEG_LINKS = tuple(
    f"{side}_{link}"
    for side in ("left", "right")
    for link in ("hip_roll_link", "hip_yaw_link", "knee_link")
)

FOOT_SPHERE_M = 0.04  # radius of the heel and toe spheres [m]

FOOT_SPHERE_X = (-0.05, 0.05)  # heel and toe along the sole [m]: the G1's sole is 18 cm long


@dataclasses.dataclass(frozen=True)
class RobotSphere:
    """One collision sphere of the robot, fixed to a link.

    Attributes:
        name: ``<link>/<i>`` (a capsule's), or what the point is (``left_hand/front``).
        radius: [m].
        link: The link it is fixed to.
        index: Which of the link's capsule spheres; None for a point at ``offset``.
        offset: A point's place in the link frame [m].
    """

    name: str
    radius: float
    link: str
    index: int | None = None
    offset: tuple[float, float, float] = (0.0, 0.0, 0.0)


def link_sphere_list(link: str) -> list[RobotSphere]:
    """A link's capsule spheres."""
    return list(_link_spheres(link))


@functools.cache
def _link_spheres(link: str) -> tuple[RobotSphere, ...]:
    # Made once per link: the pair lists ask for them at every node.
    return tuple(
        RobotSphere(f"{link}/{i}", float(s.radius), link, index=i)
        for i, s in enumerate(link_spheres(link))
    )


def _point(name: str, radius: float, link: str, offset) -> RobotSphere:
    return RobotSphere(name, float(radius), link, offset=tuple(float(v) for v in offset))


def palm_spheres(frames: ContactFrames, i: int) -> list[RobotSphere]:
    """Hand i's capsule as its centre and both ends of its axis (the palm contact frame's
    x), which reach ``palm_half_length`` further."""
    hand, link = HANDS[i], g1.HAND_LINKS[i]
    side = hand.split("_")[0]
    centre = np.asarray(frames.palm[f"{side}_palm"], dtype=float)
    axis = np.asarray(frames.palm_axes[f"{side}_palm"], dtype=float)[:, 0]
    r, h = frames.palm_radius, frames.palm_half_length
    return [
        _point(f"{hand}/centre", r, link, centre),
        _point(f"{hand}/back", r, link, centre - h * axis),
        _point(f"{hand}/front", r, link, centre + h * axis),
    ]


def foot_spheres(frames: ContactFrames, i: int) -> list[RobotSphere]:
    """A heel and a toe sphere resting on foot i's sole."""
    sole = np.asarray(frames.sole["left_sole"], dtype=float)
    link = g1.FOOT_LINKS[i]
    return [
        _point(f"{FEET[i]}/{which}", FOOT_SPHERE_M, link, sole + np.array([x, 0.0, FOOT_SPHERE_M]))
        for which, x in zip(("heel", "toe"), FOOT_SPHERE_X, strict=True)
    ]


def body_point_spheres() -> list[RobotSphere]:
    """The trunk's body points (pelvis, torso) with their capsules' radii."""
    return [_point(f"{link}/point", radius, link, offset) for link, offset, radius in BODY_POINTS]


class SphereSet:
    """The spheres of one problem, in the order of a node's virtual sphere centres: a used
    link's capsule spheres all, then the used points, each once.

    Args:
        used: Every sphere some term uses (repeats allowed).
    """

    def __init__(self, used: Iterable[RobotSphere]) -> None:
        used = list(dict.fromkeys(used))
        self.links = tuple(dict.fromkeys(s.link for s in used if s.index is not None))
        spheres = [s for link in self.links for s in link_sphere_list(link)]
        self.points = tuple(s for s in used if s.index is None)
        self.spheres: tuple[RobotSphere, ...] = (*spheres, *self.points)
        self._slot = {s.name: n for n, s in enumerate(self.spheres)}

    def __len__(self) -> int:
        return len(self.spheres)

    def link_slots(self, link: str) -> np.ndarray:
        """(3 n,) a link's capsule spheres' entries among a node's sphere centres."""
        start = self._slot[f"{link}/0"]
        return 3 * start + np.arange(3 * len(link_spheres(link)))

    def slots(self, sphere: RobotSphere) -> np.ndarray:
        """(3,) a sphere's entries among a node's sphere centres."""
        return 3 * self._slot[sphere.name] + np.arange(3)
