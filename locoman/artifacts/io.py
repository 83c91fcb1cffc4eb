"""Atomic, deterministic, pickle-free reading and writing of artifacts.

Every write goes to a temporary file in the destination folder and is renamed into place, so
an interrupted stage never leaves a half-written output. ``.npz`` files are written with fixed
zip timestamps so the same arrays give the same bytes.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import tempfile
import zipfile
import zlib
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from locoman.artifacts.schema import ArtifactSchema

_ZIP_EPOCH = (1980, 1, 1, 0, 0, 0)
_META_KEY = "__artifact__"


@contextlib.contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; rename it onto ``path`` on success."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    os.close(fd)
    try:
        yield Path(tmp)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def write_bytes_atomic(path: str | Path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically."""
    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        fh.write(data)
        fh.flush()
        os.fsync(fh.fileno())


def write_text_atomic(path: str | Path, text: str) -> None:
    """Write UTF-8 ``text`` to ``path`` atomically."""
    write_bytes_atomic(path, text.encode("utf-8"))


def write_json_atomic(path: str | Path, data: Any) -> None:
    """Write JSON (sorted keys, 2-space indent) atomically; used for metrics and plots."""
    write_text_atomic(path, json.dumps(data, indent=2, sort_keys=True, allow_nan=False) + "\n")


# Keys of wall-clock figures, wherever they sit in a stage's metrics: they depend on the
# machine and its load, so they go to timing.json, which DVC does not track, and not to the
# metrics.json that `dvc metrics`/`dvc exp show` compare.
WALL_CLOCK_KEYS = frozenset(
    {
        "seconds",
        "seconds_per_subtask",
        "seconds_per_keyframe",
        "keyframes_per_second",
        "build_time_s",
        "solve_time_s",
        "function_time_s",
        "gmr_seconds",
        "kmp_seconds",
        "fit_seconds",
        "predict_seconds_26s_at_1khz",
        "hqp_step_median_s",
        "hqp_step_p99_s",
        "realtime_factor",
        "qp_time_median_ms",
        "qp_time_p99_ms",
    }
)


def split_wall_clock(data: Any) -> tuple[Any, Any]:
    """(science, timing): ``data`` without the :data:`WALL_CLOCK_KEYS`, and those keys alone
    with the dicts and lists that lead to them (None where there are none)."""
    if isinstance(data, dict):
        science, timing = {}, {}
        for key, value in data.items():
            if key in WALL_CLOCK_KEYS:
                timing[key] = value
                continue
            science[key], inner = split_wall_clock(value)
            if inner is not None:
                timing[key] = inner
        return science, timing or None
    if isinstance(data, list):
        pairs = [split_wall_clock(v) for v in data]
        timings = [t for _, t in pairs]
        return [s for s, _ in pairs], timings if any(t is not None for t in timings) else None
    return data, None


# Top-level keys of per-item detail (a row per subtask): they go to details.json, so that
# `dvc metrics show` and `dvc exp show` compare the headline figures, not hundreds of columns.
DETAIL_KEYS = frozenset({"per_subtask", "deepest_penetration"})
DETAILS_FILE = "details.json"


def write_metrics(out_dir: str | Path, metrics: Mapping[str, Any]) -> None:
    """A stage's figures: ``metrics.json`` the results, ``details.json`` beside it the
    per-item rows (:data:`DETAIL_KEYS`, when there are any), ``timing.json`` the wall-clock
    figures (:func:`split_wall_clock`), each atomically."""
    science, timing = split_wall_clock(dict(metrics))
    details = {k: science.pop(k) for k in sorted(DETAIL_KEYS & set(science))}
    out = Path(out_dir)
    write_json_atomic(out / "metrics.json", science)
    if details:
        write_json_atomic(out / DETAILS_FILE, details)
    write_json_atomic(out / "timing.json", timing or {})


def _meta(schema: ArtifactSchema) -> dict[str, Any]:
    return {"name": schema.name, "version": schema.version, "producer": schema.producer}


