"""Solve time and iterations of the G1 stance slice of the TO as the horizon grows.

Usage: python benchmarks/to_stance.py [--nodes 5 10 20 30] [--out benchmarks/results/to_stance.json]

The problem: the standing G1, both feet in patch contact, pulled by the keyframe base cost
(9) towards a base 12 cm lower, from rest. Interpreted SX (expanded), exact Hessian, IPOPT
with MUMPS; issue 6 targets 30 s for `tiny` and cites about 5 s for a 30-node squat with
compiled per-node Hessians.
"""

from __future__ import annotations

import argparse

from locoman.artifacts import write_json_atomic
from locoman.scene import g1
from locoman.to.stance import StanceCfg, solve_stance


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--nodes", type=int, nargs="+", default=[5, 10, 20, 30])
    parser.add_argument("--out", default="benchmarks/results/to_stance.json")
    args = parser.parse_args()
    q_start = g1.standing_q35()
    q_keyframe = q_start.copy()
    q_keyframe[2] -= 0.12
    rows = []
    for n in args.nodes:
        s = solve_stance(q_start, q_keyframe, StanceCfg(nodes=n))
        row = {
            "nodes": n,
            "status": s.status,
            "iterations": s.iterations,
            "solve_time_s": s.solve_time_s,
            "seconds_per_iteration": s.solve_time_s / max(s.iterations, 1),
            "build_time_s": s.build_time_s,
            "n_variables": s.n_variables,
            "n_constraints": s.n_constraints,
        }
        rows.append(row)
        print(row, flush=True)
    write_json_atomic(args.out, {"problem": "G1 stance, keyframe base 12 cm lower", "rows": rows})


if __name__ == "__main__":
    main()
