"""Time series to MCAP with Foxglove schemas, so Foxglove Studio shows the robot move.

Messages are JSON-encoded with the ``jsonschema`` schema encoding, which Foxglove reads
natively. :func:`write_frame_transforms` writes ``foxglove.FrameTransforms``: one message per
time step holding the pose of every link or object relative to ``world``; with the scene's
geometry (``foxglove.SceneUpdate`` on ``/scene``) Foxglove's 3D panel draws them moving.
"""

from __future__ import annotations

import json
import struct
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
from mcap.exceptions import McapError
from mcap.reader import make_reader
from mcap.writer import Writer

from locoman.artifacts.io import atomic_path
from locoman.errors import ArtifactError

_VEC3 = {"type": "object", "properties": {k: {"type": "number"} for k in "xyz"}}
_QUAT = {"type": "object", "properties": {k: {"type": "number"} for k in "xyzw"}}
_TIME = {
    "type": "object",
    "properties": {"sec": {"type": "integer"}, "nsec": {"type": "integer"}},
}
FRAME_TRANSFORMS_SCHEMA: dict[str, Any] = {
    "title": "foxglove.FrameTransforms",
    "type": "object",
    "properties": {
        "transforms": {
            "type": "array",
            "items": {
                "title": "foxglove.FrameTransform",
                "type": "object",
                "properties": {
                    "timestamp": _TIME,
                    "parent_frame_id": {"type": "string"},
                    "child_frame_id": {"type": "string"},
                    "translation": _VEC3,
                    "rotation": _QUAT,
                },
            },
        }
    },
}


_COLOUR = {"type": "object", "properties": {k: {"type": "number"} for k in "rgba"}}
_POSE = {"type": "object", "properties": {"position": _VEC3, "orientation": _QUAT}}
_PRIMITIVE = {
    "type": "array",
    "items": {
        "type": "object",
        "properties": {
            "pose": _POSE,
            "size": _VEC3,
            "color": _COLOUR,
            "bottom_scale": {"type": "number"},
            "top_scale": {"type": "number"},
        },
    },
}
SCENE_UPDATE_SCHEMA: dict[str, Any] = {
    "title": "foxglove.SceneUpdate",
    "type": "object",
    "properties": {
        "deletions": {"type": "array", "items": {"type": "object"}},
        "entities": {
            "type": "array",
            "items": {
                "title": "foxglove.SceneEntity",
                "type": "object",
                "properties": {
                    "timestamp": _TIME,
                    "frame_id": {"type": "string"},
                    "id": {"type": "string"},
                    "lifetime": _TIME,
                    "frame_locked": {"type": "boolean"},
                    "cubes": _PRIMITIVE,
                    "spheres": _PRIMITIVE,
                    "cylinders": _PRIMITIVE,
                },
            },
        },
    },
}


SCENE_TOPIC = "/scene"


