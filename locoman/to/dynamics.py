"""Centroidal dynamics, discretised by semi-implicit Euler (paper A, eq. (1)).

    h+ = h- + [m g + sum_i f_i ; sum_i (r_i - c) x f_i + tau_i] dt          (1a)
    q+ = q- + v+ dt                                                           (1b)

h = (linear momentum [kg m/s], angular momentum about the CoM [kg m^2/s]) in world axes,
f_i, tau_i the force [N] and moment [N m] at contact point r_i [m], c the CoM [m]. Objects
obey the same equations as rigid bodies (:func:`rigid_body_momentum`). Every function takes
and returns CasADi expressions, so the same code builds the NLP and evaluates a solution.
"""

from __future__ import annotations

from collections.abc import Sequence

import casadi as ca

from locoman.to.kinematics import euler_rates_to_world, rpy_matrix

GRAVITY = (0.0, 0.0, -9.81)  # [m/s^2]


def wrench_sum(com: ca.SX, contacts: Sequence[tuple[ca.SX, ca.SX, ca.SX]], mass: float) -> ca.SX:
    """Rate of centroidal momentum (6,): gravity plus each contact's (r, f, tau)."""
    force = mass * ca.DM(GRAVITY)
    moment = ca.DM.zeros(3)
    for r, f, tau in contacts:
        force = force + f
        moment = moment + ca.cross(r - com, f) + tau
    return ca.vertcat(force, moment)


def momentum_step(
    h: ca.SX,
    com: ca.SX,
    contacts: Sequence[tuple[ca.SX, ca.SX, ca.SX]],
    mass: float,
    dt: ca.SX,
) -> ca.SX:
    """h+ of eq. (1a), with the contact wrenches of the current node."""
    return h + wrench_sum(com, contacts, mass) * dt


def configuration_step(q: ca.SX, v_next: ca.SX, dt: ca.SX) -> ca.SX:
    """q+ of eq. (1b): the configuration moves with the next velocity."""
    return q + v_next * dt


def rigid_body_momentum(
    q: ca.SX, v: ca.SX, mass: float, inertia: ca.DM, com_local: ca.DM
) -> tuple[ca.SX, ca.SX]:
    """Centroidal momentum (6,) and CoM (3,) [m] of a rigid body with configuration
    q = (p, rpy) and rate v = (p_dot, rpy_dot); ``inertia`` (3, 3) [kg m^2] about the CoM
    in body axes, ``com_local`` (3,) [m] the CoM in the body frame."""
    R = rpy_matrix(q[3:6])
    omega = euler_rates_to_world(q[3:6]) @ v[3:6]
    com = q[0:3] + R @ com_local
    v_com = v[0:3] + ca.cross(omega, R @ com_local)
    return ca.vertcat(mass * v_com, R @ inertia @ R.T @ omega), com
