"""Paper A's Fig. 5 and Fig. 6 of one scenario on a subset of its Fig. 6 grid.

Usage: python benchmarks/figures_subset.py <scenario> <out_dir> [--box-mass M ...]
       [--initial-yaw Y ...] [--figures fig5|fig6|vb|fig6_paper ...] [--runs NAME ...]
       [--draw-only]

S1's and S2's full grids (``figures.grids``: 6 and 15 cells, 8 keyframe settings each) take
hours on 2 cores with the found-pair rounds. This runs the chosen figures (default: every
one the scenario can run) at the given box masses [kg] and initial yaws [rad] (default: the
scenario's ``scenario.box_mass``, ``initial_yaw``; Fig. 5 is always at those), and draws
them with the figures stage's code into ``out_dir`` (``<figure>.png``, summary.csv,
summary.md, metrics.json, timing.json). The cells are those of the full grid, under
``data/<scenario>/grid/``: the full grid reuses them, and this reuses the full grid's.
``--runs`` keeps only these of each figure's runs (``none all``: Fig. 6's NoKeyframe and
AllKeyframe, which its claims compare); ``--draw-only`` draws the cells' records as they are
(run by hand or on a cluster) and solves nothing. The drawn cells' records go to
``out_dir/records/`` (:mod:`locoman.grid.archive`: restored in another checkout, the cells
whose key matches are not solved again).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import yaml

from locoman.config import load_params
from locoman.errors import LocomanError
from locoman.grid.archive import export_records
from locoman.grid.launch import cells
from locoman.grid.report import REPORTS, figures_scenario


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenario")
    parser.add_argument("out_dir", type=Path)
    parser.add_argument("--box-mass", type=float, nargs="+", help="[kg]")
    parser.add_argument("--initial-yaw", type=float, nargs="+", help="[rad]")
    parser.add_argument("--figures", nargs="+", choices=list(REPORTS), help="default: all it can")
    parser.add_argument("--runs", nargs="+", help="only these runs of each figure")
    parser.add_argument("--draw-only", action="store_true", help="draw the records, solve nothing")
    args = parser.parse_args(argv)
    cfg = load_params()
    if args.scenario not in cfg.figures.grids:
        print(f"figures.grids has no {args.scenario!r}", file=sys.stderr)
        return 2
    masses = args.box_mass or [cfg.scenario.box_mass]
    yaws = args.initial_yaw or [cfg.scenario.initial_yaw]
    raw = yaml.safe_load(Path("params.yaml").read_text())
    raw["figures"]["grids"][args.scenario] |= {"box_mass": masses, "initial_yaw": yaws}
    with tempfile.TemporaryDirectory() as tmp:
        # The cells read this file; it differs from params.yaml in the grid only, which is
        # not part of a cell's key, so the cells are the full grid's.
        params = Path(tmp) / "params.yaml"
        params.write_text(yaml.safe_dump(raw, sort_keys=False))
        subset = load_params(params)
        try:
            metrics = figures_scenario(
                subset,
                args.scenario,
                args.out_dir,
                params_file=params,
                figures=args.figures,
                runs=args.runs,
                solve=not args.draw_only,
            )
            for figure in metrics.keys() - {"claims"}:
                drawn = {c.name for c in cells(subset, args.scenario, figure, args.runs)}
                export_records(Path("data"), args.scenario, figure, args.out_dir, drawn)
        except LocomanError as exc:
            print(f"locoman: {type(exc).__name__}: {exc}", file=sys.stderr)
            return 2
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