def _stamp(t: float) -> dict[str, int]:
    ns = round(t * 1e9)
    return {"sec": ns // 1_000_000_000, "nsec": ns % 1_000_000_000}


def write_frame_transforms(
    path: str | Path,
    times: np.ndarray,
    frames: Mapping[str, tuple[np.ndarray, np.ndarray]],
    topic: str = "/tf",
    parent: str = "world",
    entities: list[dict[str, Any]] | None = None,
) -> None:
    """Write link/object poses over time as ``foxglove.FrameTransforms`` messages.

    Args:
        path: Output ``.mcap`` file (written atomically).
        times: (T,) time of each step [s], non-decreasing.
        frames: Frame name -> (positions (T, 3) [m], quaternions (T, 4) (w, x, y, z)).
        topic: MCAP topic.
        parent: Parent frame of every transform.
        entities: ``foxglove.SceneEntity`` dicts for ``/scene`` (see :func:`write_mcap`).
    """
    write_mcap(path, times, frames, {}, tf_topic=topic, parent=parent, entities=entities)


def write_mcap(
    path: str | Path,
    times: np.ndarray,
    frames: Mapping[str, tuple[np.ndarray, np.ndarray]],
    signals: Mapping[str, Mapping[str, np.ndarray]],
    tf_topic: str = "/tf",
    parent: str = "world",
    entities: list[dict[str, Any]] | None = None,
) -> None:
    """Write frames as ``foxglove.FrameTransforms``, named signals as JSON topics and the
    scene's geometry as one ``foxglove.SceneUpdate`` on ``/scene``.

    Every signal topic carries one message per time step, an object mapping each signal name
    to its value(s) at that step (a number or a list of numbers), so Foxglove's Plot panel can
    draw e.g. ``/ee.desired[0]`` against ``/ee.actual[0]``.

    Args:
        path: Output ``.mcap`` file (written atomically).
        times: (T,) time of each step [s], non-decreasing.
        frames: Frame name -> (positions (T, 3) [m], quaternions (T, 4) (w, x, y, z)).
        signals: Topic -> signal name -> (T,) or (T, k) values.
        tf_topic: Topic of the frame transforms.
        parent: Parent frame of every transform.
        entities: ``foxglove.SceneEntity`` dicts (:func:`locoman.sim.foxglove.scene_entities`),
            published once at the first step; frame-locked ones move with their frames.
    """
    times = np.asarray(times, dtype=float)
    for name, (pos, quat) in frames.items():
        if pos.shape != (len(times), 3) or quat.shape != (len(times), 4):
            raise ValueError(
                f"frame {name!r}: need positions (T, 3) and quaternions (T, 4) for T = "
                f"{len(times)}, got {pos.shape} and {quat.shape}"
            )
    for topic, named in signals.items():
        for name, values in named.items():
            if len(values) != len(times):
                raise ValueError(f"signal {topic}.{name} has {len(values)} rows, T = {len(times)}")
    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        writer = Writer(fh)
        writer.start(profile="", library="locoman")
        schemas: dict[str, dict[str, Any]] = {}  # topic -> JSON schema (its title names it)
        if frames:
            schemas[tf_topic] = FRAME_TRANSFORMS_SCHEMA
        if entities:
            schemas[SCENE_TOPIC] = SCENE_UPDATE_SCHEMA
        for topic, named in signals.items():
            schemas[topic] = {
                "title": f"locoman{topic.replace('/', '.')}",
                "type": "object",
                "properties": {
                    n: {"type": "array", "items": {"type": "number"}}
                    if np.ndim(v) == 2
                    else {"type": "number"}
                    for n, v in named.items()
                },
            }
        channels: dict[str, int] = {}
        for topic, schema in schemas.items():
            schema_id = writer.register_schema(
                name=schema["title"], encoding="jsonschema", data=json.dumps(schema).encode()
            )
            channels[topic] = writer.register_channel(
                topic=topic, message_encoding="json", schema_id=schema_id
            )
        for k, t in enumerate(times):
            stamp = _stamp(float(t))
            ns = stamp["sec"] * 1_000_000_000 + stamp["nsec"]
            messages: dict[str, Any] = {}
            if frames:
                messages[tf_topic] = {"transforms": _transforms(frames, k, stamp, parent)}
            if entities and k == 0:
                messages[SCENE_TOPIC] = {"deletions": [], "entities": entities}
            for topic, named in signals.items():
                messages[topic] = {n: np.asarray(v[k]).tolist() for n, v in named.items()}
            for topic, message in messages.items():
                writer.add_message(
                    channel_id=channels[topic],
                    log_time=ns,
                    publish_time=ns,
                    sequence=k,
                    data=json.dumps(message, sort_keys=True).encode(),
                )
        writer.finish()


def _transforms(
    frames: Mapping[str, tuple[np.ndarray, np.ndarray]],
    k: int,
    stamp: dict[str, int],
    parent: str,
) -> list[dict[str, Any]]:
    transforms = []
    for name, (pos, quat) in frames.items():
        w, x, y, z = (float(v) for v in quat[k])
        px, py, pz = (float(v) for v in pos[k])
        transforms.append(
            {
                "timestamp": stamp,
                "parent_frame_id": parent,
                "child_frame_id": name,
                "translation": {"x": px, "y": py, "z": pz},
                "rotation": {"x": x, "y": y, "z": z, "w": w},
            }
        )
    return transforms


def read_json_messages(path: str | Path, topic: str) -> list[tuple[str, int, dict[str, Any]]]:
    """All messages on ``topic`` as (schema name, log time [ns], decoded JSON).

    Raises:
        ArtifactError: If the file is missing, truncated or not an MCAP file written here.
    """
    path = Path(path)
    if not path.is_file():
        raise ArtifactError(f"MCAP file {path} is missing; rerun the stage that writes it")
    out = []
    try:
        with open(path, "rb") as fh:
            for schema, _channel, message in make_reader(fh).iter_messages(topics=[topic]):
                name = schema.name if schema is not None else ""
                out.append((name, message.log_time, json.loads(message.data)))
    except (McapError, OSError, struct.error, json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise ArtifactError(
            f"MCAP file {path} is truncated or corrupt ({type(exc).__name__}: {exc}); "
            "rerun the stage that writes it"
        ) from None
    return out
