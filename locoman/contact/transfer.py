"""Contact transfer: 2D contacts of the generated image -> 3D contact locations L in the scene.

Paper A, Sec. III-A.2, third step. Per subtask:

1. the semantic score pool between the object in R_g and in R_s (:mod:`.semantic`);
2. sampled SVD + ICP registration of R_g's object cloud onto the simulated object
   (:mod:`.registration`), which gives the transform T_world_gen;
3. the hands and feet lifted to 3D (:mod:`.lift`), mapped into the world (:func:`place_contacts`:
   a hand by the registration's affine map, a foot on the floor at the person's offset from
   the object's approach face)
   and projected onto the closest surface of the simulated object (hands: of the parts that
   carry a contact patch, a trolley's handle bar rather than its posts; feet: the closest
   surface they can stand on, the object's tops or the floor), so that no contact lies
   inside the object (:mod:`.surface`);
4. the human's placement: the pelvis of the 3D pose mapped by the same transform, relative to
   the object, for retargeting.

The ``naive`` method is the geometry-unaware baseline of Sec. V-B: each contact is the top-1
semantic match, in R_s, of the object pixel under the hand or foot, lifted with D_s.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from locoman.config.contacts import ContactsCfg
from locoman.contact import semantic
from locoman.contact.confidence import Confidence, confidence
from locoman.contact.kabsch import apply, decompose_similarity, nearest_rotation
from locoman.contact.lift import SOLE_KEYPOINTS, Anchor, fit_anchor, support_up
from locoman.contact.registration import Person, Registration, Surface, View, register
from locoman.contact.surface import project_to_support, project_to_surface, sample_surface
from locoman.errors import SceneError
from locoman.perception import camera
from locoman.perception.demonstrator import LOCAL_FORWARD
from locoman.scene.objects import Primitive, bounding_box

FLOOR_Z = 0.0  # [m] world height of the floor
ON_FLOOR_TOL = 1e-9  # [m] a projected sole this close to the floor's height stands on it


@dataclasses.dataclass(frozen=True)
class SubtaskInputs:
    """What contact transfer reads for one subtask (all from upstream artifacts).

    Attributes:
        where: Names the subtask in errors.
        effectors: End effectors the plan puts in contact.
        rgb: R_g (H, W, 3).
        sim_rgb: R_s (Hs, Ws, 3).
        mask: Object mask in R_g.
        sim_mask: Object mask in R_s.
        depth: D_g [m] and ``K``: the intrinsics that lifted R_g [px].
        sim_depth: D_s [m], ``sim_K`` its true intrinsics, ``T_world_sim`` its camera pose.
        cloud: R_g object cloud, gen frame [m]; ``sim_cloud``: R_s cloud, world [m].
        keypoint_names: Names of the keypoints below.
        keypoints_px: 2D keypoints in R_g [px] (NaN when not found).
        keypoints_lifted: Keypoints lifted with D_g, gen frame [m] (NaN when no depth).
        pose_keypoints: 3D pose estimate, R_g's camera frame [m].
        T_cam_pelvis: Pelvis pose of the 3D pose estimate.
        T_world_object: The object's pose in the scene.
        primitives: The object's primitive shapes, object frame.
        held: Those a hand may hold (:func:`~locoman.contact.surface.held_parts`).
    """

    where: str
    effectors: list[str]
    rgb: np.ndarray
    sim_rgb: np.ndarray
    mask: np.ndarray
    sim_mask: np.ndarray
    depth: np.ndarray
    K: np.ndarray
    sim_depth: np.ndarray
    sim_K: np.ndarray
    T_world_sim: np.ndarray
    cloud: np.ndarray
    sim_cloud: np.ndarray
    keypoint_names: list[str]
    keypoints_px: np.ndarray
    keypoints_lifted: np.ndarray
    pose_keypoints: np.ndarray
    T_cam_pelvis: np.ndarray
    T_world_object: np.ndarray
    primitives: tuple[Primitive, ...]
    held: tuple[Primitive, ...]


@dataclasses.dataclass(frozen=True)
class Transfer:
    """Result of one subtask.

    Attributes:
        points_world: (C, 3) contact locations L of the chosen method [m].
        normals_world: (C, 3) outward normals at L.
        surfaces: ``object`` or ``floor`` per contact.
        raw_points_world: (C, 3) L before the surface projection [m].
        naive_world: (C, 3) the naive baseline's contacts [m].
        naive_normals_world: (C, 3) outward normals of the surface nearest to them.
        registration: The best hypothesis (it also places the human for ``naive``).
        T_world_pelvis: The human's pelvis placed in the scene.
        pool: The semantic score pool.
        lifted: (C, 3) hands and feet in R_g's metric camera frame [m].
        anchor: Maps R_g's metric camera frame to its lifted cloud's frame.
        confidence: How far the registration can be trusted, without the ground truth.
        used: Whose contacts ``points_world`` holds: ``registration`` or ``naive`` (the
            method, or a doubtful registration's fallback: ``contacts.on_doubt``).
    """

    points_world: np.ndarray
    normals_world: np.ndarray
    surfaces: list[str]
    raw_points_world: np.ndarray
    naive_world: np.ndarray
    naive_normals_world: np.ndarray
    registration: Registration
    T_world_pelvis: np.ndarray
    pool: semantic.ScorePool
    lifted: np.ndarray
    anchor: Anchor
    confidence: Confidence
    used: str


def lift_pixels(px: np.ndarray, depth: np.ndarray, K: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Camera-frame points (P, 3) [m] of integer pixels (P, 2) and whether each has depth."""
    iu, iv = px[:, 0].astype(int), px[:, 1].astype(int)
    z = depth[iv, iu].astype(float)
    return camera.pixel_rays(px, K) * z[:, None], z > 0.0


def build_pool(
    inputs: SubtaskInputs,
    describer: semantic.Describer,
    points: int,
    top_n: int,
    grid_px: int,
    rng: np.random.Generator,
) -> tuple[semantic.ScorePool, np.ndarray, np.ndarray]:
    """The score pool, plus the described grid of R_s (pixels (P, 2), descriptors (P, D))."""
    gen_px = semantic.sample_pixels(
        inputs.mask, inputs.depth > 0.0, points, rng, f"{inputs.where}, generated image"
    )
    sim_px = semantic.mask_pixels(inputs.sim_mask, inputs.sim_depth > 0.0, grid_px)
    if len(sim_px) < semantic.MIN_POOL_POINTS:
        raise SceneError(
            f"{inputs.where}: the simulated view's object mask has {len(sim_px)} grid pixels "
            f"with depth; contact transfer needs at least {semantic.MIN_POOL_POINTS}"
        )
    sim_desc = describer(inputs.sim_rgb, inputs.sim_mask, sim_px)
    gen_desc = describer(inputs.rgb, inputs.mask, gen_px)
    return semantic.score_pool(gen_desc, sim_desc, sim_px, gen_px, top_n), sim_px, sim_desc


def lift_effectors(
    inputs: SubtaskInputs, cfg: ContactsCfg
) -> tuple[np.ndarray, np.ndarray, Person, Anchor]:
    """Hands and feet of the plan (C, 3) and the pelvis (3,) in R_g's metric camera frame
    [m], the person's up and facing directions there, and the anchor between that frame and
    the frame of R_g's lifted cloud.

    Raises:
        SceneError: When too few keypoints anchor the pose, or a contact keypoint has no
            depth (``lift = depth``).
    """
    names = inputs.keypoint_names
    idx = [names.index(e) for e in inputs.effectors]
    px = inputs.keypoints_px
    h, w = inputs.mask.shape
    inside = np.isfinite(px).all(axis=1)
    iu = np.clip(np.nan_to_num(px[:, 0]).round().astype(int), 0, w - 1)
    iv = np.clip(np.nan_to_num(px[:, 1]).round().astype(int), 0, h - 1)
    on_object = inside & inputs.mask[iv, iu]
    try:
        anchor = fit_anchor(
            inputs.pose_keypoints, inputs.keypoints_lifted, ~on_object, cfg.anchor_quantile
        )
    except ValueError as err:
        raise SceneError(
            f"{inputs.where}: cannot anchor the 3D pose to the depth ({err}); check the "
            "keypoints and the depth of the generated image"
        ) from None
    pelvis = inputs.T_cam_pelvis[:3, 3]
    up = support_up(inputs.pose_keypoints[[names.index(n) for n in SOLE_KEYPOINTS]], pelvis)
    if cfg.lift == "pose":
        lifted = inputs.pose_keypoints[idx]
    else:
        lifted = anchor.undo(inputs.keypoints_lifted[idx])
        missing = [e for e, p in zip(inputs.effectors, lifted, strict=True) if np.isnan(p).any()]
        if missing:
            raise SceneError(
                f"{inputs.where}: no depth under the keypoints of {missing}; use "
                "contacts.lift = pose, which places them from the 3D pose"
            )
    person = Person(up, inputs.T_cam_pelvis[:3, :3] @ LOCAL_FORWARD)
    return lifted, pelvis, person, anchor


def project_contacts(
    points_world: np.ndarray, effectors: list[str], inputs: SubtaskInputs
) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """L projected onto the object: hands onto the closest surface point of the parts they
    hold, feet onto the closest upward surface (its tops or the floor). Returns points,
    normals (world) and the surface each landed on."""
    T = inputs.T_world_object
    local = camera.transform(points_world, np.linalg.inv(T))
    out = np.empty_like(local)
    normals = np.empty_like(local)
    surfaces = []
    floor_z = floor_height(T)
    for k, name in enumerate(effectors):
        if name.endswith("_foot"):
            q, n = project_to_support(local[k : k + 1], inputs.primitives, floor_z)
            surfaces.append("floor" if abs(q[0, 2] - floor_z) < ON_FLOOR_TOL else "object")
        else:
            q, n = project_to_surface(local[k : k + 1], inputs.primitives, inputs.held)
            surfaces.append("object")
        out[k], normals[k] = q[0], n[0]
    return camera.transform(out, T), normals @ T[:3, :3].T, surfaces


def are_feet(effectors: list[str]) -> np.ndarray:
    """Which effectors (C,) are feet, which stand on a support rather than hold the object."""
    return np.array([name.endswith("_foot") for name in effectors], dtype=bool)


def place_contacts(
    affine: np.ndarray,
    lifted: np.ndarray,
    effectors: list[str],
    primitives: tuple[Primitive, ...],
    T_world_object: np.ndarray,
) -> np.ndarray:
    """Contacts (C, 3) lifted in R_g's metric camera frame, placed in the scene world [m].

    A hand is on the object: it goes where the registration's ``affine`` map A (4, 4: the
    similarity and the object's per-axis stretch) takes it, and so does a foot that A puts on
    one of the object's tops. A foot on the floor stands in front of the object's approach
    face (its -x side) at the person's offset from that face's centre a, on the object's
    bottom: with c = A^-1 a the point of R_g that A puts there, and R the nearest rotation to
    A's linear part,

        p_world = a + R (p - c).

    The object's size does not move the person: a table the variant shows 20 % smaller
    moves neither a person standing 0.3 m in front of it nor their feet 0.1 m either side of
    its centre line, which the nearest point of the object (a leg) would.
    """
    placed = apply(affine, lifted)
    floor = are_feet(effectors) & ~on_object_top(placed, primitives, T_world_object)
    if floor.any():
        lo, _ = bounding_box(primitives)
        a = camera.transform(np.array([[lo[0], 0.0, 0.0]]), T_world_object)
        c = apply(np.linalg.inv(affine), a)
        placed[floor] = a + (lifted[floor] - c) @ nearest_rotation(affine[:3, :3]).T
    return placed


def on_object_top(
    points_world: np.ndarray, primitives: tuple[Primitive, ...], T_world_object: np.ndarray
) -> np.ndarray:
    """Whether the upward surface closest to each point (N, 3) [m] is one of the object's
    tops rather than the floor (N,)."""
    local = camera.transform(points_world, np.linalg.inv(T_world_object))
    floor_z = floor_height(T_world_object)
    q, _ = project_to_support(local, primitives, floor_z)
    return np.abs(q[:, 2] - floor_z) > ON_FLOOR_TOL


def floor_height(T_world_object: np.ndarray) -> float:
    """The floor's height [m] in the object's frame (object frames are upright: yaw only)."""
    return FLOOR_Z - float(T_world_object[2, 3])


def contact_gaps(raw: np.ndarray, projected: np.ndarray, effectors: list[str]) -> np.ndarray:
    """How far [m] (C,) each contact moved onto the surface it touches: a hand the whole way,
    a foot horizontally (a sole keypoint stands above the floor it is projected onto). A
    registered hand that lands centimetres off the object was placed by a wrong pose."""
    gap = raw - projected
    gap[are_feet(effectors), 2] = 0.0
    return np.linalg.norm(gap, axis=1)


def naive_contacts(
    inputs: SubtaskInputs,
    describer: semantic.Describer,
    sim_px: np.ndarray,
    sim_desc: np.ndarray,
    lifted_gen: np.ndarray,
) -> np.ndarray:
    """The geometry-unaware baseline (C, 3) [m]: for each contact, the object pixel of R_g
    nearest to its 2D keypoint, its top-1 match in R_s, lifted with D_s into the world."""
    names = inputs.keypoint_names
    px = inputs.keypoints_px[[names.index(e) for e in inputs.effectors]]
    # A keypoint the 2D detector missed falls back to the lifted point's projection.
    fallback = camera.project(lifted_gen, inputs.K) - 0.5
    px = np.where(np.isfinite(px), px, fallback)
    vs, us = np.nonzero(inputs.mask & (inputs.depth > 0.0))
    object_px = np.column_stack([us, vs]).astype(float)
    nearest = np.linalg.norm(object_px[None] - px[:, None], axis=2).argmin(axis=1)
    gen_px = object_px[nearest]
    gen_desc = describer(inputs.rgb, inputs.mask, gen_px)
    matched = semantic.score_pool(gen_desc, sim_desc, sim_px, gen_px, top_n=1).sim_px[:, 0]
    points, _ = lift_pixels(matched, inputs.sim_depth, inputs.sim_K)
    return camera.transform(points, inputs.T_world_sim)


def object_surface(inputs: SubtaskInputs, points: int, rng: np.random.Generator) -> Surface:
    """The simulated object's whole surface in the scene world, which registration fits."""
    local, normals = sample_surface(inputs.primitives, points, rng)
    T = inputs.T_world_object
    return Surface(camera.transform(local, T), normals @ T[:3, :3].T, T)


def transfer_subtask(
    inputs: SubtaskInputs,
    cfg: ContactsCfg,
    describer: semantic.Describer,
    rng: np.random.Generator,
) -> Transfer:
    """Contact locations L, the object transform and the human placement of one subtask."""
    pool, sim_px, sim_desc = build_pool(
        inputs, describer, cfg.pool.points, cfg.pool.top_n, cfg.pool.grid_px, rng
    )
    lifted, pelvis, person, anchor = lift_effectors(inputs, cfg)
    naive = naive_contacts(inputs, describer, sim_px, sim_desc, anchor(lifted))
    src, _ = lift_pixels(pool.gen_px, inputs.depth, inputs.K)
    s, n = pool.sim_px.shape[:2]
    dst_cam, valid = lift_pixels(pool.sim_px.reshape(-1, 2), inputs.sim_depth, inputs.sim_K)
    dst = camera.transform(dst_cam, inputs.T_world_sim).reshape(s, n, 3)
    source = anchor.undo(inputs.cloud)
    surface = object_surface(inputs, cfg.registration.model_points, rng)
    view = _view(inputs, anchor, cfg.registration.occlusion_margin_m)
    reg = register(
        source,
        surface,
        anchor.undo(src),
        dst,
        valid.reshape(s, n),
        person,
        view,
        cfg.registration,
        rng,
        inputs.where,
    )
    placed = place_contacts(
        reg.affine, lifted, inputs.effectors, inputs.primitives, inputs.T_world_object
    )
    projected, normals, surfaces = project_contacts(placed, inputs.effectors, inputs)
    gaps = dict(
        zip(inputs.effectors, contact_gaps(placed, projected, inputs.effectors), strict=True)
    )
    trust = confidence(reg, surface, source, view, inputs.mask, cfg.confidence, gaps)
    T = reg.transform
    _, rot, _ = decompose_similarity(T)
    T_world_pelvis = np.eye(4)
    T_world_pelvis[:3, :3] = rot @ inputs.T_cam_pelvis[:3, :3]
    T_world_pelvis[:3, 3] = apply(T, pelvis[None])[0]
    naive_normals = _naive_normals(naive, inputs)
    used = "naive" if cfg.method == "naive" else "registration"
    if trust.doubtful and cfg.on_doubt == "fallback":
        used = "naive"
    raw, points = placed, projected
    if used == "naive":
        raw = points = naive
        normals, surfaces = naive_normals, ["object"] * len(naive)
    return Transfer(
        points,
        normals,
        surfaces,
        raw,
        naive,
        naive_normals,
        reg,
        T_world_pelvis,
        pool,
        lifted,
        anchor,
        trust,
        used,
    )


def _view(inputs: SubtaskInputs, anchor: Anchor, margin_m: float | None) -> View | None:
    """R_g's depth as the registration needs it to tell what the person hides."""
    if margin_m is None:
        return None
    return View(inputs.depth, inputs.K, anchor.scale, anchor.offset, margin_m)


def _naive_normals(points: np.ndarray, inputs: SubtaskInputs) -> np.ndarray:
    """Outward normals of the object surface nearest to naive contacts."""
    T = inputs.T_world_object
    _, normals = project_to_surface(camera.transform(points, np.linalg.inv(T)), inputs.primitives)
    return normals @ T[:3, :3].T


def primitives_of(obj: dict[str, Any]) -> tuple[Primitive, ...]:
    """Primitive shapes of an object table entry."""
    return tuple(
        Primitive(p["shape"], tuple(p["size"]), tuple(p["pos"]), p["name"])
        for p in obj["primitives"]
    )
