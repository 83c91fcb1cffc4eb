"""``benchmarks/fatrop_probe.py``: its OCP is in the stage order fatrop detects, and both
solvers find the same optimum of it."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

SCRIPT = Path(__file__).parents[1] / "benchmarks" / "fatrop_probe.py"
spec = importlib.util.spec_from_file_location("fatrop_probe", SCRIPT)
fatrop_probe = importlib.util.module_from_spec(spec)
spec.loader.exec_module(fatrop_probe)


def test_fatrop_and_ipopt_solve_the_probe_to_the_same_optimum():
    costs = {}
    for name in fatrop_probe.SOLVERS:
        plugin, options = fatrop_probe.SOLVERS[name](200)
        opti = fatrop_probe.build(nodes=6, nx=12, nu=16, n_eq=3, n_ineq=3)
        # fatrop's structure detection warns and refuses a Jacobian out of stage order.
        opti.solver(plugin, {"expand": True, "print_time": False, **options})
        opti.solve()
        costs[name] = float(opti.value(opti.f))
    assert costs["fatrop"] == pytest.approx(costs["ipopt_mumps"], rel=1e-6)
