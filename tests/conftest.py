"""Shared fixtures. MuJoCo renders off-screen on the CPU (EGL through Mesa)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from locoman.kernels import pin_kernels

# As every stage: the kernels the artifacts were made with, before a test loads NumPy.
pin_kernels()
os.environ.setdefault("MUJOCO_GL", "egl")
os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

REPO = Path(__file__).resolve().parents[1]
# The benchmark scripts import their shared helpers as `common`, as `python benchmarks/x.py`
# finds them beside the script; the tests that load a script need the same.
sys.path.insert(0, str(REPO / "benchmarks"))

# A guard against a hung stage, not a speed check: a loaded 2-core machine must pass.
CLI_TIMEOUT_S = 3600


# The files that take minutes, longest first. `make test` gives each pytest-xdist worker whole
# files in collection order (`--dist loadfile --no-loadscope-reorder`): these start at once,
# one per worker, and the short files fill in behind them. In xdist's default order (files
# with the most tests first) the end-to-end file started last and ran alone on one core.
SLOW_FILES = ("test_pipeline_e2e.py", "test_dvc_experiments.py", "test_mm_stages.py")


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    def rank(item: pytest.Item) -> int:
        name = item.path.name
        return SLOW_FILES.index(name) if name in SLOW_FILES else len(SLOW_FILES)

    items.sort(key=rank)  # stable: each file's tests keep their order


@pytest.fixture(scope="session")
def repo() -> Path:
    return REPO


@pytest.fixture(scope="session")
def params():
    from locoman.config import load_params

    return load_params(REPO / "params.yaml")


@pytest.fixture(scope="session")
def tiny_scene(params, tmp_path_factory) -> Path:
    """tiny's scene stage outputs (scene.xml, objects.json, plan.json, initial state),
    written here: a fresh clone has no data/ outputs (they live in DVC's cache)."""
    from locoman.scene.builder import build_scene
    from locoman.scene.io import write_scene

    out = tmp_path_factory.mktemp("tiny_scene")
    write_scene(out, build_scene("tiny", params.scenarios["tiny"], (64, 48)))
    return out


def _run_cli(
    args: list[str], cwd: Path, extra_env: dict[str, str] | None = None
) -> subprocess.CompletedProcess[str]:
    from locoman.to.nlp.compile import CACHE_ENV

    env = dict(os.environ) | dict(extra_env or {})
    env["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{env['PATH']}"
    # The copy's TO compiles into (and reuses) the checkout's cache: a later run with the
    # same compiler and flags builds nothing.
    env.setdefault(CACHE_ENV, str(REPO / ".cache" / "casadi"))
    return subprocess.run(
        args, cwd=cwd, env=env, capture_output=True, text=True, timeout=CLI_TIMEOUT_S
    )


@pytest.fixture(scope="session")
def run_cli():
    """``run_cli(args, cwd[, extra_env])``: a command in a checkout copy, this interpreter's
    environment first on PATH, its output captured."""
    return _run_cli


_NOT_COPIED = ("data/", "benchmarks/results/", "docs/gallery/")


@pytest.fixture(scope="module")
def workdir(repo, tmp_path_factory) -> Path:
    """A fresh checkout-like copy per test file: tracked and unignored files only, no data
    outputs, a git repository of its own (DVC needs one).

    Left out besides ``data/``: what no stage reads. ``dvc.lock`` describes outputs the copy
    has not got, so a stage runs with or without it, but DVC parses its 130 kB with
    pure-Python YAML about twice per command (3-4 s each on a slow 2-core instance); the
    committed benchmark results and gallery (1 100 files, 12 MB) would only lengthen
    every ``dvc exp run``'s copy of the workspace."""
    files = subprocess.run(
        ["git", "ls-files", "--cached", "--others", "--exclude-standard"],
        cwd=repo,
        capture_output=True,
        text=True,
        check=True,
    ).stdout.split()
    dst = tmp_path_factory.mktemp("pipeline")
    for rel in files:
        src = repo / rel
        if src.is_file() and not rel.startswith(_NOT_COPIED) and rel != "dvc.lock":
            (dst / rel).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, dst / rel)
    assert _run_cli(["git", "init", "-q"], dst).returncode == 0
    return dst
