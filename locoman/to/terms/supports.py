"""What an object rests on while it is not carried: one class per support contact kind.

Paper A models every object as a rigid body with contacts (Sec. IV-A); an object that no
hand carries rests on something, and the kind of that contact decides its constraints:

- :class:`Surface`: a patch contact (2a)-(2c) of its bottom on a fixed horizontal surface
  (the floor, a table, a shelf), with the friction cone and CoP (3);
- :class:`OnObject`: the interactive patch contact (4), (5a), (5b) of its bottom on the top
  of another object (the box on the trolley's platform), Newton's third law (6) handing the
  opposite wrench to that object, with (3);
- :class:`Chassis`: the nonholonomic chassis contact of Sec. IV-A.3 of a wheeled object
  (the trolley): (2a), (2c) at the virtual chassis frame, (7a) no lateral velocity of the
  rear wheels, (7b) no longitudinal ground force.

Every kind writes its contact at the object's frame origin (its bottom centre, or for a
trolley the chassis frame on the ground) and takes the wrench of the support on the object
there, in world axes. A kind is structure (it decides which rows exist); the heights and
sizes it uses are numbers (parameters). A new kind is a new class here.

Term kinds of the supports of :mod:`locoman.to.terms.supports`, made from the classes
themselves: a new support kind is a new class there, and its terms follow.

- :func:`support_contact_kind`: its rows (= 0) at node k + 1, at touchdown or held
  (the object's frame at node k, and the supporting object's at both nodes, are inputs
  where the kind uses them);
- :func:`support_wrench_kind`: its rows on the support's wrench at a node, equalities
  (a chassis's (7b)) then inequalities ((3)).

An object's numbers (half sizes, friction, a chassis's rear axle) are inputs ``p``.
"""

from __future__ import annotations

import abc
import dataclasses
import functools

import casadi as ca
import numpy as np

from locoman.to.problem.objects import ObjectModel
from locoman.to.terms.contacts import SELECT_XY, friction_cone_cop, no_rolling, patch_contact
from locoman.to.terms.kinematics import euler_rates_to_world, rpy_matrix
from locoman.to.terms.term import Rows, TermKind, term_kind


@dataclasses.dataclass(frozen=True)
class BodyFrame:
    """A rigid body's frame at a node, world axes.

    Attributes:
        p: (3,) origin [m].
        R: (3, 3) rotation.
        v: (3,) velocity of the origin [m/s].
        omega: (3,) angular velocity [rad/s].
    """

    p: ca.SX
    R: ca.SX
    v: ca.SX
    omega: ca.SX


@dataclasses.dataclass(frozen=True)
class SupportContact:
    """The symbols one support contact of object ``obj`` at node k + 1 is written with.

    Attributes:
        obj: The supported object (numbers or the symbols of the global parameters).
        now: Its frame at node k + 1.
        before: Its frame at node k if the same support held it there (the contact goes
            on), None at touchdown.
        base_now, base_before: The supporting object's frames (:class:`OnObject`), else None.
        height: [m] height of the supporting surface: world z for a fixed surface, z in the
            supporting object's frame for :class:`OnObject`.
        stiffness: k_z of (2a) [1/s].
        slack: s_z of (2a) [m].
    """

    obj: ObjectModel
    now: BodyFrame
    before: BodyFrame | None
    base_now: BodyFrame | None
    base_before: BodyFrame | None
    height: ca.SX
    stiffness: ca.SX
    slack: ca.SX


class Support(abc.ABC):
    """A support contact kind. ``base``: the object that receives the opposite wrench (6),
    None for the world."""

    base: int | None = None
    name: str = ""

    @abc.abstractmethod
    def equalities(self, c: SupportContact) -> ca.SX:
        """Rows (= 0) of the contact at node k + 1."""

    @abc.abstractmethod
    def inequalities(self, obj: ObjectModel, frame: BodyFrame, wrench: ca.SX) -> ca.SX:
        """Rows (>= 0) on the wrench at a node (``frame``: the object's there)."""

    def wrench_equalities(self, obj: ObjectModel, frame: BodyFrame, wrench: ca.SX) -> ca.SX:
        """Rows (= 0) on the wrench at a node; none but for a chassis."""
        return ca.SX(0, 1)

    def contact_inequalities(self, c: SupportContact) -> ca.SX:
        """Rows (>= 0) of the contact at node k + 1; none but where a turn is held."""
        return ca.SX(0, 1)