def write_npz(path: str | Path, schema: ArtifactSchema, arrays: Mapping[str, Any]) -> None:
    """Check ``arrays`` against ``schema`` and write them as a deterministic ``.npz``."""
    arrays = {k: np.asarray(v) for k, v in arrays.items()}
    schema.check_arrays(arrays, path)
    arrays[_META_KEY] = np.asarray(json.dumps(_meta(schema), sort_keys=True))
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        for key in sorted(arrays):
            info = zipfile.ZipInfo(f"{key}.npy", date_time=_ZIP_EPOCH)
            info.compress_type = zipfile.ZIP_DEFLATED
            member = io.BytesIO()
            np.lib.format.write_array(member, arrays[key], allow_pickle=False)
            zf.writestr(info, member.getvalue())
    write_bytes_atomic(path, buffer.getvalue())


def read_npz(path: str | Path, schema: ArtifactSchema) -> dict[str, np.ndarray]:
    """Read an ``.npz`` artifact and check it against ``schema`` (never unpickles)."""
    path = Path(path)
    if not path.is_file():
        raise schema.error(path, "file is missing")
    try:
        with np.load(path, allow_pickle=False) as npz:
            arrays = {k: npz[k] for k in npz.files}
    except (OSError, ValueError, zipfile.BadZipFile, EOFError, zlib.error) as exc:
        raise schema.error(path, f"file is corrupt ({type(exc).__name__}: {exc})") from None
    _check_meta(schema, path, arrays.pop(_META_KEY, None))
    schema.check_arrays(arrays, path)
    return arrays


def write_json(path: str | Path, schema: ArtifactSchema, data: Mapping[str, Any]) -> None:
    """Check ``data`` against ``schema`` and write it as JSON with an artifact header."""
    schema.check_json(data, path)
    write_json_atomic(path, {_META_KEY: _meta(schema), **data})


def read_json(path: str | Path, schema: ArtifactSchema) -> dict[str, Any]:
    """Read a JSON artifact and check it against ``schema``."""
    path = Path(path)
    if not path.is_file():
        raise schema.error(path, "file is missing")
    try:
        data = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise schema.error(path, f"file is corrupt ({type(exc).__name__}: {exc})") from None
    if not isinstance(data, dict):
        raise schema.error(path, "file does not hold a JSON object")
    meta = data.pop(_META_KEY, None)
    _check_meta(schema, path, None if meta is None else np.asarray(json.dumps(meta)))
    schema.check_json(data, path)
    return data


def _check_meta(schema: ArtifactSchema, path: Path, raw: np.ndarray | None) -> None:
    if raw is None:
        raise schema.error(path, "file has no artifact header; it was not written by locoman")
    try:
        meta = json.loads(str(raw))
    except json.JSONDecodeError:
        raise schema.error(path, "artifact header is corrupt") from None
    if meta.get("name") != schema.name:
        raise schema.error(path, f"file holds artifact {meta.get('name')!r}")
    if meta.get("version") != schema.version:
        raise schema.error(
            path, f"file has schema version {meta.get('version')}, this code reads {schema.version}"
        )


def write_png(path: str | Path, rgb: np.ndarray) -> None:
    """Write an RGB uint8 image (H, W, 3) as PNG, atomically and deterministically."""
    import cv2

    rgb = np.asarray(rgb)
    if rgb.dtype != np.uint8 or rgb.ndim != 3 or rgb.shape[2] != 3:
        raise ValueError(f"write_png needs an (H, W, 3) uint8 image, got {rgb.shape} {rgb.dtype}")
    ok, buf = cv2.imencode(".png", np.ascontiguousarray(rgb[:, :, ::-1]))
    if not ok:
        raise OSError(f"PNG encoding failed for {path}")
    write_bytes_atomic(path, buf.tobytes())


def write_figure(path: str | Path, fig: Any, dpi: int = 110) -> None:
    """Write a matplotlib ``Figure`` as PNG, atomically and without the version stamp (so
    the same data give the same bytes)."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, metadata={"Software": None})
    write_bytes_atomic(path, buf.getvalue())
