"""The CPU kernels are pinned before the numerical libraries load (locoman/kernels.py)."""

from __future__ import annotations

import ast
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from locoman.kernels import cpu_flags, kernel_pins, pin_kernels

REPO = Path(__file__).resolve().parents[1]
NUMERICAL = {"numpy", "scipy", "cv2", "mujoco", "casadi", "pinocchio", "placo", "sklearn"}


def test_pins_keep_an_avx512_cpu_at_avx2_kernels():
    pins = kernel_pins("x86_64", {"avx2", "fma", "avx512f"})
    assert pins["OPENBLAS_CORETYPE"] == "Haswell"
    assert "AVX512_SKX" in pins["NPY_DISABLE_CPU_FEATURES"].split(",")
    # OpenCV names its groups with a hyphen and warns about any group the CPU lacks: only
    # those whose every flag the CPU has are disabled, none without AVX-512.
    assert "OPENCV_CPU_DISABLE" not in pins
    skx = {"avx2", "fma", "avx512f", "avx512cd", "avx512bw", "avx512dq", "avx512vl"}
    assert kernel_pins("x86_64", skx)["OPENCV_CPU_DISABLE"].split(",") == [
        "AVX512-COMMON",
        "AVX512-SKX",
    ]
    assert "OPENCV_CPU_DISABLE" not in kernel_pins("x86_64", {"avx2", "fma"})


@pytest.mark.skipif(
    "OPENCV_CPU_DISABLE" not in kernel_pins("x86_64", cpu_flags()),
    reason="this CPU has no AVX-512 group of OpenCV's: nothing to disable",
)
def test_opencv_takes_the_pin_without_a_warning():
    """The pin reaches OpenCV's dispatcher (its AVX-512 group marked ``?``: disabled) and
    OpenCV prints nothing about it (it printed a line per unknown name into every log)."""
    code = (
        "from locoman.kernels import pin_kernels\npin_kernels()\n"
        "import cv2\nprint(cv2.getCPUFeaturesLine())"
    )
    pins = kernel_pins("x86_64", cpu_flags())
    env = {k: v for k, v in os.environ.items() if k not in pins}
    out = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True
    )
    assert "OPENCV" not in out.stderr
    assert "AVX512-SKX?" in out.stdout


@pytest.mark.parametrize(
    ("machine", "flags"), [("x86_64", {"avx", "sse4_2"}), ("aarch64", {"asimd"}), ("x86_64", set())]
)
def test_no_pin_where_the_avx2_kernel_would_be_an_illegal_instruction(machine, flags):
    assert kernel_pins(machine, flags) == {}


def test_a_variable_the_user_set_is_kept(monkeypatch):
    monkeypatch.setattr("locoman.kernels.cpu_flags", lambda: {"avx2", "fma", "avx512f"})
    monkeypatch.setattr("platform.machine", lambda: "x86_64")
    env = {"OPENBLAS_CORETYPE": "Zen"}
    added = pin_kernels(env)
    assert env["OPENBLAS_CORETYPE"] == "Zen" and "OPENBLAS_CORETYPE" not in added
    assert env["NPY_DISABLE_CPU_FEATURES"] == added["NPY_DISABLE_CPU_FEATURES"]


def test_cpu_flags_read_proc_cpuinfo(tmp_path):
    info = tmp_path / "cpuinfo"
    info.write_text("processor\t: 0\nflags\t\t: fpu sse2 avx2 fma\nbugs\t: x\n")
    assert cpu_flags(info) == {"fpu", "sse2", "avx2", "fma"}
    assert cpu_flags(tmp_path / "missing") == set()


@pytest.mark.skipif(
    not kernel_pins("x86_64", cpu_flags()), reason="this CPU has no AVX2: nothing is pinned"
)
def test_pinning_first_loads_openblas_with_the_pinned_kernel():
    code = (
        "from locoman.kernels import pin_kernels\npin_kernels()\n"
        "import numpy, scipy.linalg, json, os\n"
        "from threadpoolctl import threadpool_info\n"
        "print(json.dumps([os.environ.get('OPENBLAS_CORETYPE'),"
        " [i.get('architecture') for i in threadpool_info() if i['internal_api'] == 'openblas']]))"
    )
    pins = kernel_pins("x86_64", {"avx2", "fma", "avx512f"})
    env = {k: v for k, v in os.environ.items() if k not in pins}
    out = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True
    )
    coretype, architectures = json.loads(out.stdout)
    assert coretype == "Haswell"
    assert len(architectures) >= 2 and set(architectures) == {"Haswell"}  # NumPy's, SciPy's


def test_importing_locoman_changes_no_process_wide_setting():
    """issue 49: importing the library (and building the NLP) leaves the process as it was;
    only an entry point pins."""
    # The libraries' own imports set some (scikit-learn KMP_DUPLICATE_LIB_OK, CasADi
    # LD_LIBRARY_PATH): they are loaded first, then locoman must add nothing.
    code = (
        "import os, json\n"
        "import numpy, scipy, sklearn, casadi, pinocchio, mujoco, cv2, placo, hydra\n"
        "before = dict(os.environ)\n"
        "import locoman, locoman.stage, locoman.to.solve.optimizer, locoman.grid.launch\n"
        "import locoman.sim.evaluate, locoman.contact.semantic, locoman.kmp.fit\n"
        "import locoman.hqp.replay, locoman.retarget\n"
        "print(json.dumps(sorted(set(os.environ.items()) ^ set(before.items()))))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert json.loads(out.stdout) == []


@pytest.mark.parametrize("script", sorted((REPO / "stages").glob("*.py")), ids=lambda p: p.name)
def test_every_stage_pins_the_kernels_before_a_numerical_library(script):
    """A stage that loaded NumPy first would run with the CPU's own kernels: the first
    statement after the module's docstring and ``__future__`` import is the pin."""
    body = [
        node
        for node in ast.parse(script.read_text()).body
        if not (isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant))
        and not (isinstance(node, ast.ImportFrom) and node.module == "__future__")
    ]
    first, call = body[0], body[1]
    assert isinstance(first, ast.ImportFrom) and first.module == "locoman.kernels", script
    assert isinstance(call, ast.Expr) and ast.unparse(call) == "pin_kernels()", script
