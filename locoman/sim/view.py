"""Open a scene, or a TO trajectory in its scene, in MuJoCo's interactive viewer.

Usage: ``python -m locoman.sim.view data/<scenario>/scene [data/<scenario>/solve]``

With a solve folder the trajectory plays in a loop at its own timing (the TO's nodes, the
pose held between them). Needs a display; without one, look at the filmstrip
(``data/<scenario>/evaluate/filmstrip.png``) or the MCAP in Foxglove.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import mujoco
import numpy as np

from locoman.artifacts import read_npz
from locoman.errors import LocomanError, SceneError
from locoman.scene.io import load_scene_model
from locoman.sim.evaluate import scene_qpos
from locoman.to.io import TRAJECTORY, TRAJECTORY_FILE


def has_display() -> bool:
    """Whether a window can open (X11 or Wayland)."""
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def trajectory_qpos(model: mujoco.MjModel, solve_dir: Path) -> tuple[np.ndarray, np.ndarray]:
    """(N,) node times [s] and (N, nq) MuJoCo qpos of a TO trajectory."""
    traj = read_npz(solve_dir / TRAJECTORY_FILE, TRAJECTORY)
    names = [str(name) for name in traj["object_names"]]
    qpos = np.array(
        [scene_qpos(model, q, names, o) for q, o in zip(traj["q"], traj["object_q"], strict=True)]
    )
    return np.r_[0.0, np.cumsum(traj["dt"][:-1])], qpos


def view(scene_dir: Path, solve_dir: Path | None) -> None:
    """Open the viewer until its window closes.

    Raises:
        SceneError: Without a display.
    """
    if not has_display():
        raise SceneError(
            "no display (DISPLAY and WAYLAND_DISPLAY are unset): the viewer needs a window; "
            "see the filmstrip PNG or open the trajectory's MCAP in Foxglove instead"
        )
    import mujoco.viewer  # needs a display to import its GUI back end

    model = load_scene_model(scene_dir)
    data = mujoco.MjData(model)
    data.qpos[:] = model.key("home").qpos
    times, frames = (None, None) if solve_dir is None else trajectory_qpos(model, solve_dir)
    with mujoco.viewer.launch_passive(model, data) as handle:
        start = time.monotonic()
        while handle.is_running():
            if frames is not None:
                t = (time.monotonic() - start) % times[-1]
                data.qpos[:] = frames[np.searchsorted(times, t, side="right") - 1]
            mujoco.mj_forward(model, data)
            handle.sync()
            time.sleep(1.0 / 60.0)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scene_dir", type=Path)
    parser.add_argument("solve_dir", type=Path, nargs="?")
    args = parser.parse_args(argv)
    try:
        view(args.scene_dir, args.solve_dir)
    except LocomanError as exc:
        print(f"locoman: {type(exc).__name__}: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
