"""A stance foot's wrench: the contact wrench cone of a rectangular sole.

The sole is a rectangle of half length X and half width Y [m] touching its support at its four
corners, each pushing with a force inside its friction pyramid (|f_t| <= mu f_n per axis), as
MuJoCo's box-on-plane contact does. The wrench (f, tau) at the sole's centre, in the sole's
frame, is a sum of such corner forces exactly when (Caron, Pham and Nakamura, "Stability of
surface contacts for humanoid robots: closed-form formulae of the contact wrench cone for
rectangular support areas", ICRA 2015):

    |f_x| <= mu f_z,  |f_y| <= mu f_z                                  friction
    |tau_x| <= Y f_z,  |tau_y| <= X f_z                                 CoP inside the sole
    tau_z + |Y f_x + mu tau_x| + |X f_y + mu tau_y| <= mu (X + Y) f_z   yaw, one way
    -tau_z + |Y f_x - mu tau_x| + |X f_y - mu tau_y| <= mu (X + Y) f_z  yaw, the other
    f_z >= f_min                                                       unilateral, loaded

Paper A's (3c), |tau_z| <= mu max(X, Y) f_z, allows a yaw moment the corners cannot carry when
the CoP is near an edge: on tiny's first step the TO asks 25 N m of a sole loaded on its heel,
and MuJoCo's foot spins (docs/execution.md). The QP uses these rows, written ``C w <= d`` on
the wrench in world axes.
"""

from __future__ import annotations

import numpy as np

_AXES = {"fx": 0, "fy": 1, "fz": 2, "tx": 3, "ty": 4, "tz": 5}


def _row(**coefficients: float) -> np.ndarray:
    row = np.zeros(6)
    for name, value in coefficients.items():
        row[_AXES[name]] = value
    return row


def local_wrench_rows(mu: float, half_extents: np.ndarray) -> np.ndarray:
    """(17, 6) C_local of the cone above, C_local (f, tau) <= d in the sole's frame; the last
    row is -f_z <= -f_min (:func:`wrench_bounds`)."""
    x, y = (float(h) for h in half_extents)
    rows = []
    for s in (1.0, -1.0):
        rows += [
            _row(fx=s, fz=-mu),
            _row(fy=s, fz=-mu),
            _row(tx=s, fz=-y),
            _row(ty=s, fz=-x),
        ]
    yaw = -mu * (x + y)
    for a in (1.0, -1.0):
        for b in (1.0, -1.0):
            rows.append(_row(tz=1.0, fx=a * y, tx=a * mu, fy=b * x, ty=b * mu, fz=yaw))
            rows.append(_row(tz=-1.0, fx=a * y, tx=-a * mu, fy=b * x, ty=-b * mu, fz=yaw))
    rows.append(_row(fz=-1.0))
    return np.array(rows)


def wrench_bounds(min_normal_force_n: float) -> np.ndarray:
    """(17,) d of :func:`local_wrench_rows`."""
    d = np.zeros(17)
    d[-1] = -min_normal_force_n
    return d


def world_wrench_rows(local_rows: np.ndarray, rotation: np.ndarray) -> np.ndarray:
    """C for a wrench in world axes: C_local diag(R^T, R^T), R the sole's frame (3, 3)."""
    out = np.empty_like(local_rows)
    out[:, :3] = local_rows[:, :3] @ rotation.T
    out[:, 3:] = local_rows[:, 3:] @ rotation.T
    return out
