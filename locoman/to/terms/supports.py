"""Term kinds of the supports of :mod:`locoman.to.supports`, made from the classes
themselves: a new support kind is a new class there, and its terms follow.

- :func:`support_contact_kind`: its rows (= 0) at node k + 1, at touchdown or held
  (the object's frame at node k, and the supporting object's at both nodes, are inputs
  where the kind uses them);
- :func:`support_wrench_kind`: its rows on the support's wrench at a node, equalities
  (a chassis's (7b)) then inequalities ((3)).

An object's numbers (half sizes, friction, a chassis's rear axle) are inputs ``p``.
"""

from __future__ import annotations

import functools

import casadi as ca
import numpy as np

from locoman.to.kinematics import euler_rates_to_world, rpy_matrix
from locoman.to.layout import ObjectModel
from locoman.to.supports import BodyFrame, OnObject, Support, SupportContact
from locoman.to.terms import Rows, TermKind, term_kind

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
