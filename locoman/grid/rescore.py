"""Score a grid's kept solves again with today's evaluation, and redraw it; solve nothing.

Usage: ``python -m locoman.grid.rescore <scenario> <figure> <out_dir> [params.yaml]``

A plain grid run (``python -m locoman.grid``, ``dvc repro figures@<scenario>``) already
evaluates a cell again, without solving, when only the evaluation changed. When the solve's
code or parameters changed too, it would solve again; this scores the trajectories the cells
kept with today's evaluation instead (each record says ``"rescored": true`` and keeps the key
of the solve it holds) and draws the figure's summary into ``out_dir``, so an old grid can
be read with a new metric. Cells without a kept solve are named, and the figure is not drawn.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

from locoman.config import load_params
from locoman.errors import ArtifactError, LocomanError
from locoman.grid.app import summary
from locoman.grid.cell import cell_dir, run_cell
from locoman.grid.launch import cells
from locoman.grid.report import REPORTS, draw
from locoman.kernels import pin_kernels


def rescore(
    scenario: str,
    figure: str,
    out_dir: Path,
    params_file: Path = Path("params.yaml"),
    data_dir: Path = Path("data"),
) -> dict:
    """Evaluate every cell of ``figure`` again on its kept solve and draw the figure into
    ``out_dir``; return its metrics.

    Raises:
        ConfigError: An unknown figure or scenario.
        ArtifactError: Cells without a kept solve (named).
    """
    cfg = load_params(params_file)
    missing = []
    for cell in cells(cfg, scenario, figure):
        try:
            print(summary(run_cell(cfg, cell, data_dir, rescore=True)), flush=True)
        except ArtifactError:
            missing.append(str(cell_dir(data_dir, cell)))
    if missing:
        raise ArtifactError(
            f"{len(missing)} cells have no kept solve to score: {', '.join(missing)}; run "
            f"`python -m locoman.grid {scenario} {figure}` for them"
        )
    return draw(cfg, scenario, [figure], Path(out_dir), data_dir)


def main(argv: list[str]) -> int:
    if len(argv) not in (3, 4) or argv[1] not in REPORTS:
        print(__doc__, file=sys.stderr)
        return 2
    env = dict(os.environ)
    if pin_kernels(env):  # NumPy has loaded its kernels: start again with them pinned
        os.execve(sys.executable, [sys.executable, "-m", __spec__.name, *argv], env)
    params = Path(argv[3]) if len(argv) == 4 else Path("params.yaml")
    try:
        rescore(argv[0], argv[1], Path(argv[2]), params)
    except LocomanError as exc:
        print(f"locoman: {type(exc).__name__}: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
