"""Shared fixtures. MuJoCo renders off-screen on the CPU (EGL through Mesa)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

os.environ.setdefault("MUJOCO_GL", "egl")
os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

REPO = Path(__file__).resolve().parents[1]


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
