"""The ``render`` image backend: a posed human demonstrator and an object variant in MuJoCo.

It stands in for the image generator of paper A (Sec. III-A.1) on a CPU: the object drawn is a
*variant* of the scene's object (size, proportions, colour, texture) and the camera, light and
the person's placement change with the seed, as they would between generated images. Because
it is rendered, it also yields the ground truth (camera, depth, masks, keypoints, contacts)
that only scoring code reads.

The image's world ("generation world") has the variant's origin, the centre of its bottom
face, at (0, 0, z0) with zero yaw; z0 is the object's height in the scene for the subtask.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import mujoco
import numpy as np

from locoman.config.perception import GenerateCfg, VariantCfg
from locoman.errors import SceneError
from locoman.perception import camera, demonstrator
from locoman.scene import human
from locoman.scene.builder import GEOM_TYPES
from locoman.scene.objects import (
    ContactPatch,
    ObjectGeometry,
    object_geometry,
    primitive_half_extents,
)
from locoman.scene.plan_state import top_face

MIN_OBJECT_PIXELS = 200  # [px] fewer visible object pixels than this is "out of view"
IK_TOLERANCE_M = 0.02  # [m] largest miss of a posed demonstrator's contact
OBJECT_BODY = "object"
SUPPORT_BODY = "support"
STAND_BODY = "stand_on"


@dataclasses.dataclass(frozen=True)
class Variant:
    """The object as drawn in the image.

    Attributes:
        kind: Object kind.
        size: Extents [m] (same layout as the scene's size).
        rgba: Colour.
        texture_rgb: Second checker colour, or None for a plain object.
    """

    kind: str
    size: tuple[float, ...]
    rgba: tuple[float, float, float, float]
    texture_rgb: tuple[float, float, float] | None


@dataclasses.dataclass(frozen=True)
class StandOn:
    """The object the demonstrator stands on, where an earlier subtask stepped onto it.

    Attributes:
        obj: Its object table entry (``objects.json``).
        T_object_stand: (4, 4) its pose in the frame of the subtask's object [m].
    """

    obj: dict[str, Any]
    T_object_stand: np.ndarray


@dataclasses.dataclass(frozen=True)
class RenderedSubtask:
    """A rendered image R_g of a subtask and its ground truth.

    Attributes:
        rgb: (H, W, 3) uint8 image.
        truth: Ground-truth arrays (schema ``perception.ground_truth``).
        ik_residual_m: Largest contact miss of the posed demonstrator [m].
    """

    rgb: np.ndarray
    truth: dict[str, np.ndarray]
    ik_residual_m: float


def sample_variant(obj: dict[str, Any], cfg: VariantCfg, rng: np.random.Generator) -> Variant:
    """Draw a variant of an object table entry (``objects.json``)."""
    scale = rng.uniform(*cfg.size_scale)
    size = [
        s * scale * (1.0 + rng.uniform(-cfg.aspect_jitter, cfg.aspect_jitter))
        for s in obj["size_m"]
    ]
    rgb = np.clip(np.asarray(obj["rgba"][:3]) + rng.uniform(-1, 1, 3) * cfg.colour_jitter, 0, 1)
    textured = rng.random() < cfg.texture_probability
    second = tuple(float(c) for c in np.clip(rgb * rng.uniform(0.4, 0.7), 0, 1))
    return Variant(
        kind=obj["kind"],
        size=tuple(float(s) for s in size),
        rgba=(*(float(c) for c in rgb), 1.0),
        texture_rgb=second if textured else None,
    )


def render_subtask(
    obj: dict[str, Any],
    subtask: dict[str, Any],
    height: float,
    cfg: GenerateCfg,
    rng: np.random.Generator,
    stand_on: StandOn | None = None,
) -> RenderedSubtask:
    """Pose the demonstrator for ``subtask`` against a variant of ``obj`` standing at
    ``height`` [m] (where the object is during the subtask), and render it.

    With ``stand_on`` (the plan state of :mod:`locoman.scene.plan_state`), that object is drawn
    where the plan left it, relative to the variant's approach face, and the demonstrator
    stands on its top.

    Raises:
        SceneError: When the demonstrator cannot reach the contacts or the object ends up
            out of view; the message names the subtask and the object.
    """
    where = f"subtask {subtask['index']} ({subtask['prompt']!r}, object {subtask['object']!r})"
    variant = sample_variant(obj, cfg.variant, rng)
    z0 = height
    geometry = object_geometry(variant.kind, variant.size)
    targets = demonstrator.contact_targets(
        variant.kind,
        geometry.patches,
        subtask["contacts"],
        variant.size,
        cfg.step_height_max_m,
        base_height=z0,
    )
    lifted = {t.effector: (t.point + np.array([0.0, 0.0, z0]), t.normal) for t in targets}
    stand = None
    if stand_on is not None and not any(t.effector.endswith("_foot") for t in targets):
        stand = _stand_pose(stand_on, obj, variant, z0)
        lifted |= _feet_on_top(stand_on.obj, stand)
    view = cfg.view
    yaw = np.deg2rad(rng.uniform(-view.yaw_jitter_deg, view.yaw_jitter_deg))
    lateral = rng.uniform(-view.lateral_jitter_m, view.lateral_jitter_m)
    standoff = rng.uniform(*view.standoff_m)
    stance, world_targets = _place_person(lifted, yaw, lateral, standoff)
    # The truth is where the feet stand: they step aside with the person.
    targets = [
        demonstrator.stepped_aside(t, lateral, geometry.patches)
        if t.effector.endswith("_foot")
        else t
        for t in targets
    ]

    spec = _generation_spec(variant, z0, cfg, rng)
    if stand is not None:
        _add_stand(spec, stand_on.obj, stand)
    model = spec.compile()
    pose = demonstrator.pose_demonstrator(model, world_targets, stance, yaw)
    demonstrator.check_pose(pose, IK_TOLERANCE_M, where)

    fovy = np.deg2rad(rng.uniform(*view.fovy_deg))
    side = 1.0 if rng.random() < 0.5 else -1.0
    azimuth = yaw + side * np.deg2rad(rng.uniform(*view.azimuth_deg))
    elevation = np.deg2rad(rng.uniform(*view.elevation_deg))
    points = [_mesh_points(model, pose.qpos), _object_corners(geometry, z0)]
    if stand is not None:
        stand_geometry = object_geometry(stand_on.obj["kind"], stand_on.obj["size_m"])
        corners = _object_corners(stand_geometry, 0.0)
        points.append(corners @ stand[:3, :3].T + stand[:3, 3])
    points = np.vstack(points)
    K = camera.intrinsics_from_fovy(cfg.width, cfg.height, fovy)
    cam_pose = _fit_camera(points, K, cfg.width, cfg.height, azimuth, elevation, view.margin)
    spec.worldbody.add_camera(
        name="generated",
        pos=cam_pose[:3, 3].tolist(),
        xyaxes=camera.mujoco_xyaxes(cam_pose),
        fovy=float(np.rad2deg(fovy)),
    )
    model = spec.compile()
    rgb, depth, seg = _render(model, pose.qpos, "generated", cfg.width, cfg.height)
    object_mask = _body_mask(model, seg, {OBJECT_BODY})
    if object_mask.sum() < MIN_OBJECT_PIXELS:
        raise SceneError(
            f"{where}: only {int(object_mask.sum())} object pixels are visible in the "
            f"generated image (need {MIN_OBJECT_PIXELS}); the object is out of view or hidden"
        )
    human_bodies = {model.body(b).name for b in range(1, model.nbody)} - {
        OBJECT_BODY,
        SUPPORT_BODY,
        STAND_BODY,
    }
    human_mask = _body_mask(model, seg, human_bodies)
    kp_world = demonstrator.keypoints_world(model, pose.qpos)
    kp_cam = camera.to_camera(kp_world, cam_pose)
    kp_px = camera.project(kp_cam, K) - 0.5
    truth = {
        "K": K,
        "T_world_cam": cam_pose,
        "depth_m": depth,
        "object_mask": object_mask,
        "human_mask": human_mask,
        "keypoint_names": np.array(list(demonstrator.KEYPOINTS)),
        "keypoints_px": kp_px,
        "keypoints_world_m": kp_world,
        "keypoints_visible": _visible(kp_px, kp_cam[:, 2], depth, human_mask),
        "contact_names": np.array([t.effector for t in targets]),
        "contact_patches": np.array([t.patch for t in targets]),
        "contact_uv": np.array([t.patch_uv for t in targets], dtype=float).reshape(-1, 2),
        "contact_points_variant_m": np.array([t.point for t in targets]).reshape(-1, 3),
        "T_world_object": _translation(z0),
        "variant_size_m": np.array(variant.size),
        "variant_rgba": np.array(variant.rgba),
        "variant_textured": np.array(variant.texture_rgb is not None),
        "human_qpos": pose.qpos,
    }
    return RenderedSubtask(rgb=rgb, truth=truth, ik_residual_m=pose.residual_m)


def _stand_pose(stand_on: StandOn, obj: dict[str, Any], variant: Variant, z0: float) -> np.ndarray:
    """Pose (4, 4) of the stood-on object in the generation world: as far in front of the
    variant's approach face as it is in front of the scene object's (the variant is longer or
    shorter than the object), at the scene's heights."""
    pose = stand_on.T_object_stand.copy()
    pose[0, 3] += 0.5 * (float(obj["size_m"][0]) - float(variant.size[0]))
    pose[2, 3] += z0
    return pose


def _feet_on_top(
    stand_obj: dict[str, Any], pose: np.ndarray
) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Sole targets on the top patch of the stood-on object, either side of its centre
    across the person's facing (+x of the generation world)."""
    face = top_face(stand_obj)
    if face is None:
        raise SceneError(f"the demonstrator cannot stand on a {stand_obj['kind']!r}: no top face")
    centre = pose[:3, :3] @ face[0] + pose[:3, 3]
    up = np.array([0.0, 0.0, 1.0])
    return {
        name: (centre + np.array([0.0, side * demonstrator.STANCE_HALF_WIDTH, 0.0]), up)
        for name, side in (("left_foot", 1.0), ("right_foot", -1.0))
    }


def _add_stand(spec: mujoco.MjSpec, stand_obj: dict[str, Any], pose: np.ndarray) -> None:
    """The stood-on object's primitives, in its own colour, at ``pose`` (4, 4)."""
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, pose[:3, :3].ravel())
    body = spec.worldbody.add_body(name=STAND_BODY, pos=pose[:3, 3].tolist(), quat=quat.tolist())
    geometry = object_geometry(stand_obj["kind"], stand_obj["size_m"])
    _add_primitives(body, STAND_BODY, geometry, list(stand_obj["rgba"]))


