"""The robot's kinematics, lifted: the quantities every other term reads, as functions of q, v.

The expensive part of the TO, the G1's forward kinematics and its derivatives, appears once
per node, in these terms only:

- :func:`kinematics_kind`: centroidal momentum, CoM, the soles' and palms' frames and the
  trunk's body points (:data:`locoman.to.layout.KINEMATICS`);
- :func:`link_spheres_kind`: the centres of one link's collision spheres (its capsules, as
  placo and MuJoCo see them), one kind per link;
- :func:`link_point_kind`: a point fixed to a link (the palms', the feet's and the trunk's
  collision spheres), one kind per link.

Each lifts its quantities (:attr:`locoman.to.assembly.Term.lifts`): as virtual variables of
the NLP (:class:`locoman.to.assembly.BlockNLP`), functions of q and v whose derivatives reach
them by the chain rule.
"""

from __future__ import annotations

import casadi as ca

from locoman.retarget.robot import ContactFrames
from locoman.scene import g1
from locoman.to.collision import link_spheres
from locoman.to.kinematics import SymbolicKinematics
from locoman.to.layout import BODY_POINTS, FEET, HANDS, KINEMATICS, N_KIN, NQ
from locoman.to.terms import Rows, TermKind, term_kind


def kinematics_function(kin: SymbolicKinematics, frames: ContactFrames) -> ca.Function:
    """K(q, v): the lifted kinematic quantities in :data:`KINEMATICS` order. A palm's
    contact frame is ``frames.palm_axes``: (5a) lays the palm's capsule flat on the face."""
    q, v = kin.q, kin.v
    parts = {"h": kin.centroidal_momentum(), "com": kin.com()}
    palms = [frames.palm[f"{side}_palm"] for side in ("left", "right")]
    palm_axes = [frames.palm_axes[f"{side}_palm"] for side in ("left", "right")]
    for foot, link in zip(FEET, g1.FOOT_LINKS, strict=True):
        R, p = kin.frame_pose(link)
        w, v_origin = kin.frame_velocity(link)
        offset = R @ ca.DM(frames.sole["left_sole"])
        parts |= {
            f"{foot}_r": p + offset,
            f"{foot}_r_dot": v_origin + ca.cross(w, offset),
            f"{foot}_R": ca.vec(R),
            f"{foot}_w": w,
        }
    for hand, link, palm, axes in zip(HANDS, g1.HAND_LINKS, palms, palm_axes, strict=True):
        R, p = kin.frame_pose(link)
        w, _ = kin.frame_velocity(link)
        parts |= {
            f"{hand}_r": p + R @ ca.DM(palm),
            f"{hand}_R": ca.vec(R @ ca.DM(axes)),
            f"{hand}_w": w,
        }
    points = []
    for link, offset, _ in BODY_POINTS:
        R, p = kin.frame_pose(link)
        points.append(p + R @ ca.DM(offset))
    parts["body_points"] = ca.vertcat(*points)
    return ca.Function("kinematics", [q, v], [ca.vertcat(*[parts[name] for name in KINEMATICS])])


def kinematics_kind(kin: SymbolicKinematics, frames: ContactFrames) -> TermKind:
    """kin - K(q, v) = 0 at a node."""
    K = kinematics_function(kin, frames)

    def body(x, p) -> Rows:
        return Rows(equalities=[x["kin"] - K(x["q"], x["v"])])

    return term_kind("kinematics", {"q": NQ, "v": NQ, "kin": N_KIN}, {}, body, lifts=True)


def link_spheres_kind(kin: SymbolicKinematics, link: str) -> TermKind:
    """c - c(q) = 0: the world centres [m] of ``link``'s collision spheres, lifted."""
    R, p = kin.frame_pose(link)
    spheres = link_spheres(link)
    centres = ca.Function(
        f"{link}_centres", [kin.q], [ca.vertcat(*[p + R @ ca.DM(s.centre) for s in spheres])]
    )

    def body(x, _) -> Rows:
        return Rows(equalities=[x["c"] - centres(x["q"])])

    return term_kind(f"spheres_{link}", {"q": NQ, "c": 3 * len(spheres)}, {}, body, lifts=True)


def link_point_kind(kin: SymbolicKinematics, link: str) -> TermKind:
    """c - (p(q) + R(q) o) = 0: a point at ``offset`` o [m] in ``link``'s frame, defined."""
    R, p = kin.frame_pose(link)
    pose = ca.Function(f"{link}_pose", [kin.q], [p, ca.vec(R)])

    def body(x, par) -> Rows:
        p_link, R_link = pose(x["q"])
        return Rows(equalities=[x["c"] - (p_link + ca.reshape(R_link, 3, 3) @ par["offset"])])

    return term_kind(f"point_{link}", {"q": NQ, "c": 3}, {"offset": 3}, body, lifts=True)


def _between(q: ca.SX, q_next: ca.SX, fraction: ca.SX) -> ca.SX:
    """The configuration a fraction t along a step, linear in q (as the evaluation's
    replay between two nodes has it)."""
    return q + fraction * (q_next - q)


def link_spheres_between_kind(kin: SymbolicKinematics, link: str) -> TermKind:
    """:func:`link_spheres_kind` at the configuration a fraction along a step (inputs q at
    both nodes, ``p`` slot ``fraction``): where a collision pair between two nodes puts the
    link's spheres."""
    R, p = kin.frame_pose(link)
    spheres = link_spheres(link)
    centres = ca.Function(
        f"{link}_centres", [kin.q], [ca.vertcat(*[p + R @ ca.DM(s.centre) for s in spheres])]
    )

    def body(x, par) -> Rows:
        q = _between(x["q"], x["q_next"], par["fraction"])
        return Rows(equalities=[x["c"] - centres(q)])

    slots = {"q": NQ, "q_next": NQ, "c": 3 * len(spheres)}
    return term_kind(f"spheres_between_{link}", slots, {"fraction": 1}, body, lifts=True)


def link_point_between_kind(kin: SymbolicKinematics, link: str) -> TermKind:
    """:func:`link_point_kind` at the configuration a fraction along a step."""
    R, p = kin.frame_pose(link)
    pose = ca.Function(f"{link}_pose", [kin.q], [p, ca.vec(R)])

    def body(x, par) -> Rows:
        p_link, R_link = pose(_between(x["q"], x["q_next"], par["fraction"]))
        return Rows(equalities=[x["c"] - (p_link + ca.reshape(R_link, 3, 3) @ par["offset"])])

    slots = {"q": NQ, "q_next": NQ, "c": 3}
    p_slots = {"offset": 3, "fraction": 1}
    return term_kind(f"point_between_{link}", slots, p_slots, body, lifts=True)
