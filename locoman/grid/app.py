"""The Hydra app of the figure grids: each job runs one cell (:func:`run_cell`).

``python -m locoman.grid.app -m cell.run=none,all cell.box_mass=2.5,5.0 ...`` sweeps the
cells with Hydra's multirun; ``hydra/launcher=`` picks where they run (``joblib``, the
default, locally in parallel; ``submitit_slurm`` on a SLURM cluster; ``submitit_local``
through submitit on this machine). Config: ``locoman/grid/conf/grid.yaml``. Normally
started by ``python -m locoman.grid`` (:mod:`locoman.grid.launch`), which builds the sweep
from ``params.yaml`` and pins the CPU kernels in the jobs' environment
(:mod:`locoman.kernels`; run directly, the app uses the CPU's own).
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path
from typing import Any

import hydra
from omegaconf import DictConfig, OmegaConf
from threadpoolctl import threadpool_limits

from locoman.config import load_params
from locoman.errors import ConfigError
from locoman.grid.cell import CellCfg, run_cell
from locoman.grid.slots import environment_slot

CONFIG_DIR = Path(__file__).resolve().parent / "conf"


def summary(record: dict[str, Any]) -> str:
    """One line per cell: what it is, its status, and its headline numbers."""
    name = CellCfg(**{f.name: record[f.name] for f in dataclasses.fields(CellCfg)}).name
    head = f"[grid {record['scenario']} {record['figure']}] {name}: {record['status']}"
    if record["status"] == "error":
        return f"{head} ({record['reason']})"
    pen = record["avg_penetration_m"]
    pen_text = "n/a" if pen is None else f"{pen * 1000:.2f} mm"
    why = f" ({record['reason']})" if record["reason"] else ""
    if record.get("skipped"):
        reuse = " (up to date, skipped)"
    elif record.get("reevaluated"):
        reuse = " (its solve up to date: evaluated again)"
    else:
        reuse = ""
    return f"{head}{why}, {record['iterations']} its, avg penetration {pen_text}{reuse}"


@hydra.main(version_base="1.3", config_path=str(CONFIG_DIR), config_name="grid")
def main(cfg: DictConfig) -> dict[str, Any]:
    fields = {f.name for f in dataclasses.fields(CellCfg)}
    raw = OmegaConf.to_container(cfg.cell)
    unknown = sorted(set(raw) - fields)
    if unknown:
        raise ConfigError(f"cell: unknown keys {unknown}; a cell has {sorted(fields)}")
    # Hydra reads `cell.box_mass=5` as an int: the same cell must have the same key.
    cell = CellCfg(
        str(raw["scenario"]),
        str(raw["figure"]),
        str(raw["run"]),
        float(raw["box_mass"]),
        float(raw["initial_yaw"]),
    )
    # One BLAS / OpenMP thread per cell, as every stage (locoman.stage.run_stage): the same
    # bits on any machine, and n_jobs cells share the cores instead of oversubscribing them.
    os.environ["OPENBLAS_NUM_THREADS"] = os.environ["OMP_NUM_THREADS"] = "1"
    # Grids launched side by side share the workers (locoman/grid/slots.py).
    with environment_slot(), threadpool_limits(limits=1):
        record = run_cell(load_params(cfg.params_file), cell, Path(cfg.data_dir))
    print(summary(record), flush=True)
    return record


if __name__ == "__main__":
    main()