def _add_primitives(
    body: mujoco.MjsBody,
    prefix: str,
    geometry: ObjectGeometry,
    rgba: list[float],
    material: str = "",
) -> None:
    """One geom per primitive of ``geometry`` on ``body``, named ``<prefix>/<part>``."""
    for part in geometry.primitives:
        geom = body.add_geom(
            name=f"{prefix}/{part.name}",
            type=GEOM_TYPES[part.shape],
            size=list(part.size) + [0.0] * (3 - len(part.size)),
            pos=list(part.pos),
            rgba=rgba,
        )
        if material:
            geom.material = material


def _place_person(
    lifted: dict[str, tuple[np.ndarray, np.ndarray]], yaw: float, lateral: float, standoff: float
) -> tuple[np.ndarray, dict[str, tuple[np.ndarray, np.ndarray]]]:
    """Stance centre [m] and world targets of all four end effectors.

    Hands stay on their contacts. Feet without a contact stand on the floor ``standoff``
    behind the hands; the person turns by ``yaw`` about the hands and steps ``lateral``.
    """
    targets = dict(lifted)
    rot = np.array([[np.cos(yaw), -np.sin(yaw)], [np.sin(yaw), np.cos(yaw)]])
    hands = [p for name, (p, _) in lifted.items() if name.endswith("_hand")]
    feet = {name: p for name, (p, _) in lifted.items() if name.endswith("_foot")}
    if feet:
        centre = np.mean(list(feet.values()), axis=0)[:2]
        for name, (p, n) in lifted.items():
            if name.endswith("_foot"):
                targets[name] = (p + np.array([0.0, lateral, 0.0]), n)
        return centre + np.array([0.0, lateral]), targets
    anchor = np.mean(hands, axis=0)[:2] if hands else np.zeros(2)
    centre = anchor + rot @ np.array([-standoff, lateral])
    for name, side in (("left_foot", 1.0), ("right_foot", -1.0)):
        xy = centre + rot @ np.array([0.0, side * demonstrator.STANCE_HALF_WIDTH])
        targets[name] = (np.array([xy[0], xy[1], 0.0]), np.array([0.0, 0.0, 1.0]))
    return centre, targets


