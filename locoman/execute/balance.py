"""A centre-of-mass reference the soles can carry: the linear inverted pendulum (LIPM) over the
plan's footsteps.

The TO's centre of mass puts the centre of pressure (CoP) of its soles at 95-99 % of their
half extents (docs/execution.md): feasible on paper, with no room left for feedback. This
module keeps the plan's footsteps, timing, swing feet and hands, and replans the horizontal
centre of mass so that the CoP runs through the middle of the support (Kajita et al. 2003,
"Biped walking pattern generation by using preview control of zero-moment point"):

    z_ref(t)   the stance sole's centre in single support; in double support a straight line
               from the sole the weight leaves to the sole it goes to               (ZMP path)
    m g c - m h c_ddot = m g z_hat                                                  (LIPM)

with h the centre of mass's height above the stance soles [m]. The hands' planned wrenches
(f_h, tau_h) at the palms p_h (the held object's weight, a push) shift the CoP the robot's own
centre of mass must make: moment balance about the CoP z, neglecting the rate of the
centroidal angular momentum, gives (x; y by symmetry)

    m g c_x - m h c_ddot_x = z_x (m g - sum f_hz) + sum (p_hx f_hz - p_hz f_hx - tau_hy)

whose right side divided by m g is z_hat, the robot's own ZMP reference (``effective_zmp``).
c follows from a least-squares fit over the whole motion, jerk piecewise constant every
``period_s`` (Kajita's preview control without a finite preview):

    min  sum_k |z_k - z_hat_k|^2 + r |jerk_k|^2 + terminal rest,  c(0) = c_0 at rest
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pinocchio as pin

from locoman.config.execute import BalanceCfg, ExecuteCfg
from locoman.execute.model import PALMS, SOLES, execution_model
from locoman.execute.reference import (
    Reference,
    build_reference,
    contact_blend,
    translated,
    with_hand_clearance,
)

GRAVITY = 9.81  # [m/s^2]


def zmp_path(foot_contact: np.ndarray, soles: np.ndarray, start: np.ndarray) -> np.ndarray:
    """(T, 2) z_ref [m]: the stance sole's centre in single support, in double support a
    straight line from the sole the weight leaves to the sole it goes to; before the first
    single support it starts at ``start`` (2,) (the centre of mass standing), after the last
    it ends between the soles.

    Args:
        foot_contact: (T, 2) whether each foot (left, right) is on its support.
        soles: (T, 2, 2) each sole centre's planned horizontal position [m].
        start: (2,) where the path starts [m].
    """
    T = len(foot_contact)
    single = foot_contact.sum(axis=1) == 1
    anchor = np.full((T, 2), np.nan)
    anchor[single] = soles[single, np.argmax(foot_contact[single], axis=1)]
    path = anchor.copy()
    i = 0
    while i < T:
        if single[i]:
            i += 1
            continue
        j = i
        while j < T and not single[j]:
            j += 1
        begin = anchor[i - 1] if i > 0 else np.asarray(start, dtype=float)
        end = anchor[j] if j < T else soles[T - 1].mean(axis=0)
        # The weight moves over the whole double support, ending on the next stance sole
        # as it lifts the other (or between the soles at the end).
        s = (np.arange(i, j) - i + 1) / (j - i + (0 if j == T else 1))
        path[i:j] = begin + s[:, None] * (end - begin)
        i = j
    return path


def effective_zmp(
    zmp: np.ndarray,
    hand_wrench: np.ndarray,
    hand_position: np.ndarray,
    ground: np.ndarray,
    mass: float,
) -> np.ndarray:
    """(T, 2) z_hat [m]: the ZMP the robot's own centre of mass must make for its soles' CoP
    to be ``zmp`` (T, 2) while its hands take the wrenches ``hand_wrench`` (T, H, 6) [N, N m]
    (the objects' on the hands, world axes, at ``hand_position`` (T, H, 3) [m]); ``ground``
    (T,) the soles' height [m], ``mass`` the robot's [kg] (the module's docstring)."""
    f, tau = hand_wrench[..., :3], hand_wrench[..., 3:]
    p = hand_position.copy()
    p[..., 2] -= ground[:, None]
    weight = mass * GRAVITY
    load = weight - f[..., 2].sum(axis=1)
    x = zmp[:, 0] * load + (p[..., 0] * f[..., 2] - p[..., 2] * f[..., 0] - tau[..., 1]).sum(1)
    y = zmp[:, 1] * load + (p[..., 1] * f[..., 2] - p[..., 2] * f[..., 1] + tau[..., 0]).sum(1)
    return np.stack([x, y], axis=1) / weight


def _triple_integrator(step: float) -> tuple[np.ndarray, np.ndarray]:
    """(A (3, 3), B (3,)) of (c, c_dot, c_ddot) under a jerk held over ``step`` [s]."""
    a = np.array([[1.0, step, step**2 / 2], [0.0, 1.0, step], [0.0, 0.0, 1.0]])
    b = np.array([step**3 / 6, step**2 / 2, step])
    return a, b


def fit_com(
    target: np.ndarray,
    initial: np.ndarray,
    height: float,
    timestep_s: float,
    period_s: float,
    jerk_weight: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(c, c_dot, c_ddot), each (T, 2), of the LIPM whose ZMP c - h c_ddot / g best follows
    ``target`` (T, 2) [m] sampled every ``timestep_s`` [s]: from the state ``initial``
    (3, 2) (c [m], c_dot [m/s], c_ddot [m/s^2]), jerk constant over each ``period_s`` [s]
    (rounded to a multiple of the timestep), weighted ``jerk_weight`` [s^6] against the
    ZMP's error at the pieces' starts, and at rest at the end."""
    T = len(target)
    stride = max(1, round(period_s / timestep_s))
    K = -(-T // stride)  # jerk pieces; the fit looks at the samples 0, stride, ...
    a_k, b_k = _triple_integrator(stride * timestep_s)
    # x_k = A^k x_0 + sum_{l<k} A^(k-1-l) B u_l, k = 0..K.
    powers = np.zeros((K + 1, 3, 3))
    powers[0] = np.eye(3)
    gain = np.zeros((K + 1, 3, K))
    for k in range(1, K + 1):
        powers[k] = a_k @ powers[k - 1]
        gain[k] = a_k @ gain[k - 1]
        gain[k, :, k - 1] += b_k
    zmp_row = np.array([1.0, 0.0, -height / GRAVITY])
    zmp_gain = np.einsum("j,kjl->kl", zmp_row, gain[:K])
    end = gain[K, 1:]  # velocity and acceleration at the end
    rest_weight = 1e3
    lhs = zmp_gain.T @ zmp_gain + jerk_weight * np.eye(K) + rest_weight * end.T @ end
    free = powers @ np.asarray(initial, dtype=float)  # (K + 1, 3, 2): no jerk
    rhs = zmp_gain.T @ (target[::stride] - np.einsum("j,kja->ka", zmp_row, free[:K]))
    rhs -= rest_weight * end.T @ free[K, 1:]
    jerk = np.linalg.solve(lhs, rhs)  # (K, 2)
    coarse = free + np.einsum("kjl,la->kja", gain, jerk)  # (K + 1, 3, 2)
    # Between the pieces' starts, the exact polynomial of a constant jerk.
    piece = np.arange(T) // stride
    tau = ((np.arange(T) - piece * stride) * timestep_s)[:, None]
    x, u = coarse[piece], jerk[piece]
    c = x[:, 0] + tau * x[:, 1] + tau**2 / 2 * x[:, 2] + tau**3 / 6 * u
    c_dot = x[:, 1] + tau * x[:, 2] + tau**2 / 2 * u
    c_ddot = x[:, 2] + tau * u
    return c, c_dot, c_ddot


def support_height(foot_contact: np.ndarray, sole_height: np.ndarray) -> np.ndarray:
    """(T,) the height of the ground under the robot [m]: its lowest stance sole's (both
    soles' lowest where none stands), from ``foot_contact`` (T, 2) and ``sole_height``
    (T, 2) [m]."""
    ground = np.where(foot_contact, sole_height, np.inf).min(axis=1)
    return np.where(np.isfinite(ground), ground, sole_height.min(axis=1))


def body_shift(
    shift: np.ndarray, touching: np.ndarray, timestep_s: float, blend_s: float
) -> np.ndarray:
    """(T, 3) the part of the centre of mass's ``shift`` (T, 3) [m] a hand follows: all of it
    ``blend_s`` [s] or more from any sample ``touching`` (T,) its object, none while it
    touches (:func:`locoman.execute.reference.contact_blend`). A free hand moves with the
    body, so that replanning the centre of mass does not push it into the hips; a holding
    hand stays on its object."""
    return contact_blend(touching, timestep_s, blend_s)[:, None] * shift


def balanced_reference(
    ref: Reference, cfg: BalanceCfg, timestep_s: float, hand_blend_s: float
) -> Reference:
    """``ref`` with its horizontal centre of mass replanned by the LIPM (the module's
    docstring), h the mean height of the plan's above the ground, and no foot wrench of the
    TO's (the QP's least-norm wrenches, their CoP mid-sole, go with it); a free hand moves
    with the centre of mass (:func:`body_shift`, ``hand_blend_s`` [s]); everything else,
    the vertical centre of mass included, is the plan's."""
    soles = np.stack([ref.frames[name].position for name in SOLES], axis=1)
    palms = np.stack([ref.frames[name].position for name in PALMS], axis=1)
    ground = support_height(ref.foot_contact, soles[..., 2])
    mass = pin.computeTotalMass(execution_model())
    zmp = zmp_path(ref.foot_contact, soles[..., :2], ref.com[0, :2])
    target = effective_zmp(zmp, ref.hand_wrench, palms, ground, mass)
    height = float(np.mean(ref.com[:, 2] - ground))
    initial = np.vstack([ref.com[0, :2], np.zeros((2, 2))])  # standing still
    c, c_dot, c_ddot = fit_com(target, initial, height, timestep_s, cfg.period_s, cfg.jerk_weight)
    shift = np.column_stack([c - ref.com[:, :2], np.zeros(len(c))])
    frames = dict(ref.frames)
    for k, name in enumerate(PALMS):
        moved = body_shift(shift, ref.hand_object[:, k] >= 0, timestep_s, hand_blend_s)
        frames[name] = translated(ref.frames[name], moved, timestep_s)
    return dataclasses.replace(
        ref,
        frames=frames,
        com=np.column_stack([c, ref.com[:, 2]]),
        com_velocity=np.column_stack([c_dot, ref.com_velocity[:, 2]]),
        com_acceleration=np.column_stack([c_ddot, ref.com_acceleration[:, 2]]),
        foot_wrench=np.zeros_like(ref.foot_wrench),
    )


def execution_reference(traj: dict[str, np.ndarray], cfg: ExecuteCfg) -> Reference:
    """The reference the controller tracks: the TO's trajectory ``traj`` sampled
    (:func:`locoman.execute.reference.build_reference`), the hands approaching their
    objects from outside (:func:`locoman.execute.reference.with_hand_clearance`), its
    centre of mass the plan's (``cfg.balance.com_path = plan``) or the LIPM's (``lipm``)."""
    ref = build_reference(traj, cfg.timestep_s, cfg.settle_s, cfg.hold_s)
    ref = with_hand_clearance(ref, cfg.hand_clearance_m, cfg.timestep_s, cfg.hand_blend_s)
    if cfg.balance.com_path == "lipm":
        ref = balanced_reference(ref, cfg.balance, cfg.timestep_s, cfg.hand_blend_s)
    return ref
