"""The dynamics (1) of a rigid body as the TO transcribes it, for the toy problems of the
tests: the compiled kinds' own rows (:func:`locoman.to.terms.dynamics.object_step_kind` and a
:func:`locoman.to.terms.dynamics.wrench_kind` share per contact), called on SX or MX."""

from __future__ import annotations

from collections.abc import Sequence

import casadi as ca

from locoman.to.terms.dynamics import object_step_kind, wrench_kind
from locoman.to.terms.term import TermKind


def kind_rows(kind: TermKind, **slots) -> ca.SX:
    """The rows g of ``kind`` at its slots given by name (x's and p's)."""
    x = ca.vertcat(*[slots[name] for name in kind.x_slots])
    p = ca.vertcat(*[slots[name] for name in kind.p_slots])
    return kind.term.function(x, p)[0]


def object_dynamics(q, v, q1, v1, contacts: Sequence[tuple], *, mass, inertia, com, dt):
    """(1a), (1b) of a body from node k (q, v) to k + 1 (q1, v1): 12 rows, zero when the
    step holds. ``contacts``: (r, f, tau) acting on the body at node k, or (r, f, tau, sign)
    for a wrench whose reaction this body feels (sign -1: Newton's third law (6), one
    wrench on two bodies); ``inertia`` (3, 3) [kg m^2], ``com`` (3,) [m] in the body frame."""
    rows = kind_rows(
        object_step_kind(),
        q=q,
        v=v,
        q1=q1,
        v1=v1,
        dt=dt,
        mass=mass,
        inertia=ca.vec(ca.DM(inertia)),
        com=ca.DM(com),
    )
    share = wrench_kind("point", "object")
    for r, f, tau, *sign in contacts:
        wrench = ca.vertcat(f, tau)
        rows[0:6] += kind_rows(
            share,
            wrench=wrench,
            dt=dt,
            r=r,
            c_q=q,
            sign=sign[0] if sign else 1.0,
            c_local=ca.DM(com),
        )
    return rows