def _generation_spec(
    variant: Variant, z0: float, cfg: GenerateCfg, rng: np.random.Generator
) -> mujoco.MjSpec:
    spec = human.human_mjspec(prefix="")
    spec.visual.global_.offwidth, spec.visual.global_.offheight = cfg.width, cfg.height
    ambient = rng.uniform(0.2, 0.4)
    spec.visual.headlight.ambient = [ambient] * 3
    spec.visual.headlight.diffuse = [0.3] * 3
    sky = rng.uniform(0.5, 0.9) * np.array([0.85, 0.9, 1.0])
    spec.add_texture(
        name="sky",
        type=mujoco.mjtTexture.mjTEXTURE_SKYBOX,
        builtin=mujoco.mjtBuiltin.mjBUILTIN_GRADIENT,
        width=64,
        height=64,
        rgb1=sky.tolist(),
        rgb2=(0.6 * sky).tolist(),
    )
    floor_rgb = rng.uniform(0.55, 0.9) * np.array([1.0, 0.97, 0.92])
    spec.worldbody.add_geom(
        name="floor",
        type=mujoco.mjtGeom.mjGEOM_PLANE,
        size=[0, 0, 0.05],
        rgba=[*floor_rgb, 1.0],
    )
    light_dir = np.array([rng.uniform(-1, 1), rng.uniform(-1, 1), -2.0])
    diffuse = rng.uniform(*cfg.view.light_diffuse)
    spec.worldbody.add_light(
        pos=(-2.0 * light_dir).tolist(),
        dir=(light_dir / np.linalg.norm(light_dir)).tolist(),
        diffuse=[diffuse] * 3,
    )
    material = ""
    if variant.texture_rgb is not None:
        spec.add_texture(
            name="variant_texture",
            type=mujoco.mjtTexture.mjTEXTURE_CUBE,
            builtin=mujoco.mjtBuiltin.mjBUILTIN_CHECKER,
            width=64,
            height=64,
            rgb1=list(variant.rgba[:3]),
            rgb2=list(variant.texture_rgb),
        )
        mat = spec.add_material(name="variant_material")
        mat.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = "variant_texture"
        material = "variant_material"
    geometry = object_geometry(variant.kind, variant.size)
    body = spec.worldbody.add_body(name=OBJECT_BODY, pos=[0.0, 0.0, z0])
    rgba = list(variant.rgba) if not material else [1.0, 1.0, 1.0, 1.0]
    _add_primitives(body, OBJECT_BODY, geometry, rgba, material)
    if z0 > 0.01:
        # What the object rests on (a table, a shelf, a trolley): a plain block under it,
        # reaching away from the person so that their legs stay clear of it.
        hx, hy = 0.5 * variant.size[0] + 0.05, 0.5 * variant.size[1] + 0.15
        wood = rng.uniform(0.3, 0.6) * np.array([1.0, 0.8, 0.6])
        spec.worldbody.add_body(name=SUPPORT_BODY, pos=[hx - 0.5 * variant.size[0], 0, 0]).add_geom(
            name=f"{SUPPORT_BODY}/top",
            type=mujoco.mjtGeom.mjGEOM_BOX,
            size=[hx, hy, 0.5 * z0],
            pos=[0.0, 0.0, 0.5 * z0],
            rgba=[*wood, 1.0],
        )
    return spec


