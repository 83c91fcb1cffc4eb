"""Paper A's figures of one scenario, each into its canonical folder, on all or part of a grid.

Usage: python benchmarks/figures_subset.py <scenario> [--box-mass M ...] [--initial-yaw Y ...]
       [--figures fig5|fig6|vb|fig6_paper ...] [--runs NAME ...] [--draw-only]
       [--results benchmarks/results]

S1's and S2's full grids (``figures.grids``: 6 and 15 cells, 8 keyframe settings each) take
hours on 2 cores with the found-pair rounds. This runs the chosen figures (default: every
one the scenario can run) at the given box masses [kg] and initial yaws [rad] (default: the
scenario's ``figures.grids`` entry; Fig. 5 is always at ``scenario.box_mass``,
``initial_yaw``), and draws each with the figures stage's code into its canonical folder
``<results>/<scenario>/<figure>/``: ``<figure>.png``, summary.csv, summary.md,
metrics.json, timing.json, the drawn cells' records (``records/``, restorable in another
checkout: :mod:`locoman.grid.archive`) and ``provenance.json`` (the commit and what the
cells read: :mod:`locoman.grid.provenance`; ``make results`` says whether today's code
would give the grid again). The cells are those of the full grid, under
``data/<scenario>/grid/``: the full grid reuses them, and this reuses the full grid's.
``--runs`` keeps only these of each figure's runs (``none all``: Fig. 6's NoKeyframe and
AllKeyframe, which its claims compare); ``--draw-only`` draws the cells' records as they are
(run by hand, restored, or on a cluster) and solves nothing.
"""

from __future__ import annotations

import argparse
import shlex
import sys
import tempfile
from pathlib import Path

import yaml

from locoman.config import load_params
from locoman.errors import LocomanError
from locoman.grid.archive import export_records
from locoman.grid.launch import cells, launch_figures
from locoman.grid.provenance import RESULTS_DIR, stamp
from locoman.grid.report import REPORTS, default_figures, draw


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenario")
    parser.add_argument("--box-mass", type=float, nargs="+", help="[kg]")
    parser.add_argument("--initial-yaw", type=float, nargs="+", help="[rad]")
    parser.add_argument("--figures", nargs="+", choices=list(REPORTS), help="default: all it can")
    parser.add_argument("--runs", nargs="+", help="only these runs of each figure")
    parser.add_argument("--draw-only", action="store_true", help="draw the records, solve nothing")
    parser.add_argument("--results", type=Path, default=RESULTS_DIR, help="the results folder")
    args = parser.parse_args(argv)
    cfg = load_params()
    if args.scenario not in cfg.figures.grids:
        print(f"figures.grids has no {args.scenario!r}", file=sys.stderr)
        return 2
    grid = cfg.figures.grids[args.scenario]
    raw = yaml.safe_load(Path("params.yaml").read_text())
    raw["figures"]["grids"][args.scenario] |= {
        "box_mass": args.box_mass or list(grid.box_mass),
        "initial_yaw": args.initial_yaw or list(grid.initial_yaw),
    }
    command = shlex.join(["python", "benchmarks/figures_subset.py", *argv])
    with tempfile.TemporaryDirectory() as tmp:
        # The cells read this file; it differs from params.yaml in the grid only, which is
        # not part of a cell's key, so the cells are the full grid's.
        params = Path(tmp) / "params.yaml"
        params.write_text(yaml.safe_dump(raw, sort_keys=False))
        subset = load_params(params)
        figures = args.figures or default_figures(subset, args.scenario)
        try:
            seconds = None
            if not args.draw_only:
                seconds = launch_figures(subset, args.scenario, figures, params, args.runs)
            for figure in figures:
                out = args.results / args.scenario / figure
                wall = None if seconds is None else {figure: seconds[figure]}
                draw(subset, args.scenario, [figure], out, Path("data"), wall, args.runs)
                drawn = {c.name for c in cells(subset, args.scenario, figure, args.runs)}
                export_records(Path("data"), args.scenario, figure, out, drawn)
                stamp(out, args.scenario, figure, command)
                print(f"[figures_subset] {out}/", flush=True)
        except LocomanError as exc:
            print(f"locoman: {type(exc).__name__}: {exc}", file=sys.stderr)
            return 2
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
