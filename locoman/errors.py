"""Exception hierarchy: every error says what went wrong and what to do about it."""

from __future__ import annotations


class LocomanError(Exception):
    """Base class of every error raised on purpose by locoman."""


class ConfigError(LocomanError):
    """A configuration key is unknown, missing, of the wrong type or out of range."""


class ArtifactError(LocomanError):
    """An artifact is missing, corrupt, of the wrong schema version or has a wrong field."""


class ModelError(LocomanError):
    """A robot or object model cannot be built (missing package file, bad geometry)."""


class SceneError(LocomanError):
    """A scenario is infeasible as configured (penetrating bodies, robot not standing, ...)."""


class DemoError(LocomanError):
    """A demonstration file is malformed (bad header, a missing or non-numeric value, ...)."""


class InputError(LocomanError):
    """A user's input file (an image, its annotations, its depth) is missing or malformed."""


class SolverError(LocomanError):
    """A numerical solve failed (a QP reported infeasibility, a factorisation broke down)."""


class SetupError(LocomanError):
    """The Python environment lacks what the project needs (a package it depends on)."""


class SolverBuildError(SolverError):
    """The NLP could not be built or compiled."""
