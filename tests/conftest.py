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
