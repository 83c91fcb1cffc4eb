"""The scene stage's artifacts: MJCF, object table, plan and initial state."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from locoman.artifacts import ArtifactSchema, Field, read_json, read_npz, write_json, write_npz
from locoman.artifacts.io import write_text_atomic
from locoman.errors import ArtifactError
from locoman.scene import assets
from locoman.scene.builder import Scene

MJCF_FILE = "scene.xml"
OBJECTS_FILE = "objects.json"
PLAN_FILE = "plan.json"
STATE_FILE = "initial_state.npz"

OBJECTS = ArtifactSchema(
    "scene.objects",
    1,
    "scene",
    (
        Field(
            "objects",
            "object",
            doc="name -> kind, size_m, pos_m, quat_wxyz, mass_kg, movable, rgba, "
            "friction, primitives, contact_patches (object frame, [m])",
            items=(
                ("kind", "str"),
                ("size_m", "list"),
                ("pos_m", "list"),
                ("yaw_rad", "number"),
                ("quat_wxyz", "list"),
                ("mass_kg", "number?"),
                ("movable", "bool"),
                ("rgba", "list"),
                ("friction", "number"),
                ("primitives", "list"),
                ("contact_patches", "list"),
            ),
        ),
    ),
)
PLAN = ArtifactSchema(
    "scene.plan",
    1,
    "scene",
    (
        Field("robot", "str", doc="g1 or mobile_manipulator"),
        Field("description", "str"),
        Field(
            "subtasks",
            "list",
            doc="ordered: prompt, predicate, object, contacts, target",
            items=(
                ("index", "int"),
                ("prompt", "str"),
                ("predicate", "str"),
                ("object", "str"),
                ("contacts", "list"),
                ("target", "object?"),
            ),
        ),
    ),
)
STATE = ArtifactSchema(
    "scene.state",
    1,
    "scene",
    (
        Field(
            "qpos",
            "float64",
            ("nq",),
            "mixed",
            "MuJoCo qpos of keyframe 'home' ([m], [rad], quaternions w, x, y, z)",
        ),
        Field("body_names", "str", ("nbody",), "-", "MuJoCo body names"),
        Field("body_pos", "float64", ("nbody", 3), "m", "world position of each body"),
        Field("body_quat_wxyz", "float64", ("nbody", 4), "-", "world orientation of each body"),
    ),
)


def write_scene(out_dir: str | Path, scene: Scene) -> tuple[mujoco.MjModel, np.ndarray]:
    """Write MJCF, object table, plan and initial state; return the model and home ``qpos``.

    The MJCF's ``meshdir`` is made relative to ``out_dir``, so the file has no absolute path
    and opens in any MuJoCo viewer from a checkout with its ``.venv``.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    model = scene.spec.compile()
    qpos = model.key("home").qpos.copy()
    absolute = f'meshdir="{assets.robots_dir()}"'
    xml = scene.spec.to_xml()
    if absolute not in xml:
        raise ArtifactError(f"MJCF of {scene.spec.modelname!r} lacks {absolute}; cannot relocate")
    relative = os.path.relpath(assets.robots_dir(), out.resolve())
    write_text_atomic(out / MJCF_FILE, xml.replace(absolute, f'meshdir="{relative}"'))
    write_json(out / OBJECTS_FILE, OBJECTS, {"objects": scene.objects})
    write_json(out / PLAN_FILE, PLAN, scene.plan)
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_kinematics(model, data)
    write_npz(
        out / STATE_FILE,
        STATE,
        {
            "qpos": qpos,
            "body_names": np.array([model.body(i).name for i in range(model.nbody)]),
            "body_pos": data.xpos.copy(),
            "body_quat_wxyz": data.xquat.copy(),
        },
    )
    return model, qpos


def load_scene_model(scene_dir: str | Path) -> mujoco.MjModel:
    """Compile the MJCF written by the scene stage."""
    path = Path(scene_dir) / MJCF_FILE
    if not path.is_file():
        raise ArtifactError(
            f"scene MJCF {path} is missing (produced by stage 'scene'; "
            "rerun it with `dvc repro scene`)"
        )
    try:
        return mujoco.MjModel.from_xml_path(str(path))
    except ValueError as exc:
        raise ArtifactError(f"scene MJCF {path} does not compile: {exc}") from None


def load_objects(scene_dir: str | Path) -> dict[str, Any]:
    """The object table written by the scene stage."""
    return read_json(Path(scene_dir) / OBJECTS_FILE, OBJECTS)["objects"]


def load_plan(scene_dir: str | Path) -> dict[str, Any]:
    """The task plan written by the scene stage."""
    return read_json(Path(scene_dir) / PLAN_FILE, PLAN)


def load_state(scene_dir: str | Path) -> dict[str, np.ndarray]:
    """The initial state written by the scene stage."""
    return read_npz(Path(scene_dir) / STATE_FILE, STATE)
