"""What one evaluation of the NLP's derivatives costs, and how much of it is the terms' own.

Usage: python benchmarks/hessian_profile.py [--scenarios tiny s1_basket s2_trolley]
       [--repeats 15] [--out benchmarks/results/hessian_profile.json]

Per scenario (its first problem at the defaults: the TO's broad collision set, before any
round of found pairs) and per Hessian flavour, at the initial guess with seeded multipliers:
the time of one call of each oracle IPOPT calls (``hess_lag``, ``jac_g``, ``grad_f``), and of
the compiled terms' Hessians alone, grouped by term kind, called over every call (the
oracles skip a collision penalty's far calls: since the numeric oracles of
:mod:`locoman.to.nlp.oracles` the terms' column can exceed the oracle's). The difference is the
assembly's: gathering the terms' inputs, scattering their nonzeros, and the chain rule
through the virtual variables (sphere centres, kinematics;
:class:`locoman.to.nlp.ipopt.BlockNLP`). Also the sizes that drive it: the terms'
Hessian nonzeros, the collision-pair calls, and the Hessian's nonzeros over x. Each time is
the minimum of ``--repeats`` calls less the same minimum for a function that only takes the
inputs (Python's conversion of them), so it holds on a busy machine.
"""

from __future__ import annotations

from locoman.kernels import pin_kernels

pin_kernels()  # first, as every stage: NumPy and OpenBLAS choose their kernels when they load

import argparse
import os
import platform
import sys
import time
from collections import defaultdict
from pathlib import Path

import casadi as ca
import numpy as np
from common import write_benchmark

from locoman.config import load_params
from locoman.config.to import HESSIANS
from locoman.to.nlp.ipopt import BlockNLP, parameter_vector
from locoman.to.pipeline import build_optimizer
from locoman.to.problem.loading import load_inputs
from locoman.to.solve.bounds import bounds
from locoman.to.solve.initial_guess import initial_guess
from locoman.to.terms.term import Block


def fastest(function: ca.Function, args: tuple, repeats: int) -> float:
    """The shortest of ``repeats`` calls [s], after one to warm up."""
    function(*args)
    best = np.inf
    for _ in range(repeats):
        tic = time.perf_counter()
        function(*args)
        best = min(best, time.perf_counter() - tic)
    return float(best)


def own_time(outputs: list[ca.MX], inputs: list[ca.MX], args: tuple, repeats: int) -> float:
    """[s] of computing ``outputs`` (summed inside, so nothing large comes back), less the
    conversion of the inputs."""
    total = sum(ca.sum1(ca.sum2(ca.MX(o))) for o in outputs)
    taken = sum(ca.sum1(ca.sum2(i)) for i in inputs)
    run = fastest(ca.Function("run", inputs, [total]), args, repeats)
    base = fastest(ca.Function("base", inputs, [taken]), args, repeats)
    return max(run - base, 0.0)


