"""Scene assembly: robot + objects + environment as one MuJoCo spec, plus the object table.

The robot's spec is the scene's root (its names stay unprefixed); the floor, a light, an
overview camera and every object of the scenario are added to its world body. Static objects
are welded to the world; movable ones get a free joint. The initial state is stored as the
MJCF keyframe ``home``.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import mujoco
import numpy as np

from locoman.config.schema import ObjectCfg, ScenarioCfg
from locoman.scene import g1, mobile_manipulator, rotations
from locoman.scene.objects import BOX, CYLINDER, SPHERE, object_geometry

GEOM_TYPES = {
    BOX: mujoco.mjtGeom.mjGEOM_BOX,
    CYLINDER: mujoco.mjtGeom.mjGEOM_CYLINDER,
    SPHERE: mujoco.mjtGeom.mjGEOM_SPHERE,
}
OBJECT_GROUP = 0
FLOOR = "floor"


@dataclasses.dataclass(frozen=True)
class Scene:
    """A built scene.

    Attributes:
        spec: MuJoCo spec (compile it for a model; ``key_qpos("home")`` is the start).
        objects: JSON-ready object table (poses, sizes, masses, friction, contact patches).
        plan: JSON-ready task plan (ordered subtask prompts and target placements).
    """

    spec: mujoco.MjSpec
    objects: dict[str, Any]
    plan: dict[str, Any]


def build_scene(name: str, cfg: ScenarioCfg, render_size: tuple[int, int] = (640, 480)) -> Scene:
    """Assemble the scenario ``name`` from its configuration."""
    if cfg.robot == "g1":
        spec = g1.g1_mjspec()
    else:
        spec = mobile_manipulator.mobile_manipulator_mjspec()
    spec.modelname = name
    spec.option.timestep = 0.002
    # Grasped objects creep out of pyramidal-cone, impratio-1 contacts under a steady load;
    # elliptic cones with a high impratio hold them. Stiff velocity actuators on the mobile
    # base need the implicit integrator.
    spec.option.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
    spec.option.impratio = 10.0
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    spec.visual.global_.offwidth, spec.visual.global_.offheight = render_size
    spec.visual.headlight.ambient = [0.35, 0.35, 0.35]
    spec.worldbody.add_geom(
        name=FLOOR,
        type=mujoco.mjtGeom.mjGEOM_PLANE,
        size=[0, 0, 0.05],
        rgba=[0.82, 0.82, 0.8, 1],
        friction=[1.0, 0.005, 0.0001],
    )
    spec.worldbody.add_light(pos=[0, 0, 4], dir=[0, 0, -1], diffuse=[0.6, 0.6, 0.6])
    table: dict[str, Any] = {}
    for obj_name, obj in cfg.objects.items():
        table[obj_name] = _add_object(spec, obj_name, obj)
    _add_overview_camera(spec, cfg)
    model = spec.compile()
    home = _initial_qpos(model, cfg)
    spec.add_key(name="home", qpos=home)
    return Scene(spec=spec, objects=table, plan=_plan(cfg))


def _add_object(spec: mujoco.MjSpec, name: str, obj: ObjectCfg) -> dict[str, Any]:
    geometry = object_geometry(obj.kind, obj.extents_m)
    quat = rotations.yaw_quat_wxyz(obj.yaw)
    body = spec.worldbody.add_body(name=name, pos=list(obj.pos), quat=list(quat))
    if obj.mass is not None:
        body.add_freejoint(name=f"{name}_free")
    volumes = [_volume(p.shape, p.size) for p in geometry.primitives]
    for part, volume in zip(geometry.primitives, volumes, strict=True):
        geom = body.add_geom(
            name=f"{name}/{part.name}",
            type=GEOM_TYPES[part.shape],
            size=list(part.size) + [0.0] * (3 - len(part.size)),
            pos=list(part.pos),
            rgba=list(obj.rgba),
            friction=[obj.friction, 0.005, 0.0001],
            group=OBJECT_GROUP,
        )
        if obj.mass is not None:
            geom.mass = obj.mass * volume / sum(volumes)
    return {
        "kind": obj.kind,
        "size_m": list(obj.extents_m),
        "pos_m": list(obj.pos),
        "yaw_rad": obj.yaw,
        "quat_wxyz": quat.tolist(),
        "mass_kg": obj.mass,
        "movable": obj.mass is not None,
        "friction": obj.friction,
        "rgba": list(obj.rgba),
        "primitives": [dataclasses.asdict(p) for p in geometry.primitives],
        "contact_patches": [dataclasses.asdict(p) for p in geometry.patches],
    }


def _volume(shape: str, size: tuple[float, ...]) -> float:
    if shape == BOX:
        return 8.0 * size[0] * size[1] * size[2]
    if shape == CYLINDER:
        return np.pi * size[0] ** 2 * 2.0 * size[1]
    return 4.0 / 3.0 * np.pi * size[0] ** 3


def _add_overview_camera(spec: mujoco.MjSpec, cfg: ScenarioCfg) -> None:
    """A camera looking at the middle of robot and objects from the front-left, 35 deg down."""
    points = [np.r_[cfg.start.xy, 0.6]] + [np.asarray(o.pos, float) for o in cfg.objects.values()]
    pts = np.array(points)
    centre = 0.5 * (pts.min(axis=0) + pts.max(axis=0))
    span = float(np.linalg.norm(pts.max(axis=0)[:2] - pts.min(axis=0)[:2]))
    distance = max(3.0, 1.4 * span + 1.5)
    azimuth, elevation = np.deg2rad(-140.0), np.deg2rad(35.0)
    offset = distance * np.array(
        [
            np.cos(elevation) * np.cos(azimuth),
            np.cos(elevation) * np.sin(azimuth),
            np.sin(elevation),
        ]
    )
    target = centre + np.array([0.0, 0.0, 0.5])
    eye = target + offset
    forward = (target - eye) / np.linalg.norm(target - eye)
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    spec.worldbody.add_camera(name="overview", pos=eye.tolist(), xyaxes=[*right, *up], fovy=50.0)


def _initial_qpos(model: mujoco.MjModel, cfg: ScenarioCfg) -> np.ndarray:
    data = mujoco.MjData(model)
    qpos = data.qpos.copy()
    if cfg.robot == "g1":
        q35 = g1.standing_q35()
        q35[:2] = cfg.start.xy
        q35[5] = cfg.start.yaw
        qpos = g1.pin_to_mujoco_qpos(g1.q35_to_pin(q35), model, qpos)
    else:
        base = np.r_[cfg.start.xy, cfg.start.yaw]
        qpos = mobile_manipulator.start_qpos(model, base, np.asarray(cfg.arm_start, float))
    return qpos


def _plan(cfg: ScenarioCfg) -> dict[str, Any]:
    subtasks = []
    for i, sub in enumerate(cfg.plan):
        entry: dict[str, Any] = {
            "index": i,
            "prompt": sub.prompt,
            # The action (walk, pick, ...): said, or the prompt's verb through its synonyms.
            "predicate": sub.resolved_action if cfg.robot == "g1" else sub.prompt.split()[0],
            "object": sub.object,
            "contacts": list(sub.contacts),
            "target": None,
        }
        if sub.target is not None:
            entry["target"] = {"pos_m": list(sub.target.pos), "yaw_rad": sub.target.yaw}
        subtasks.append(entry)
    return {"robot": cfg.robot, "description": cfg.description, "subtasks": subtasks}
