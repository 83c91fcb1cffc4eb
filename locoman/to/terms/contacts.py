"""Contact constraints of paper A, Sec. IV-A, as CasADi expressions.

Each function returns the residuals of its equations (to be constrained to 0) or the
left-hand sides of its inequalities (to be constrained >= 0), so that one contact kind is
one call, and new kinds slot in beside them.

The robot's contacts (paper A, Sec. IV-A) as term kinds, written with
:mod:`locoman.to.terms.contacts`:

- a foot's patch contact (2a)-(2c) at node k + 1, at touchdown with (2d), or going on, (2b)
  then over the step (:func:`foot_patch_kind`), and how deep a landing sole may sink
  (:func:`sole_depth_kind`);
- a hand's interactive contact (4), (5a), (5b) with the object it touches, at the first touch
  or going on (:func:`hand_contact_kind`);
- the friction cone and CoP (3) of a foot on its surface (:func:`foot_cone_kind`) and of a
  wrench on a face fixed to an object (:func:`object_face_cone_kind`: a hand's, or an
  object's support).
"""

from __future__ import annotations

import functools

import casadi as ca

from locoman.to.terms.kinematics import euler_rates_to_world, rpy_matrix
from locoman.to.terms.term import Rows, TermKind, term_kind

SELECT_XY = ca.DM([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])  # [I_2, 0_{2x1}]


def patch_contact(
    r: ca.SX,
    r_dot: ca.SX,
    R: ca.SX,
    surface_z: float,
    stiffness: float,
    slack: ca.SX,
    r_prev: ca.SX | None = None,
) -> ca.SX:
    """Equalities of a patch on a horizontal surface at height ``surface_z`` [m]:

    (2a) (r_z - z_g) + r_dot_z / k_z + s_z = 0  (distance, stabilised, with slack),
    (2b) r_dot_xy = 0                          (no sliding),
    (2c) [I_2, 0] R_z = 0                      (the patch's normal along the surface's).

    Where the patch was already down at the previous node, pass its point there as
    ``r_prev``: (2b) is then imposed over the step, r_xy - r_prev_xy = 0. The velocity form
    only holds at the nodes, and with the (1b) step of a turning base the sole slid by up
    to 3.6 cm between nodes on ``tiny``.

    Args:
        r, r_dot: Contact point [m] and its velocity [m/s], world.
        R: (3, 3) contact frame in the world; its z axis is the patch normal.
        stiffness: k_z [1/s].
        slack: s_z [m].
        r_prev: Contact point at the previous node [m], if it was in contact there.
    """
    sliding = r_dot[0:2] if r_prev is None else r[0:2] - r_prev[0:2]
    return ca.vertcat(
        (r[2] - surface_z) + r_dot[2] / stiffness + slack, sliding, SELECT_XY @ R[:, 2]
    )


def sinking_bound(r: ca.SX, surface_z: float, depth_max: float) -> ca.SX:
    """Inequality (>= 0) of a patch on a surface at ``surface_z`` [m]: its point sinks no
    deeper than ``depth_max`` [m], (r_z - z_g) + d_max >= 0.

    (2a)'s stabilised form puts (r_z - z_g) at -s_z - r_dot_z / k_z: with s_z bounded, a
    sole still moving at touchdown sat 7 mm in the box it stepped on (S1's Fig. 6, both
    slacks at their 4 mm bound). The distance itself needs the bound."""
    return r[2] - surface_z + depth_max


def no_rolling(omega: ca.SX) -> ca.SX:
    """(2d) omega_xy = 0: a body on a surface does not start to rotate into it.

    Use it where (2c) is not imposed at the next node too: with (2c) at every node, (1b)
    already fixes these rates, and imposing both makes the constraint Jacobian
    rank-deficient (on the G1's feet, IPOPT's dual infeasibility stalled at 1e12).
    """
    return omega[0:2]


