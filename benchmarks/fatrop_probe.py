"""Would a structure-exploiting factorisation pay for S2? fatrop against IPOPT + MUMPS.

fatrop (in CasADi's wheel) solves optimal control problems by a Riccati recursion over
stage blocks instead of a general sparse LDL'. The TO cannot be handed to it as it stands
(its dynamics (1b) are semi-implicit, and fatrop needs x_{k+1} = F(x_k, u_k)), so this
measures what a reformulation could buy before anyone writes one: an optimal control
problem with S2's stage sizes (per node 94 states: the robot's q and v, two objects' q and
v; 48 controls: wrenches, slacks, alpha, dt; 112 constraints with the gap-closing ones),
nonlinear dynamics, equalities and two-sided inequalities, solved by both with the same
CasADi functions. Reported: each solver's time per iteration outside the NLP's functions
(its linear algebra and bookkeeping), median of ``--repeats`` solves after a first one that
builds the solver.

    python benchmarks/fatrop_probe.py [--nodes 192] [--repeats 3] [--max-iter 40]

writes ``benchmarks/results/fatrop_probe.json``.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import platform
import statistics
import time
from pathlib import Path

import casadi as ca
import numpy as np
from common import write_benchmark

OUT = Path(__file__).parent / "results" / "fatrop_probe.json"


def build(nodes: int, nx: int, nu: int, n_eq: int, n_ineq: int, seed: int = 0) -> ca.Opti:
    """The probe's OCP in fatrop's stage order: per stage its gap-closing constraint, then
    its path constraints; every block 20-30 % dense, as the TO's node blocks are."""
    rng = np.random.default_rng(seed)
    a = np.eye(nx) + 0.02 * rng.standard_normal((nx, nx)) * (rng.random((nx, nx)) < 0.2)
    b = 0.05 * rng.standard_normal((nx, nu)) * (rng.random((nx, nu)) < 0.3)
    c = rng.standard_normal((n_eq, nx + nu)) * (rng.random((n_eq, nx + nu)) < 0.2)
    g = rng.standard_normal((n_ineq, nx + nu)) * (rng.random((n_ineq, nx + nu)) < 0.2)
    xs, us = ca.SX.sym("x", nx), ca.SX.sym("u", nu)
    z = ca.vertcat(xs, us)
    step = ca.Function("F", [xs, us], [a @ xs + b @ us + 0.01 * ca.sin(xs)])
    equal = ca.Function("h", [xs, us], [c @ z + 0.01 * z[:n_eq] ** 2])
    inside = ca.Function("g", [xs, us], [g @ z + 0.05 * ca.sin(z[:n_ineq])])

    opti = ca.Opti()
    x, u = [], []
    for k in range(nodes + 1):  # variables in stage order: x0, u0, x1, u1, ..., xN
        x.append(opti.variable(nx))
        if k < nodes:
            u.append(opti.variable(nu))
    cost = ca.sumsqr(x[nodes])
    for k in range(nodes):
        opti.subject_to(x[k + 1] == step(x[k], u[k]))
        if k == 0:
            opti.subject_to(x[0] == 0.1)
        opti.subject_to(equal(x[k], u[k]) == 0.1)
        opti.subject_to(opti.bounded(-1, inside(x[k], u[k]), 1))
        opti.subject_to(opti.bounded(-3, u[k], 3))
        cost += ca.sumsqr(x[k] - 0.5) + 0.1 * ca.sumsqr(u[k]) + ca.sum1(ca.cos(x[k][: min(10, nx)]))
    opti.minimize(cost)
    return opti


SOLVERS = {
    "fatrop": lambda it: (
        "fatrop",
        {"structure_detection": "auto", "fatrop": {"print_level": 0, "max_iter": it}},
    ),
    # MUMPS as the TO runs it (solver.mumps_scaling false).
    "ipopt_mumps": lambda it: (
        "ipopt",
        {
            "ipopt": {
                "print_level": 0,
                "max_iter": it,
                "mumps_scaling": 0,
                "mumps_permuting_scaling": 0,
            }
        },
    ),
}


def measure(name: str, args: argparse.Namespace) -> dict:
    plugin, options = SOLVERS[name](args.max_iter)
    opti = build(args.nodes, args.nx, args.nu, args.n_eq, args.n_ineq)
    opti.solver(plugin, {"expand": True, "print_time": False, **options})
    runs = []
    for repeat in range(args.repeats + 1):  # the first builds the solver: not counted
        start = time.perf_counter()
        # Out of iterations raises: the time per iteration still counts.
        with contextlib.suppress(RuntimeError):
            opti.solve()
        wall = time.perf_counter() - start
        stats = opti.stats()
        functions = sum(v for k, v in stats.items() if k.startswith("t_wall_nlp_"))
        iterations = int(stats["iter_count"])
        if repeat:
            runs.append(
                {
                    "iterations": iterations,
                    "wall_s": wall,
                    "functions_s": functions,
                    "seconds_per_iteration_outside_functions": (wall - functions) / iterations,
                    "status": str(stats.get("return_status")),
                }
            )
    per_iteration = [r["seconds_per_iteration_outside_functions"] for r in runs]
    return {
        "runs": runs,
        "median_seconds_per_iteration_outside_functions": statistics.median(per_iteration),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--nodes", type=int, default=192, help="stages (S2: 192)")
    parser.add_argument("--nx", type=int, default=94, help="states per stage")
    parser.add_argument("--nu", type=int, default=48, help="controls per stage")
    parser.add_argument("--n-eq", type=int, default=8, help="path equalities per stage")
    parser.add_argument("--n-ineq", type=int, default=10, help="path inequalities per stage")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--max-iter", type=int, default=40)
    parser.add_argument("--out", type=Path, default=OUT)
    args = parser.parse_args()
    result = {
        "machine": {"cpus": os.cpu_count(), "platform": platform.platform()},
        "casadi": ca.__version__,
        "problem": {k: getattr(args, k) for k in ("nodes", "nx", "nu", "n_eq", "n_ineq")},
        "max_iter": args.max_iter,
        "repeats": args.repeats,
    }
    for name in SOLVERS:
        result[name] = measure(name, args)
        print(name, result[name]["median_seconds_per_iteration_outside_functions"], flush=True)
    write_benchmark(args.out, result)


if __name__ == "__main__":
    main()