@dataclasses.dataclass(frozen=True)
class Surface(Support):
    """The object's bottom patch on a fixed horizontal surface: (2a)-(2c), (2d) at
    touchdown, and (3) with its bottom's half sizes; and no spin about the normal, as
    :class:`OnObject`'s (5b): over the step where the contact goes on, no yaw rate at
    touchdown.

    Paper A's (2b) keeps the patch's point from sliding, not the patch from turning about
    it: with (3c)'s yaw moment to turn it, S1's box spun by up to 0.34 rad per node on the
    floor while the robot stood on it (a foot 15 mm inside its turned edge) and S2's by
    0.21 rad on the table. A patch in static contact turns no more than it slides.
    """

    name = "surface"

    def equalities(self, c: SupportContact) -> ca.SX:
        before = c.before.p if c.before is not None else None
        rows = patch_contact(c.now.p, c.now.v, c.now.R, c.height, c.stiffness, c.slack, before)
        if c.before is not None:
            return ca.vertcat(rows, turn_about_normal(c.before.R, c.now.R))
        return ca.vertcat(rows, no_rolling(c.now.omega), c.now.omega[2])

    def contact_inequalities(self, c: SupportContact) -> ca.SX:
        return facing_same_way(c.before.R, c.now.R) if c.before is not None else ca.SX(0, 1)

    def inequalities(self, obj: ObjectModel, frame: BodyFrame, wrench: ca.SX) -> ca.SX:
        half = obj.half_extents
        return friction_cone_cop(wrench[0:3], wrench[3:6], frame.R, obj.friction, half[0], half[1])


def turn_about_normal(R_before: ca.SX, R_now: ca.SX) -> ca.SX:
    """sin of the turn about the shared normal between two frames whose z axes are aligned
    ((2c) or (5a)): (R_before^T R_now)[1, 0]; = 0 where the patch does not turn.

    Not R_now[0, 1] - R_before[0, 1] (the sines of the two yaws): that difference is flat
    where the yaw is near +-90 deg, and S2's box, set at -84 deg on the trolley, turned to
    -96 deg with it satisfied (-sin(84 deg) = -sin(96 deg)).
    """
    return (R_before.T @ R_now)[1, 0]


def facing_same_way(R_before: ca.SX, R_now: ca.SX) -> ca.SX:
    """cos of the same turn, (R_before^T R_now)[0, 0] (>= 0): with :func:`turn_about_normal`
    = 0 alone, a half turn is no turn (sin pi = 0), and ``tiny``'s stance foot flipped by
    180 deg between two nodes."""
    return (R_before.T @ R_now)[0, 0]


def _in_base(base: BodyFrame, frame: BodyFrame) -> tuple[ca.SX, ca.SX]:
    """The object's origin [m] and rotation in the base's frame."""
    return base.R.T @ (frame.p - base.p), base.R.T @ frame.R


@dataclasses.dataclass(frozen=True)
class OnObject(Support):
    """The object's bottom patch on the top face of object ``base``, which moves:

    (4)  the origin's height over the base's frame is the face's, and, where the contact
         goes on, its place in that frame unchanged over the step (at touchdown: no
         relative velocity along the face);
    (5a) the two normals aligned;
    (5b) no relative rotation about the normal, over the step (at touchdown: no relative
         rate);
    (6)  the base receives the opposite wrench at the same point (its wrench term, with the
         opposite sign, on the base's momentum rows: :mod:`locoman.to.transcription.transcribe`);
    (3)  with the object's bottom half sizes and friction.

    (4) and (5b) are written over the step, like (2b) of :func:`patch_contact`: the rate
    forms only hold at the nodes, and the box would creep on the platform between them.
    """

    base: int
    name = "on_object"

    def equalities(self, c: SupportContact) -> ca.SX:
        r, R = _in_base(c.base_now, c.now)
        rows = [r[2] - c.height + c.slack, SELECT_XY @ R[:, 2]]
        if c.before is not None:
            r0, R0 = _in_base(c.base_before, c.before)
            rows += [r[0:2] - r0[0:2], turn_about_normal(R0, R)]
        else:
            base = c.base_now
            relative_v = c.now.v - base.v - ca.cross(base.omega, c.now.p - base.p)
            rows += [(base.R.T @ relative_v)[0:2], base.R.T @ (c.now.omega - base.omega)]
        return ca.vertcat(*rows)

    def contact_inequalities(self, c: SupportContact) -> ca.SX:
        if c.before is None:
            return ca.SX(0, 1)
        return facing_same_way(_in_base(c.base_before, c.before)[1], _in_base(c.base_now, c.now)[1])

    def inequalities(self, obj: ObjectModel, frame: BodyFrame, wrench: ca.SX) -> ca.SX:
        half = obj.half_extents
        return friction_cone_cop(wrench[0:3], wrench[3:6], frame.R, obj.friction, half[0], half[1])