def friction_cone_cop(
    force: ca.SX, moment: ca.SX, R: ca.SX, mu: float, size_x: float, size_y: float
) -> ca.SX:
    """Inequalities (>= 0) of the linearised friction cone (3a), the CoP inside the patch
    (3b) and the yaw-moment bound (3c), in the contact frame R (columns: its axes).

    ``size_x``, ``size_y`` are the patch's half-sizes [m]: the paper's X, Y, read so that
    the centre of pressure stays on the patch."""
    f = R.T @ force
    tau = R.T @ moment
    return ca.vertcat(
        mu * f[2] - f[0],
        mu * f[2] + f[0],
        mu * f[2] - f[1],
        mu * f[2] + f[1],
        f[2] * size_x - tau[1],
        f[2] * size_x + tau[1],
        f[2] * size_y - tau[0],
        f[2] * size_y + tau[0],
        mu * f[2] * ca.fmax(size_x, size_y) - tau[2],
        mu * f[2] * ca.fmax(size_x, size_y) + tau[2],
    )


def sole_yaw_cone(force: ca.SX, moment: ca.SX, R: ca.SX, mu: float, size_x: float, size_y: float):
    """Inequalities (>= 0) of the yaw moment a rectangular sole's four corners carry, each
    inside its friction pyramid (Caron, Pham and Nakamura, ICRA 2015), in the contact frame
    R: for both signs s of tau_z and every sign pair (a, b),

        mu (X + Y) f_z - s tau_z - a (Y f_x + s mu tau_x) - b (X f_y + s mu tau_y) >= 0.

    They replace (3c) (``solve.contact.sole_cone = exact``): near an edge of the sole (3c)
    allows a yaw moment the corners cannot carry (``docs/execution.md``). The same rows as
    the execution's cone, :func:`locoman.execute.contacts.local_wrench_rows`."""
    f = R.T @ force
    tau = R.T @ moment
    return ca.vertcat(
        *[
            mu * (size_x + size_y) * f[2]
            - s * tau[2]
            - a * (size_y * f[0] + s * mu * tau[0])
            - b * (size_x * f[1] + s * mu * tau[1])
            for s in (1.0, -1.0)
            for a in (1.0, -1.0)
            for b in (1.0, -1.0)
        ]
    )


def interactive_contact(
    r_i: ca.SX, r_j: ca.SX, slack: ca.SX, R_i: ca.SX, R_j: ca.SX, omega_i: ca.SX, omega_j: ca.SX
) -> ca.SX:
    """Equalities of a patch of body A on body B (e.g. a hand on the box):

    (4)  r_i - r_j + s_ij = 0,
    (5a) [I_2, 0] (R_j^T R_i)_z = 0  (the patches' normals aligned),
    (5b) omega_i - omega_j = 0       (no relative rotation).
    """
    return ca.vertcat(r_i - r_j + slack, SELECT_XY @ (R_j.T @ R_i)[:, 2], omega_i - omega_j)


# A contact at node k + 1 starts there (``touchdown``) or held at node k already (``held``).
ONSETS = ("touchdown", "held")


@functools.cache
def foot_patch_kind(onset: str) -> TermKind:
    """(2a)-(2c) of a sole (centre r, velocity r_dot, rotation R, slack s) on a surface at
    ``surface_z`` [m]; at touchdown (2d) on its angular velocity w, held: (2b) over the step
    from the sole's centre at node k, ``r_before``.

    As paper A's (2b), the sole's centre does not slide but the sole may turn about it: the
    stance feet pivot by up to 12 deg per node on ``tiny``, S1 and S2 (reported by the
    evaluation as ``stance_foot_turn_max_rad``). Holding the turn too, as an object's
    support does (:func:`locoman.to.terms.supports.turn_about_normal`), slowed ``tiny``'s
    solve about tenfold: its schedule turns the robot by pivoting, and would need turning
    steps instead (docs/deviations.md)."""
    x_slots = {"r": 3, "r_dot": 3, "R": 9, "slack": 1}
    x_slots |= {"w": 3} if onset == "touchdown" else {"r_before": 3}

    def body(x, p) -> Rows:
        R = ca.reshape(x["R"], 3, 3)
        before = None if onset == "touchdown" else x["r_before"]
        rows = [patch_contact(x["r"], x["r_dot"], R, p["surface_z"], p["k_z"], x["slack"], before)]
        if onset == "touchdown":
            rows.append(no_rolling(x["w"]))
        return Rows(equalities=rows)

    return term_kind(f"foot_patch_{onset}", x_slots, {"surface_z": 1, "k_z": 1}, body)


