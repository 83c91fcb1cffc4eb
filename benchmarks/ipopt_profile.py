"""Where a TO solve's time goes, per IPOPT call: function evaluations against the linear algebra.

Usage: python benchmarks/ipopt_profile.py [--scenarios tiny s1_basket s2_trolley]
       [--ipopt KEY=VALUE ...] [--out benchmarks/results/ipopt_profile.json]

Runs the ``solve`` stage's work (the first solve, the switch to the exact Hessian, the rounds
that add found collision pairs) at the defaults of ``params.yaml`` with IPOPT's
``print_timing_statistics``, and splits each IPOPT call's time from its report: the NLP's
function evaluations (the Lagrangian's Hessian, the gradient, the constraint Jacobians
apart), the KKT system's solves (MUMPS's factorisations and back-solves; IPOPT's timer
PDSystemSolverTotal) and the rest of IPOPT; with the
iterations and how many of them needed an inertia correction (a regularised, refactorised
KKT system: IPOPT's ``lg(rg)`` column). The scenes, contacts and keyframes are the current
``data/<scenario>`` artifacts (``dvc repro retarget`` first). ``--ipopt`` adds IPOPT options
to the backend's (``mumps_pivot_order=5``: what another ordering of MUMPS costs) and the output
records them. The solve runs in a child
process whose standard output (IPOPT writes it from C) goes to a file that is parsed here.
Times are IPOPT's wall seconds: on a busy machine they include waiting for a core.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from common import write_benchmark

CHILD = """
import json, os, sys, tempfile
from pathlib import Path
from locoman.kernels import pin_kernels
pin_kernels()
from locoman.config import load_params
from locoman.config import to as to_cfg
from locoman.to.pipeline import solve_scenario
for options in to_cfg.BACKENDS.values():
    options["print_timing_statistics"] = "yes"
    options.update(json.loads(os.environ["LOCOMAN_IPOPT_OPTIONS"]))
import dataclasses
params = load_params()
# IPOPT's table (print level 5) is what the parent parses.
solver = dataclasses.replace(params.solve.solver, print_level=5)
root = Path("data") / sys.argv[1]
with tempfile.TemporaryDirectory() as tmp:
    inputs = [root / "scene", root / "contacts", root / "retarget"]
    traj = solve_scenario(*inputs, Path(tmp), dataclasses.replace(params.solve, solver=solver))
print("@@ status", traj.status, traj.iterations, traj.solve_time_s, flush=True)
"""

# "LinearSystemFactorization.........:      0.500 (sys:      0.010 wall:      0.512)"
TIMER = re.compile(r"^\s*(\w[\w ]*?)\.*:\s+([\d.]+) \(sys:\s+[\d.]+ wall:\s+([\d.]+)\)")
# An iteration line: iter objective inf_pr inf_du lg(mu) ||d|| lg(rg) alpha_du alpha_pr ls
ITERATION = re.compile(r"^\s*(\d+)[rh]?\s+\S+\s+\S+\s+\S+\s+\S+\s+\S+\s+(\S+)\s+\S+\s+\S+\s+\d+")
KEYS = {
    "OverallAlgorithm": "total_s",
    "Function Evaluations": "functions_s",
    "Lagrangian Hessian": "hessian_s",
    "Objective function gradient": "gradient_s",
    "Equality constraint Jacobian": "jacobian_s",
    "Inequality constraint Jacobian": "jacobian_s",
    # MUMPS factorises inside the multi-solve: IPOPT's LinearSystemFactorization stays 0.
    "PDSystemSolverTotal": "kkt_solve_s",
    "LinearSystemSymbolicFactorization": "symbolic_factorisation_s",
}
SUMMED = (
    "total_s",
    "functions_s",
    "hessian_s",
    "gradient_s",
    "jacobian_s",
    "kkt_solve_s",
    "other_s",
)


def parse(log: str) -> list[dict]:
    """One record per IPOPT call in ``log``: its timers [s] (wall) and iteration counts."""
    calls, current, iterations, corrected = [], {}, 0, 0
    for line in log.splitlines():
        if (m := ITERATION.match(line)) is not None:
            iterations += 1
            corrected += m.group(2) != "-"
        elif (m := TIMER.match(line)) is not None and m.group(1).strip() in KEYS:
            key = KEYS[m.group(1).strip()]
            current[key] = current.get(key, 0.0) + float(m.group(3))
        elif line.startswith("EXIT:"):
            current |= {
                "exit": line[5:].strip(),
                "iterations": max(iterations - 1, 0),  # iteration 0 is the start
                "inertia_corrected_iterations": corrected,
            }
            calls.append(current)
            current, iterations, corrected = {}, 0, 0
    for call in calls:
        known = call.get("functions_s", 0.0) + call.get("kkt_solve_s", 0.0)
        call["other_s"] = call.get("total_s", 0.0) - known
    return calls


def option(text: str) -> tuple[str, object]:
    """``KEY=VALUE`` as IPOPT takes it: an integer, a real or a string."""
    key, sep, value = text.partition("=")
    if not sep or not key:
        raise argparse.ArgumentTypeError(f"{text!r}: write an IPOPT option as KEY=VALUE")
    for kind in (int, float):
        try:
            return key, kind(value)
        except ValueError:
            pass
    return key, value


def profile(scenario: str, options: dict[str, object]) -> dict:
    with tempfile.NamedTemporaryFile("w+", suffix=".log") as log:
        tic = time.perf_counter()
        env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1")
        env["LOCOMAN_IPOPT_OPTIONS"] = json.dumps(options)
        subprocess.run(
            [sys.executable, "-c", CHILD, scenario],
            stdout=log,
            stderr=subprocess.STDOUT,
            check=True,
            env=env,
        )
        wall = time.perf_counter() - tic
        log.seek(0)
        text = log.read()
    calls = parse(text)
    totals = {k: sum(c.get(k, 0.0) for c in calls) for k in SUMMED}
    iterations = sum(c["iterations"] for c in calls)
    return {
        "scenario": scenario,
        "wall_s": wall,
        "ipopt_calls": len(calls),
        "iterations": iterations,
        "inertia_corrected_iterations": sum(c["inertia_corrected_iterations"] for c in calls),
        **totals,
        "kkt_solve_s_per_iteration": totals["kkt_solve_s"] / max(iterations, 1),
        "functions_s_per_iteration": totals["functions_s"] / max(iterations, 1),
        "calls": calls,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenarios", nargs="+", default=["tiny", "s1_basket", "s2_trolley"])
    parser.add_argument("--ipopt", nargs="+", type=option, default=[], metavar="KEY=VALUE")
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/ipopt_profile.json"))
    args = parser.parse_args()
    results = []
    for scenario in args.scenarios:
        row = profile(scenario, dict(args.ipopt))
        results.append(row)
        brief = {k: v for k, v in row.items() if k != "calls"}
        print(json.dumps(brief), flush=True)
    record = {"command": " ".join(sys.argv), "ipopt_options": dict(args.ipopt)}
    write_benchmark(args.out, record | {"results": results})


if __name__ == "__main__":
    main()
