"""The robot's collision spheres as the TO sees them.

Every sphere the collision terms (11)-(13) use has its centre among the variables of each
node, so that a pair's term is a function of two centres (or a centre and an object's pose)
and nothing else: adding a pair compiles nothing and differentiates no kinematics. A
sphere's centre is

- one of a link's capsule spheres (:func:`locoman.to.collision.link_spheres`), defined by
  that link's term (:func:`locoman.to.terms.kinematics.link_spheres_kind`): all of a link's
  spheres together;
- a point fixed to a lifted frame (a palm's capsule ends, a sole's heel and toe), defined by
  :func:`locoman.to.terms.kinematics.frame_point_kind`;
- or a lifted kinematic quantity itself (a palm's centre, the trunk's body points).

The first two are virtual variables of the NLP (:class:`locoman.to.assembly.BlockNLP`):
functions of q, whose derivatives reach q by the chain rule, not variables IPOPT sees.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable

import numpy as np

from locoman.retarget.robot import ContactFrames
from locoman.to.collision import link_spheres
from locoman.to.layout import BODY_POINTS, FEET, HANDS, KINEMATICS, NodeLayout

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
    """One collision sphere of the robot.

    Attributes:
        name: ``<link>/<i>``, ``<frame>/<which>`` or ``<body point link>/point``.
        radius: [m].
        link: The link whose capsule sphere ``index`` it is.
        index: Which of the link's spheres.
        frame: The lifted frame (a :data:`KINEMATICS` prefix: ``left_hand``, ``right_foot``)
            it is fixed to, at ``offset`` [m] in that frame.
        offset: See ``frame``.
        kin: A lifted kinematic quantity whose 3 entries from ``kin_start`` are the centre.
        kin_start: See ``kin``.
    """

    name: str
    radius: float
    link: str | None = None
    index: int = 0
    frame: str | None = None
    offset: tuple[float, float, float] = (0.0, 0.0, 0.0)
    kin: str | None = None
    kin_start: int = 0

    @property
    def lifted(self) -> bool:
        """Its centre is a variable of its own (not a kinematic quantity already lifted)."""
        return self.kin is None


def link_sphere_list(link: str) -> list[RobotSphere]:
    """A link's capsule spheres."""
    return [
        RobotSphere(f"{link}/{i}", float(s.radius), link=link, index=i)
        for i, s in enumerate(link_spheres(link))
    ]


def palm_spheres(frames: ContactFrames, i: int) -> list[RobotSphere]:
    """Hand i's capsule as its centre and both ends of its axis (the contact frame's x),
    which reach ``palm_half_length`` further."""
    hand, r, h = HANDS[i], float(frames.palm_radius), float(frames.palm_half_length)
    ends = [
        RobotSphere(f"{hand}/{which}", r, frame=f"{hand}", offset=(sign * h, 0.0, 0.0))
        for which, sign in (("back", -1.0), ("front", 1.0))
    ]
    return [RobotSphere(f"{hand}/centre", r, kin=f"{hand}_r"), *ends]


def foot_spheres(i: int) -> list[RobotSphere]:
    """A heel and a toe sphere resting on foot i's sole."""
    foot = FEET[i]
    return [
        RobotSphere(f"{foot}/{which}", FOOT_SPHERE_M, frame=foot, offset=(x, 0.0, FOOT_SPHERE_M))
        for which, x in zip(("heel", "toe"), FOOT_SPHERE_X, strict=True)
    ]


def body_point_spheres() -> list[RobotSphere]:
    """The trunk's body points (pelvis, torso) with their capsules' radii."""
    return [
        RobotSphere(f"{link}/point", radius, kin="body_points", kin_start=3 * k)
        for k, (link, _, radius) in enumerate(BODY_POINTS)
    ]


class SphereSet:
    """The virtual spheres of one problem, in the order of the NLP's virtual variables at a
    node: a used link's spheres all, then the used frame points, each once.

    Args:
        used: Every sphere some term uses (repeats allowed).
    """

    def __init__(self, used: Iterable[RobotSphere]) -> None:
        used = list(dict.fromkeys(used))
        self.links = tuple(dict.fromkeys(s.link for s in used if s.link is not None))
        lifted = [s for link in self.links for s in link_sphere_list(link)]
        lifted += [s for s in used if s.frame is not None]
        self.lifted: tuple[RobotSphere, ...] = tuple(lifted)
        self._slot = {s.name: n for n, s in enumerate(self.lifted)}

    def __len__(self) -> int:
        return len(self.lifted)

    def slots(self, link: str) -> np.ndarray:
        """(3 n,) a link's spheres' entries among a node's virtual variables."""
        start = self._slot[f"{link}/0"]
        return 3 * start + np.arange(3 * len(link_spheres(link)))

    def centre(self, layout: NodeLayout, nodes: int, k: int, sphere: RobotSphere) -> np.ndarray:
        """(3,) indices of the centre of ``sphere`` at node k of ``nodes``: in the NLP's x
        (a lifted kinematic quantity) or among its virtual variables, after x."""
        if sphere.kin is not None:
            start = layout.variables["kin"].start + KINEMATICS[sphere.kin].start + sphere.kin_start
            return k * layout.width + start + np.arange(3)
        return self.virtual(layout, nodes, k) + 3 * self._slot[sphere.name] + np.arange(3)

    def virtual(self, layout: NodeLayout, nodes: int, k: int) -> int:
        """The index of node k's first virtual variable."""
        return nodes * layout.width + k * 3 * len(self.lifted)
