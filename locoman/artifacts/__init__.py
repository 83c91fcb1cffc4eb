"""Typed artifacts: schemas, atomic deterministic I/O, MCAP with Foxglove schemas."""

from locoman.artifacts.io import (
    read_json,
    read_npz,
    write_figure,
    write_json,
    write_json_atomic,
    write_metrics,
    write_npz,
    write_png,
    write_text_atomic,
)
from locoman.artifacts.schema import ArtifactSchema, Field

__all__ = [
    "ArtifactSchema",
    "Field",
    "read_json",
    "read_npz",
    "write_figure",
    "write_json",
    "write_json_atomic",
    "write_metrics",
    "write_npz",
    "write_png",
    "write_text_atomic",
]