def _mesh_points(model: mujoco.MjModel, qpos: np.ndarray, stride: int = 7) -> np.ndarray:
    """World positions of every ``stride``-th vertex of the posed demonstrator's meshes."""
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_kinematics(model, data)
    chunks = []
    for g in range(model.ngeom):
        mesh = model.geom_dataid[g]
        if model.geom_type[g] != mujoco.mjtGeom.mjGEOM_MESH or mesh < 0:
            continue
        adr, n = model.mesh_vertadr[mesh], model.mesh_vertnum[mesh]
        verts = model.mesh_vert[adr : adr + n : stride]
        chunks.append(verts @ data.geom_xmat[g].reshape(3, 3).T + data.geom_xpos[g])
    return np.vstack(chunks)


def _object_corners(geometry: ObjectGeometry, z0: float) -> np.ndarray:
    """Corners (8 per primitive, 3) [m] of the primitives' boxes, lifted by ``z0``."""
    signs = np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1])).T.reshape(-1, 3)
    return np.vstack(
        [
            np.asarray(p.pos) + signs * primitive_half_extents(p.shape, p.size) + [0, 0, z0]
            for p in geometry.primitives
        ]
    )


def _fit_camera(
    points: np.ndarray,
    K: np.ndarray,
    width: int,
    height: int,
    azimuth: float,
    elevation: float,
    margin: float,
) -> np.ndarray:
    """The nearest camera on the given bearing that sees all ``points`` inside the margin."""
    lo, hi = points.min(axis=0), points.max(axis=0)
    target = 0.5 * (lo + hi)
    direction = np.array(
        [
            np.cos(elevation) * np.cos(azimuth),
            np.cos(elevation) * np.sin(azimuth),
            np.sin(elevation),
        ]
    )
    limits = np.array([width, height]) * np.array([margin, 1.0 - margin])[:, None]

    def fits(distance: float) -> bool:
        pose = camera.look_at(target + distance * direction, target)
        pc = camera.to_camera(points, pose)
        if np.any(pc[:, 2] < 0.1):
            return False
        uv = camera.project(pc, K)
        return bool(np.all(uv >= limits[0]) and np.all(uv <= limits[1]))

    near, far = 0.5, 50.0
    if not fits(far):
        raise SceneError("no camera distance up to 50 m fits the person and the object")
    for _ in range(40):
        mid = 0.5 * (near + far)
        near, far = (near, mid) if fits(mid) else (mid, far)
    return camera.look_at(target + far * direction, target)


