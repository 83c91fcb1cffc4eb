"""A stance foot's wrench: the linearised friction cone and centre-of-pressure limits.

Paper A's (3a)-(3c) on the sole's wrench (f, tau) at its centre, in the sole's frame
(``locoman.to.terms.contacts`` states them for the TO, ``locoman.sim.evaluate.cone_violation``
checks them), written as ``C w <= d`` on the wrench in world axes:

    |f_x| <= mu f_z,  |f_y| <= mu f_z                      (3a) friction pyramid
    |tau_y| <= X f_z,  |tau_x| <= Y f_z                     (3b) CoP inside the sole
    |tau_z| <= mu max(X, Y) f_z                             (3c) yaw moment
    f_z >= f_min                                            unilateral, kept loaded

with X, Y the sole's half length and half width [m].
"""

from __future__ import annotations

import numpy as np


def local_wrench_rows(mu: float, half_extents: np.ndarray) -> np.ndarray:
    """(11, 6) C_local with C_local (f, tau) <= d in the contact frame; the last row is
    -f_z <= -f_min (:func:`wrench_bounds`)."""
    x, y = (float(h) for h in half_extents)
    yaw = mu * max(x, y)
    rows = []
    for axis, scale in ((0, mu), (1, mu), (4, x), (3, y), (5, yaw)):
        for sign in (1.0, -1.0):
            row = np.zeros(6)
            row[axis] = sign
            row[2] = -scale
            rows.append(row)
    rows.append(np.array([0.0, 0.0, -1.0, 0.0, 0.0, 0.0]))
    return np.array(rows)


def wrench_bounds(min_normal_force_n: float) -> np.ndarray:
    """(11,) d of :func:`local_wrench_rows`."""
    d = np.zeros(11)
    d[-1] = -min_normal_force_n
    return d


def world_wrench_rows(local_rows: np.ndarray, rotation: np.ndarray) -> np.ndarray:
    """C for a wrench in world axes: C_local diag(R^T, R^T), R the contact frame (3, 3)."""
    out = np.empty_like(local_rows)
    out[:, :3] = local_rows[:, :3] @ rotation.T
    out[:, 3:] = local_rows[:, 3:] @ rotation.T
    return out
