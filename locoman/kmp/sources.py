"""Where the demonstrations come from: the synthetic protocol or recorded files."""

from __future__ import annotations

import numpy as np

from locoman.config.skill_transfer import DemosCfg
from locoman.errors import DemoError
from locoman.kmp.demos import Demos, TaskPoints, select_demos, synthetic_demos
from locoman.kmp.mocap_csv import load_demo_dir


def collect_demos(
    cfg: DemosCfg, task: TaskPoints, seed: int
) -> tuple[Demos, np.ndarray, np.ndarray]:
    """The demonstrations of ``cfg.source``, the ``cfg.n_selected`` kept for learning and
    every demonstration's grasp miss [m] (see :func:`locoman.kmp.demos.select_demos`).

    Raises:
        DemoError: The recorded folder holds fewer demonstrations than ``n_selected``, or a
            file is malformed or implausible (:func:`locoman.kmp.mocap_csv.load_demo_dir`).
    """
    if cfg.source == "synthetic":
        return synthetic_demos(cfg, task, seed)
    demos = load_demo_dir(cfg.csv_dir, cfg.rate_hz, cfg.duration_s)
    recorded = demos.wrist_pos.shape[0]
    if recorded < cfg.n_selected:
        raise DemoError(
            f"{cfg.csv_dir} holds {recorded} demonstrations and demos.n_selected is "
            f"{cfg.n_selected}: record more or lower demos.n_selected"
        )
    selected, miss = select_demos(demos, task, cfg.grasp_time_s, cfg.n_selected)
    return demos, selected, miss