def _render(
    model: mujoco.MjModel, qpos: np.ndarray, cam: str, width: int, height: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """RGB (H, W, 3) uint8, depth (H, W) float32 [m] (0 = nothing), geom ids (H, W) (-1)."""
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_forward(model, data)
    return render_rgbd(model, data, cam, width, height)


def render_rgbd(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    cam: str,
    width: int,
    height: int,
    option: mujoco.MjvOption | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """RGB, depth along the optical axis [m] (0 where no geom) and geom ids (-1 where none)."""
    with mujoco.Renderer(model, height=height, width=width) as renderer:
        renderer.update_scene(data, camera=cam, scene_option=option)
        rgb = renderer.render().copy()
        renderer.enable_depth_rendering()
        depth = renderer.render().astype(np.float32)
        renderer.disable_depth_rendering()
        renderer.enable_segmentation_rendering()
        seg = renderer.render()
    geom_ids = np.where(seg[:, :, 1] == int(mujoco.mjtObj.mjOBJ_GEOM), seg[:, :, 0], -1)
    depth = np.where(geom_ids >= 0, depth, 0.0).astype(np.float32)
    return rgb, depth, geom_ids


def _body_mask(model: mujoco.MjModel, geom_ids: np.ndarray, bodies: set[str]) -> np.ndarray:
    wanted = np.array(
        [model.body(model.geom_bodyid[g]).name in bodies for g in range(model.ngeom)] + [False]
    )
    return wanted[geom_ids]


def _visible(
    kp_px: np.ndarray, kp_depth: np.ndarray, depth: np.ndarray, human_mask: np.ndarray
) -> np.ndarray:
    """A keypoint is visible when it is in the image and no other object is in front of it."""
    h, w = depth.shape
    out = np.zeros(len(kp_px), dtype=bool)
    for k, ((u, v), z) in enumerate(zip(kp_px, kp_depth, strict=True)):
        iu, iv = round(float(u)), round(float(v))
        if 0 <= iu < w and 0 <= iv < h and z > 0:
            seen = depth[iv, iu]
            # Joint centres lie inside the limbs, up to ~8 cm behind the body's surface.
            out[k] = seen == 0.0 or (human_mask[iv, iu] and seen > z - 0.12) or seen > z - 0.02
    return out


def _translation(z: float) -> np.ndarray:
    pose = np.eye(4)
    pose[2, 3] = z
    return pose


def object_patches(obj: dict[str, Any]) -> dict[str, ContactPatch]:
    """The contact patches of an object table entry by name."""
    return {
        p["name"]: ContactPatch(
            p["name"], tuple(p["centre"]), tuple(p["normal"]), tuple(p["half_extents"])
        )
        for p in obj["contact_patches"]
    }
