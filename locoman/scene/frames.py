"""World poses of every body of a MuJoCo model along a trajectory, for MCAP/Foxglove."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np

from locoman.artifacts.mcap_io import write_frame_transforms


def body_frames(
    model: mujoco.MjModel, qpos: np.ndarray
) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Body name -> (positions (T, 3) [m], quaternions (T, 4) (w, x, y, z)) for ``qpos`` (T, nq)."""
    qpos = np.atleast_2d(np.asarray(qpos, dtype=float))
    if qpos.shape[1] != model.nq:
        raise ValueError(f"qpos has {qpos.shape[1]} columns, the model has nq = {model.nq}")
    data = mujoco.MjData(model)
    pos = np.empty((len(qpos), model.nbody, 3))
    quat = np.empty((len(qpos), model.nbody, 4))
    for k, q in enumerate(qpos):
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        pos[k], quat[k] = data.xpos, data.xquat
    return {model.body(b).name: (pos[:, b], quat[:, b]) for b in range(1, model.nbody)}


def write_trajectory_mcap(
    path: str | Path, model: mujoco.MjModel, times: np.ndarray, qpos: np.ndarray
) -> None:
    """Write the link and object poses of a ``qpos`` trajectory as ``foxglove.FrameTransforms``.

    Args:
        path: Output ``.mcap``.
        model: The scene's MuJoCo model.
        times: (T,) time of each configuration [s].
        qpos: (T, nq) configurations.
    """
    write_frame_transforms(path, times, body_frames(model, qpos))
