"""The scene stage's artifacts: MJCF, object table, plan and initial state."""

from __future__ import annotations

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
# How scene.xml names its meshes' folder; resolved when it is loaded.
MESHDIR = "package://example-robot-data/robots/"

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
        Field(
            "body_quat_wxyz",
            "float64",
            ("nbody", 4),
            "-",
            "world orientation of each body",
            values="unit_quaternion",
        ),
    ),
)


def write_scene(out_dir: str | Path, scene: Scene) -> tuple[mujoco.MjModel, np.ndarray]:
    """Write MJCF, object table, plan and initial state; return the model and home ``qpos``.

    The MJCF names its meshes' folder as ``package://example-robot-data/robots/`` (the URDFs'
    convention), not as a path: no path of this checkout or its virtual environment is
    stored, so the file is the same in every checkout, DVC's experiment copies included.
    :func:`load_scene_spec` resolves it in the running environment.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    model = scene.spec.compile()
    qpos = model.key("home").qpos.copy()
    absolute = f'meshdir="{assets.robots_dir()}"'
    xml = scene.spec.to_xml()
    if absolute not in xml:
        raise ArtifactError(f"MJCF of {scene.spec.modelname!r} lacks {absolute}; cannot relocate")
    write_text_atomic(out / MJCF_FILE, xml.replace(absolute, f'meshdir="{MESHDIR}"'))
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


def load_scene_spec(scene_dir: str | Path) -> mujoco.MjSpec:
    """The MJCF written by the scene stage, its meshes found in this environment's
    ``example-robot-data``.

    Raises:
        ArtifactError: If the file is missing or does not parse.
    """
    path = Path(scene_dir) / MJCF_FILE
    if not path.is_file():
        raise ArtifactError(
            f"scene MJCF {path} is missing (produced by stage 'scene'; "
            "rerun it with `dvc repro scene`)"
        )
    xml = path.read_text().replace(f'meshdir="{MESHDIR}"', f'meshdir="{assets.robots_dir()}"')
    try:
        return mujoco.MjSpec.from_string(xml)
    except ValueError as exc:
        raise ArtifactError(f"scene MJCF {path} does not parse: {exc}") from None


def load_scene_model(scene_dir: str | Path) -> mujoco.MjModel:
    """Compile the MJCF written by the scene stage (:func:`load_scene_spec`).

    Raises:
        ArtifactError: If the file is missing or does not compile.
    """
    spec = load_scene_spec(scene_dir)
    try:
        return spec.compile()
    except ValueError as exc:
        raise ArtifactError(
            f"scene MJCF {Path(scene_dir) / MJCF_FILE} does not compile: {exc}"
        ) from None


def load_objects(scene_dir: str | Path) -> dict[str, Any]:
    """The object table written by the scene stage."""
    return read_json(Path(scene_dir) / OBJECTS_FILE, OBJECTS)["objects"]


def load_plan(scene_dir: str | Path) -> dict[str, Any]:
    """The task plan written by the scene stage."""
    return read_json(Path(scene_dir) / PLAN_FILE, PLAN)


def load_state(scene_dir: str | Path) -> dict[str, np.ndarray]:
    """The initial state written by the scene stage."""
    return read_npz(Path(scene_dir) / STATE_FILE, STATE)
