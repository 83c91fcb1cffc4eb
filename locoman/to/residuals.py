"""Checks of a solved trajectory that do not use the TO's own CasADi code: Pinocchio
recomputes the centroidal momentum and its rate from q, v and the contact wrenches."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pinocchio as pin

from locoman.to.kinematics import pin_configuration, pin_velocity

GRAVITY = np.array([0.0, 0.0, -9.81])  # [m/s^2]


def contact_points(
    model: pin.Model, q: np.ndarray, links: Sequence[str], offsets: Sequence[np.ndarray]
) -> np.ndarray:
    """World points (C, 3) [m] at ``offsets`` in the frames of ``links``, at TO configuration
    q (35,)."""
    data = model.createData()
    pin.framesForwardKinematics(model, data, pin_configuration(q))
    out = []
    for link, offset in zip(links, offsets, strict=True):
        pose = data.oMf[model.getFrameId(link)]
        out.append(pose.rotation @ offset + pose.translation)
    return np.array(out)


def dynamics_residual(
    model: pin.Model,
    q: np.ndarray,
    v: np.ndarray,
    forces: np.ndarray,
    moments: np.ndarray,
    dt: np.ndarray,
    links: Sequence[str],
    offsets: Sequence[np.ndarray],
) -> np.ndarray:
    """|h_{k+1} - h_k - dt_k [m g + sum f; sum (r - c) x f + tau]| per interval (N - 1,),
    in [kg m/s] and [kg m^2/s] alike, with h and c from Pinocchio (eq. (1a))."""
    data = model.createData()
    mass = pin.computeTotalMass(model)
    momenta, coms = [], []
    for qk, vk in zip(q, v, strict=True):
        hg = pin.computeCentroidalMomentum(model, data, pin_configuration(qk), pin_velocity(qk, vk))
        momenta.append(np.r_[hg.linear, hg.angular])
        coms.append(data.com[0].copy())
    out = []
    for k in range(len(q) - 1):
        points = contact_points(model, q[k], links, offsets)
        force = mass * GRAVITY + forces[k].sum(axis=0)
        moment = sum(
            np.cross(r - coms[k], f) + t
            for r, f, t in zip(points, forces[k], moments[k], strict=True)
        )
        rate = np.r_[force, moment]
        out.append(np.abs(momenta[k + 1] - momenta[k] - dt[k] * rate).max())
    return np.array(out)