@dataclasses.dataclass(frozen=True)
class Chassis(Support):
    """A wheeled object's chassis contact on the floor (Sec. IV-A.3), at its frame C_ch on
    the ground below the platform centre:

    (2a) C_ch on the surface (stabilised, with slack), (2c) its normal along the surface's
         ((2d) follows from (2c) at every node);
    (7a) no lateral velocity of the rear wheels in C_ch: their axle's centre moves, over
         the step, only along C_ch's x (at touchdown: the rate form);
    (7b) no longitudinal ground force, f_x = 0 in C_ch;
    and, since the front wheels swivel, the only lateral force acts at the rear axle: the
    yaw moment about C_ch is tau_z = x_rear f_y. (3): the normal force pushes, the lateral
    force is within the wheels' friction, the CoP stays within the wheelbase.
    """

    name = "chassis"

    def equalities(self, c: SupportContact) -> ca.SX:
        now, obj = c.now, c.obj
        x_rear = obj.rear_axle_x
        rear = now.p + x_rear * now.R[:, 0]
        if c.before is not None:
            moved = rear - (c.before.p + x_rear * c.before.R[:, 0])
        else:
            moved = now.v + ca.cross(now.omega, x_rear * now.R[:, 0])
        return ca.vertcat(
            (now.p[2] - c.height) + now.v[2] / c.stiffness + c.slack,  # (2a)
            SELECT_XY @ now.R[:, 2],  # (2c)
            ca.dot(now.R[:, 1], moved),  # (7a)
        )

    def wrench_equalities(self, obj: ObjectModel, frame: BodyFrame, wrench: ca.SX) -> ca.SX:
        f, tau = frame.R.T @ wrench[0:3], frame.R.T @ wrench[3:6]
        return ca.vertcat(f[0], tau[2] - obj.rear_axle_x * f[1])  # (7b), the rear axle's yaw

    def inequalities(self, obj: ObjectModel, frame: BodyFrame, wrench: ca.SX) -> ca.SX:
        f, tau = frame.R.T @ wrench[0:3], frame.R.T @ wrench[3:6]
        x, y = obj.half_extents[0], obj.half_extents[1]
        mu = obj.friction
        return ca.vertcat(
            mu * f[2] - f[1],
            mu * f[2] + f[1],
            f[2] * x - tau[1],
            f[2] * x + tau[1],
            f[2] * y - tau[0],
            f[2] * y + tau[0],
        )


# Every support kind, for the compiled set of the TO's terms.
SUPPORT_KINDS: tuple[type[Support], ...] = (Surface, OnObject, Chassis)

OBJECT_NUMBERS = {"half": 2, "friction": 1, "rear_axle_x": 1}


def object_numbers(obj: ObjectModel) -> dict[str, object]:
    """The ``p`` slots of :data:`OBJECT_NUMBERS` for ``obj`` (no rear axle: 0)."""
    rear = 0.0 if obj.rear_axle_x is None else obj.rear_axle_x
    return {"half": obj.half_extents, "friction": obj.friction, "rear_axle_x": rear}


def body_frame(q: ca.SX, v: ca.SX) -> BodyFrame:
    """An object's frame from its q = (p, rpy) and v = dq/dt."""
    return BodyFrame(q[0:3], rpy_matrix(q[3:6]), v[0:3], euler_rates_to_world(q[3:6]) @ v[3:6])


def _symbolic_object(p) -> ObjectModel:
    return ObjectModel(
        "symbolic",
        mass=0.0,
        inertia=np.eye(3),
        com=np.zeros(3),
        half_extents=p["half"],
        friction=p["friction"],
        rear_axle_x=p["rear_axle_x"],
    )


def moving_base(support: Support) -> bool:
    """The support is another object (its frames are inputs)."""
    return isinstance(support, OnObject)


@functools.cache
def support_contact_kind(kind: type[Support], onset: str) -> TermKind:
    """The rows of a support of class ``kind`` on object (q, v, slack) at node k + 1;
    ``onset`` ``held``: the object's (q_before, v_before) at node k too; on another object:
    that object's (base_q, base_v) at k + 1 and, held, at k."""
    support = kind(0) if kind is OnObject else kind()
    held = onset == "held"
    x_slots = {"q": 6, "v": 6, "slack": 1}
    if held:
        x_slots |= {"q_before": 6, "v_before": 6}
    if moving_base(support):
        x_slots |= {"base_q": 6, "base_v": 6}
        if held:
            x_slots |= {"base_q_before": 6, "base_v_before": 6}

    def body(x, p) -> Rows:
        def frame(q: str, v: str) -> BodyFrame:
            return body_frame(x[q], x[v])

        moving = moving_base(support)
        contact = SupportContact(
            obj=_symbolic_object(p),
            now=frame("q", "v"),
            before=frame("q_before", "v_before") if held else None,
            base_now=frame("base_q", "base_v") if moving else None,
            base_before=frame("base_q_before", "base_v_before") if moving and held else None,
            height=p["height"],
            stiffness=p["k_z"],
            slack=x["slack"],
        )
        return Rows(
            equalities=[support.equalities(contact)],
            inequalities=[support.contact_inequalities(contact)],
        )

    p_slots = {"height": 1, "k_z": 1, **OBJECT_NUMBERS}
    return term_kind(f"support_{support.name}_{onset}", x_slots, p_slots, body)


@functools.cache
def support_wrench_kind(kind: type[Support]) -> TermKind:
    """The rows of a support of class ``kind`` on its wrench at a node (the object's q)."""
    support = kind(0) if kind is OnObject else kind()

    def body(x, p) -> Rows:
        obj = _symbolic_object(p)
        frame = body_frame(x["q"], ca.SX.zeros(6))
        w = x["wrench"]
        return Rows(
            equalities=[support.wrench_equalities(obj, frame, w)],
            inequalities=[support.inequalities(obj, frame, w)],
        )

    return term_kind(
        f"support_wrench_{support.name}", {"wrench": 6, "q": 6}, dict(OBJECT_NUMBERS), body
    )