def profile(scenario: str, repeats: int) -> dict:
    cfg = load_params().solve
    root = Path("data") / scenario
    inputs = load_inputs(root / "scene", root / "contacts", root / "retarget", cfg.contacts)
    optimizer = build_optimizer(inputs, cfg)
    tr = optimizer.transcription
    p = parameter_vector(tr.blocks)
    lo, hi = bounds(
        tr.layout,
        optimizer.inputs,
        optimizer.schedule,
        optimizer.modes,
        cfg.solver,
        cfg.collision.homotopy,
        cfg.schedule.end_lift_m,
    )
    guess = initial_guess(
        tr.layout,
        optimizer.inputs,
        optimizer.schedule,
        optimizer.modes,
        cfg.solver,
        optimizer.robot.mass,
        cfg.collision.homotopy,
    )
    x = np.clip(guess, lo, hi).ravel(order="F")
    lam_g = np.random.default_rng(0).normal(size=tr.rows.size)
    z = tr.extended(x)
    # Every call of a kind, its blocks' calls side by side, as the assembly maps them.
    calls: dict[str, list[Block]] = defaultdict(list)
    defining: dict[str, list[Block]] = defaultdict(list)
    for block in tr.blocks:
        if block.calls:
            (defining if block.defines else calls)[block.term.name].append(block)
    out = {
        "scenario": scenario,
        "nodes": optimizer.schedule.nodes,
        "n_x": tr.n_x,
        "n_y": tr.n_y,
        "n_g": tr.rows.size,
        "collision_pair_calls": len(tr.pairs),
        "flavours": {},
    }
    for hessian in HESSIANS:
        nlp = BlockNLP(tr.n_x, tr.blocks, tr.rows, optimizer.derivatives, hessian, {}, tr.n_y)
        X, P = ca.MX.sym("x", nlp.n_x), ca.MX.sym("p", nlp.n_p)
        lam_f, lam = ca.MX.sym("lam_f"), ca.MX.sym("lam_g", nlp.n_g)
        oracle_args = (x, p, 1.0, lam_g)
        oracles = {
            "hess_lag_s": nlp.oracles["hess_lag"](X, P, lam_f, lam),
            "jac_g_s": nlp.oracles["jac_g"](X, P)[1],
            "grad_f_s": nlp.oracles["grad_f"](X, P)[1],
        }
        row = {
            key: own_time([expr], [X, P, lam_f, lam], oracle_args, repeats)
            for key, expr in oracles.items()
        }
        # The projected flavour calls the exact terms; projecting them is the assembly's.
        flavour = "gauss_newton" if hessian == "gauss_newton" else "exact"
        terms, nonzeros = {}, 0
        for name, parts in calls.items():
            d = optimizer.derivatives[name]
            hr, _ = d.hess_pattern[flavour]
            if not len(hr):
                continue
            term = parts[0].term
            xb = np.vstack([z[b.x] for b in parts]).T
            pb = np.vstack([b.p for b in parts]).T
            lb = np.vstack([lam_g[b.rows] for b in parts]).T
            n = xb.shape[1]
            xs, ps = ca.MX.sym("x", term.nx, n), ca.MX.sym("p", term.np, n)
            ls = ca.MX.sym("l", term.ng, n)
            hnz = d.hess[flavour].map(n)(xs, ps, ls, ca.MX.ones(1, n))
            terms[name] = own_time([hnz], [xs, ps, ls], (xb, pb, lb), repeats)
            nonzeros += n * len(hr)
        # The terms that define y: their values and Jacobians (dy/dx), and in the exact
        # flavour their Hessians (the curvature sum mu nabla^2 F).
        virtual = 0.0
        for name, parts in defining.items():
            d, term = optimizer.derivatives[name], parts[0].term
            n_in = term.nx - term.ng
            xb = np.vstack([np.c_[z[b.x[:, :n_in]], np.zeros((b.calls, term.ng))] for b in parts]).T
            pb = np.vstack([b.p for b in parts]).T
            n = xb.shape[1]
            xs, ps = ca.MX.sym("x", term.nx, n), ca.MX.sym("p", term.np, n)
            ls = ca.MX.sym("l", term.ng, n)
            outputs = [*d.val.map(n)(xs, ps), *d.jac.map(n)(xs, ps)]
            if flavour == "exact":
                outputs.append(d.hess[flavour].map(n)(xs, ps, ls, ca.MX.ones(1, n)))
            lb = np.ones((term.ng, n))
            virtual += own_time(outputs, [xs, ps, ls], (xb, pb, lb), repeats)
        row["terms_s"] = sum(terms.values())
        row["virtual_terms_s"] = virtual
        row["assembly_s"] = row["hess_lag_s"] - row["terms_s"] - virtual
        row["slowest_terms_s"] = dict(sorted(terms.items(), key=lambda kv: -kv[1])[:5])
        row["term_hessian_nonzeros"] = nonzeros
        row["hessian_nonzeros_x"] = nlp.oracles["hess_lag"].sparsity_out(0).nnz()
        out["flavours"][hessian] = row
        print(f"[hessian_profile] {scenario} {hessian}: {row}", flush=True)
    return out


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenarios", nargs="+", default=["tiny", "s1_basket", "s2_trolley"])
    parser.add_argument("--repeats", type=int, default=15)
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/hessian_profile.json"))
    args = parser.parse_args(argv)
    results = [profile(s, args.repeats) for s in args.scenarios]
    write_benchmark(
        args.out,
        {
            "command": "benchmarks/hessian_profile.py",
            "machine": {
                "cpus": os.cpu_count(),
                "platform": platform.platform(),
                "load_average_1min": os.getloadavg()[0],
            },
            "results": results,
        },
    )
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
