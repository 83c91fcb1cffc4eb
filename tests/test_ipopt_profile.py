"""``benchmarks/ipopt_profile.py``: IPOPT's report split per call, and the options it adds."""

from __future__ import annotations

import argparse
import importlib.util
from pathlib import Path

import pytest

SCRIPT = Path(__file__).parents[1] / "benchmarks" / "ipopt_profile.py"
spec = importlib.util.spec_from_file_location("ipopt_profile", SCRIPT)
ipopt_profile = importlib.util.module_from_spec(spec)
spec.loader.exec_module(ipopt_profile)

# Two IPOPT calls as IPOPT 3.14 prints them (print_level 5, print_timing_statistics: the
# timers before the EXIT line); the second's iterations 1 and 2 were inertia-corrected
# (lg(rg) is not "-").
LOG = """
iter    objective    inf_pr   inf_du lg(mu)  ||d||  lg(rg) alpha_du alpha_pr  ls
   0  1.0000000e+00 1.00e+00 1.00e+00  -1.0 0.00e+00    -  0.00e+00 0.00e+00   0
   1  5.0000000e-01 1.00e-01 1.00e-01  -1.0 1.00e+00    -  1.00e+00 1.00e+00f  1
OverallAlgorithm....................:      2.000 (sys:      0.010 wall:      2.500)
 Function Evaluations...............:      1.000 (sys:      0.000 wall:      1.000)
  Lagrangian Hessian................:      0.400 (sys:      0.000 wall:      0.400)
 PDSystemSolverTotal................:      0.800 (sys:      0.000 wall:      0.900)
EXIT: Optimal Solution Found.
iter    objective    inf_pr   inf_du lg(mu)  ||d||  lg(rg) alpha_du alpha_pr  ls
   0  5.0000000e-01 1.00e-01 1.00e-01  -4.0 0.00e+00    -  0.00e+00 0.00e+00   0
   1  4.0000000e-01 1.00e-02 1.00e-02  -4.0 1.00e-01   2.0 1.00e+00 1.00e+00h  1
   2  3.9000000e-01 1.00e-03 1.00e-03  -4.0 1.00e-02   1.5 1.00e+00 1.00e+00h  1
   3r 3.8000000e-01 1.00e-04 1.00e-04  -4.0 1.00e-03    -  1.00e+00 1.00e+00f  1
OverallAlgorithm....................:      1.000 (sys:      0.000 wall:      1.200)
 PDSystemSolverTotal................:      0.500 (sys:      0.000 wall:      0.600)
EXIT: Solved To Acceptable Level.
"""


def test_each_ipopt_call_gets_its_wall_timers_and_iterations():
    first, second = ipopt_profile.parse(LOG)
    assert first["exit"] == "Optimal Solution Found."
    assert (first["iterations"], first["inertia_corrected_iterations"]) == (1, 0)
    assert first["total_s"] == pytest.approx(2.5)
    assert first["kkt_solve_s"] == pytest.approx(0.9)
    assert first["other_s"] == pytest.approx(2.5 - 1.0 - 0.9)
    assert (second["iterations"], second["inertia_corrected_iterations"]) == (3, 2)
    assert second["other_s"] == pytest.approx(1.2 - 0.6)


@pytest.mark.parametrize(
    ("text", "parsed"),
    [
        ("mumps_pivot_order=5", ("mumps_pivot_order", 5)),
        ("mumps_pivtol=1e-8", ("mumps_pivtol", 1e-8)),
        ("mu_oracle=loqo", ("mu_oracle", "loqo")),
    ],
)
def test_an_ipopt_option_keeps_the_type_ipopt_takes(text, parsed):
    key, value = ipopt_profile.option(text)
    assert (key, value) == parsed
    assert type(value) is type(parsed[1])


def test_an_option_without_a_value_is_refused_with_the_syntax():
    with pytest.raises(argparse.ArgumentTypeError, match="KEY=VALUE"):
        ipopt_profile.option("mumps_pivot_order")
