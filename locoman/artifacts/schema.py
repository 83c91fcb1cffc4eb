"""Artifact schemas: name, version, producing stage and typed fields.

A schema is checked on write and on read. Shapes may use symbols (``"N"``): every field that
uses the same symbol must agree on its size within one artifact.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

import numpy as np

from locoman.errors import ArtifactError


@dataclasses.dataclass(frozen=True)
class Field:
    """One field of an artifact.

    Attributes:
        name: Key in the file.
        dtype: NumPy dtype name for arrays (``float64``, ``int64``, ``bool``, ``str``), or a
            JSON type (``object``, ``list``, ``str``, ``number``) for JSON artifacts.
        shape: Array shape; ints are fixed sizes, strings are symbols. Empty for JSON fields.
        unit: SI unit, ``-`` when dimensionless, ``mixed`` when the doc says per entry.
        doc: What the field holds.
        items: For a JSON ``object`` (each value) or ``list`` (each element): the keys every
            entry must hold, with their JSON types (a ``?`` suffix allows null).
        nan_allowed: A float field in which NaN means "none" (a keypoint not seen, no
            goal); every other float field must be finite.
        values: What the entries must satisfy beyond finiteness: ``increasing`` (strictly,
            along the first axis: times), ``unit_quaternion`` (rows of norm 1), or
            ``index:<symbol>`` (integers in [0, symbol), or -1 where the field says so with
            ``index:<symbol>|-1``).
    """

    name: str
    dtype: str
    shape: tuple[int | str, ...] = ()
    unit: str = "-"
    doc: str = ""
    items: tuple[tuple[str, str], ...] = ()
    nan_allowed: bool = False
    values: str = ""


@dataclasses.dataclass(frozen=True)
class ArtifactSchema:
    """A typed artifact.

    Attributes:
        name: e.g. ``scene.objects``.
        version: Bumped on every incompatible change.
        producer: The DVC stage that writes it (named in errors so users know what to rerun).
        fields: Its fields.
    """

    name: str
    version: int
    producer: str
    fields: tuple[Field, ...]

    def error(self, path: Any, what: str) -> ArtifactError:
        """An error naming this artifact, its file and the stage that produces it."""
        return ArtifactError(
            f"artifact {self.name!r} v{self.version} at {path}: {what} "
            f"(produced by stage {self.producer!r}; rerun it with `dvc repro {self.producer}`)"
        )

    def check_arrays(self, arrays: Mapping[str, np.ndarray], path: Any) -> None:
        """Check presence, dtype and shape of every field; no extra keys allowed."""
        extra = sorted(set(arrays) - {f.name for f in self.fields})
        if extra:
            raise self.error(path, f"unexpected fields {extra}")
        sizes: dict[str, int] = {}
        for f in self.fields:
            if f.name not in arrays:
                raise self.error(path, f"field {f.name!r} is missing")
            arr = np.asarray(arrays[f.name])
            if not _dtype_ok(arr.dtype, f.dtype):
                raise self.error(
                    path, f"field {f.name!r} has dtype {arr.dtype}, expected {f.dtype}"
                )
            if arr.ndim != len(f.shape):
                raise self.error(
                    path, f"field {f.name!r} has shape {arr.shape}, expected {f.shape}"
                )
            for got, want in zip(arr.shape, f.shape, strict=True):
                if isinstance(want, int) and got != want:
                    raise self.error(
                        path, f"field {f.name!r} has shape {arr.shape}, expected {f.shape}"
                    )
                if isinstance(want, str) and sizes.setdefault(want, got) != got:
                    raise self.error(
                        path,
                        f"field {f.name!r} has {want} = {got}, other fields have {sizes[want]}",
                    )
        for f in self.fields:
            self._check_values(f, np.asarray(arrays[f.name]), sizes, path)

    def _check_values(self, f: Field, arr: np.ndarray, sizes: dict[str, int], path: Any) -> None:
        """A float field's entries are finite (NaN too where it means "none"): a NaN in a
        keyframe once surfaced three stages later as a raw ValueError. Then ``f.values``."""
        if arr.size == 0:
            return
        bad, what = np.zeros(arr.shape, bool), ""
        if arr.dtype.kind == "f":
            bad, what = ~np.isfinite(arr), "not finite"
            if f.nan_allowed:
                bad &= ~np.isnan(arr)
        if not bad.any() and f.values == "increasing":
            bad, what = np.zeros(arr.shape, bool), "not increasing"
            bad[1:] = np.diff(arr, axis=0) <= 0
        elif not bad.any() and f.values == "unit_quaternion":
            # float32 round trips and renormalised integrations stay far inside 1e-6.
            norm = np.linalg.norm(arr, axis=-1, keepdims=True)
            bad, what = np.broadcast_to(np.abs(norm - 1.0) > 1e-6, arr.shape), "not of unit norm"
        elif not bad.any() and f.values.startswith("index:"):
            symbol, _, none = f.values.removeprefix("index:").partition("|")
            low = int(none) if none else 0
            bad = (arr < low) | (arr >= sizes[symbol])
            what = f"outside [{low}, {symbol} = {sizes[symbol]})"
        if bad.any():
            index = tuple(int(i) for i in np.argwhere(bad)[0])
            where = index if arr.ndim else "()"
            raise self.error(path, f"field {f.name!r} is {what} at {where}: {arr[index]} ({f.doc})")

    def check_json(self, data: Mapping[str, Any], path: Any) -> None:
        """Check presence and JSON type of every top-level field; no extra keys allowed."""
        extra = sorted(set(data) - {f.name for f in self.fields})
        if extra:
            raise self.error(path, f"unexpected fields {extra}")
        for f in self.fields:
            if f.name not in data:
                raise self.error(path, f"field {f.name!r} is missing")
            if not _json_type_ok(data[f.name], f.dtype):
                got = type(data[f.name]).__name__
                raise self.error(path, f"field {f.name!r} is a {got}, expected {f.dtype}")
            if not f.items:
                continue
            value = data[f.name]
            entries = value.items() if isinstance(value, dict) else enumerate(value)
            for key, entry in entries:
                where = f"field {f.name!r}, entry {key!r}"
                if not isinstance(entry, dict):
                    raise self.error(path, f"{where} is a {type(entry).__name__}, expected object")
                for item, dtype in f.items:
                    if item not in entry:
                        raise self.error(path, f"{where}: key {item!r} is missing")
                    if not _json_type_ok(entry[item], dtype):
                        got = type(entry[item]).__name__
                        raise self.error(path, f"{where}: {item!r} is a {got}, expected {dtype}")


_JSON_TYPES = {"object": dict, "list": list, "str": str, "bool": bool, "int": int}


def _json_type_ok(value: Any, dtype: str) -> bool:
    """``value`` has JSON type ``dtype`` (``number``: int or float, not bool; a ``?``
    suffix: or null)."""
    if dtype.endswith("?"):
        return value is None or _json_type_ok(value, dtype[:-1])
    if isinstance(value, bool):
        return dtype == "bool"
    if dtype == "number":
        return isinstance(value, int | float)
    return isinstance(value, _JSON_TYPES[dtype])


def _dtype_ok(got: np.dtype, want: str) -> bool:
    if want == "str":
        return got.kind == "U"
    if want == "bool":
        return got.kind == "b"
    if want.startswith("int"):
        return got.kind in "iu"
    if want.startswith("float"):
        return got.kind == "f"
    return got == np.dtype(want)
