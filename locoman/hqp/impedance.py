"""Joint impedance law of the torque-controlled arm (paper B, eq. (10))."""

from __future__ import annotations

import mujoco
import numpy as np


def joint_impedance_torque(
    q_star: np.ndarray,
    qdot_star: np.ndarray,
    q: np.ndarray,
    qdot: np.ndarray,
    stiffness: float,
    damping: float,
    gravity: np.ndarray,
) -> np.ndarray:
    """tau_a = K_d (qdot_a* - qdot_a) + K_p (q_a* - q_a) + g_a  [N m], eq. (10)."""
    return damping * (qdot_star - qdot) + stiffness * (q_star - q) + gravity


class GravityModel:
    """g(q) of a MuJoCo model: the bias forces at zero velocity, on a scratch ``MjData``."""

    def __init__(self, model: mujoco.MjModel) -> None:
        self.model = model
        self.data = mujoco.MjData(model)
        self.out = np.zeros(model.nv)

    def __call__(self, qpos: np.ndarray) -> np.ndarray:
        """Generalised gravity forces (nv,) at ``qpos`` [N] or [N m]."""
        self.data.qpos[:] = qpos
        mujoco.mj_kinematics(self.model, self.data)
        mujoco.mj_comPos(self.model, self.data)
        mujoco.mj_rne(self.model, self.data, 0, self.out)
        return self.out