@functools.cache
def sole_depth_kind() -> TermKind:
    """A sole's centre r no deeper than ``depth_max`` [m] below its surface at ``surface_z``
    [m] (:func:`locoman.to.terms.contacts.sinking_bound`), beside (2a) where it lands.

    Only at touchdown, where the sole still moves: held, r_dot_z is about 0 and (2a) bounds
    the depth by the slack already, and rows on every standing node cost S1 and S2 hundreds
    of iterations (``docs/trajectory-optimisation.md``)."""

    def body(x, p) -> Rows:
        return Rows(inequalities=[sinking_bound(x["r"], p["surface_z"], p["depth_max"])])

    return term_kind("sole_depth", {"r": 3}, {"surface_z": 1, "depth_max": 1}, body)


def object_face(q_object: ca.SX, point: ca.SX, face: ca.SX) -> tuple[ca.SX, ca.SX]:
    """A point [m] and a contact frame fixed to an object (its frame's ``point``, ``face``
    (3x3, column-major)), in the world."""
    R = rpy_matrix(q_object[3:6])
    return q_object[0:3] + R @ point, R @ ca.reshape(face, 3, 3)


@functools.cache
def hand_contact_kind(onset: str) -> TermKind:
    """(4), (5a), (5b) of a palm (centre, contact frame, angular velocity: lifted) on the
    face at ``point`` of an object (q, v); the palm's centre sits ``palm_radius`` [m] off
    the face. Held, (5b) keeps only the rate about the normal: with (5a) at both nodes the
    other two follow, and imposing them makes the constraint Jacobian singular."""

    def body(x, p) -> Rows:
        r_j, R_j = object_face(x["q_o"], p["point"], p["face"])
        r_j = r_j + p["palm_radius"] * R_j[:, 2]
        w_o = euler_rates_to_world(x["q_o"][3:6]) @ x["v_o"][3:6]
        R_palm = ca.reshape(x["R"], 3, 3)
        rows = interactive_contact(x["r"], r_j, x["slack"], R_palm, R_j, x["w"], w_o)
        if onset == "held":
            rows = ca.vertcat(rows[0:5], ca.dot(R_j[:, 2], x["w"] - w_o))
        return Rows(equalities=[rows])

    x_slots = {"r": 3, "R": 9, "w": 3, "slack": 3, "q_o": 6, "v_o": 6}
    p_slots = {"point": 3, "face": 9, "palm_radius": 1}
    return term_kind(f"hand_contact_{onset}", x_slots, p_slots, body)


@functools.cache
def foot_cone_kind(exact: bool = False) -> TermKind:
    """(3) of a foot's wrench (force, moment at the sole centre) in its sole frame R; with
    ``exact``, (3c)'s two rows replaced by the corners' yaw rows (:func:`sole_yaw_cone`)."""

    def body(x, p) -> Rows:
        w, R = x["wrench"], ca.reshape(x["R"], 3, 3)
        mu, half = p["mu"], p["half"]
        rows = friction_cone_cop(w[0:3], w[3:6], R, mu, half[0], half[1])
        if exact:
            rows = ca.vertcat(rows[:8], sole_yaw_cone(w[0:3], w[3:6], R, mu, half[0], half[1]))
        return Rows(inequalities=[rows])

    name = "foot_cone_exact" if exact else "foot_cone"
    return term_kind(name, {"wrench": 6, "R": 9}, {"mu": 1, "half": 2}, body)


@functools.cache
def object_face_cone_kind() -> TermKind:
    """(3) of a wrench on a face fixed to an object (frame ``face`` in the object's, whose
    rpy are variables): a hand's on the object it pushes, or a support's on the object's
    bottom (``face`` the identity)."""

    def body(x, p) -> Rows:
        w = x["wrench"]
        R = rpy_matrix(x["rpy"]) @ ca.reshape(p["face"], 3, 3)
        half = p["half"]
        return Rows(inequalities=[friction_cone_cop(w[0:3], w[3:6], R, p["mu"], half[0], half[1])])

    return term_kind(
        "object_face_cone", {"wrench": 6, "rpy": 3}, {"mu": 1, "half": 2, "face": 9}, body
    )
