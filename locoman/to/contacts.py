"""Contact constraints of paper A, Sec. IV-A, as CasADi expressions.

Each function returns the residuals of its equations (to be constrained to 0) or the
left-hand sides of its inequalities (to be constrained >= 0), so that one contact kind is
one call, and new kinds slot in beside them.
"""

from __future__ import annotations

import casadi as ca

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


def interactive_contact(
    r_i: ca.SX, r_j: ca.SX, slack: ca.SX, R_i: ca.SX, R_j: ca.SX, omega_i: ca.SX, omega_j: ca.SX
) -> ca.SX:
    """Equalities of a patch of body A on body B (e.g. a hand on the box):

    (4)  r_i - r_j + s_ij = 0,
    (5a) [I_2, 0] (R_j^T R_i)_z = 0  (the patches' normals aligned),
    (5b) omega_i - omega_j = 0       (no relative rotation).
    """
    return ca.vertcat(r_i - r_j + slack, SELECT_XY @ (R_j.T @ R_i)[:, 2], omega_i - omega_j)


def newton_third_law(f_i: ca.SX, tau_i: ca.SX, f_j: ca.SX, tau_j: ca.SX) -> ca.SX:
    """Equalities (6): f_i + f_j = 0, tau_i + tau_j = 0."""
    return ca.vertcat(f_i + f_j, tau_i + tau_j)
