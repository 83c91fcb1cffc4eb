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
    except (OSError, ValueError, zipfile.BadZipFile, EOFError) as exc:
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
