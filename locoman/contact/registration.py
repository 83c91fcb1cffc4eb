"""Sampling-based registration of the generated object cloud onto the simulated object.

Paper A, Sec. III-A.2: draw one correspondence per sampled point from the semantic score pool,
lift both sides to 3D, solve the transform by SVD, refine it with ICP and score the overlap of
the two clouds; repeat (10 iterations in the paper) and keep the transform with the highest
overlap. The idea: correct semantic matches give good geometric overlap.

What this implementation adds, and why:

- **The target is the simulated object's whole surface** (sampled from its primitives, with
  normals), not only the part one simulated camera sees: R_g and R_s show the object from
  different sides, and a partial-to-partial fit has no reason to be right.
- **View-aware symmetric ICP.** The generated cloud only shows the side facing R_g's camera.
  Each ICP step pairs every source point with its nearest target point *and* every target
  point the current camera estimate sees with its nearest source point, so a fit cannot
  shrink the cloud onto a patch of the target to raise its overlap; the scale is estimated
  (Umeyama) and clamped to a range. The overlap score is the F-score of both directions.
  A target point is seen when it faces the camera and nothing nearer covers its pixel in
  D_g: the person's arm in front of the box hides part of it, and asking that part for
  source points turned the fit (``s2_trolley``'s pick: 14 deg of yaw, 5 cm contact error).
- **Per-axis stretch.** The object in R_g is a variant: a stretched copy of the simulated
  one (each extent scaled on its own), which no similarity absorbs. After the winner is
  chosen, ICP goes on with a scale per object axis and a small rotation, y = D R x + b in the
  object frame, with each factor of D pulled towards 1 by a prior so that an axis the view
  barely sees keeps the similarity's scale.
- **Symmetric poses.** Boxes and tables look the same turned about their vertical axis, so
  every hypothesis is also tried turned by 360/turns degrees. ICP keeps each levelled
  hypothesis upright (``upright``): it only turns it about the vertical, since a view that
  shows one face and a top does not pin the tilt, and objects stand on the floor. The
  winner has the best overlap among the hypotheses that stand the object upright on the
  person's ground plane and put the person facing the object's approach side (+x in the
  object frame), which is how every scene is built: the overlap cannot tell symmetric
  poses apart, the person can.

All hypotheses are drawn, solved by SVD and refined by ICP at once (batched over the leading
axis, with one KD-tree per cloud).
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy.spatial import cKDTree

from locoman.config.contacts import RegistrationCfg
from locoman.contact.kabsch import apply, similarity_matrix, umeyama
from locoman.errors import SceneError

UP = np.array([0.0, 0.0, 1.0])


@dataclasses.dataclass(frozen=True)
class Surface:
    """The simulated object's surface in the scene world.

    Attributes:
        points: (M, 3) samples [m].
        normals: (M, 3) outward unit normals.
        T_world_object: (4, 4) the object's pose; its z axis is the symmetry axis.
    """

    points: np.ndarray
    normals: np.ndarray
    T_world_object: np.ndarray


@dataclasses.dataclass(frozen=True)
class Registration:
    """The winning hypothesis.

    Attributes:
        transform: (4, 4) similarity from R_g's camera frame to the scene world [m].
        affine: (4, 4) ``transform`` followed by the per-axis stretch: where contacts go.
        stretch: (3,) factors of the stretch along the object's axes [-].
        overlap: F-score of the overlap, in [0, 1].
        iteration: 1-based sampling iteration whose SVD started the winner.
        turn: Turns (of 360/turns degrees) about the object's axis applied to that start.
        overlaps: (H, T) overlap of every hypothesis and turn after ICP.
        scales: (H, T) their scales [-].
        tilt_deg: (H, T) angle between the person's up direction, mapped, and world +z [deg].
        facing_error_deg: (H, T) angle between the person's facing and the object's +x [deg]
            (NaN without a facing direction).
        candidates: (H, T, 4, 4) every hypothesis after ICP.
        gated: (H, T) those that passed the gates the winner was chosen among.
    """

    transform: np.ndarray
    affine: np.ndarray
    stretch: np.ndarray
    overlap: float
    iteration: int
    turn: int
    overlaps: np.ndarray
    scales: np.ndarray
    tilt_deg: np.ndarray
    facing_error_deg: np.ndarray
    candidates: np.ndarray
    gated: np.ndarray


@dataclasses.dataclass(frozen=True)
class View:
    """What R_g's camera saw, to tell hidden surface from missing surface.

    Attributes:
        depth_m: (H, W) D_g, in the frame the cloud was lifted in [m]; 0 where none.
        K: (3, 3) the intrinsics the cloud was lifted with [px].
        scale: (3,) per-axis scale from the registered (metric) frame to the lifted one.
        offset: (3,) offset of that map [m].
        margin_m: A point is hidden where D_g at its pixel is nearer by more than this [m].
    """

    depth_m: np.ndarray
    K: np.ndarray
    scale: np.ndarray
    offset: np.ndarray
    margin_m: float


@dataclasses.dataclass(frozen=True)
class Person:
    """What the demonstrator tells about the object's pose, in the gen frame.

    Attributes:
        up: Unit normal of the plane the soles stand on (objects stand upright on it), or
            None when the feet are not seen.
        facing: The person's forward direction (they face the object's approach side, +x in
            the object frame), or None.
    """

    up: np.ndarray | None
    facing: np.ndarray | None


def draw_hypotheses(valid: np.ndarray, iterations: int, rng: np.random.Generator) -> np.ndarray:
    """Candidate index (H, S) per hypothesis and sampled point, uniform over its valid
    candidates; the first hypothesis takes every point's top-1 match."""
    counts = valid.sum(axis=1)
    draws = rng.random((iterations, valid.shape[0]))
    rank = np.minimum((draws * counts).astype(int), np.maximum(counts - 1, 0))
    # Valid candidates first, in score order; then the rank-th of them.
    order = np.argsort(~valid, axis=1, kind="stable")
    choice = np.take_along_axis(
        np.broadcast_to(order, rank.shape + order.shape[1:]), rank[..., None], axis=2
    )[..., 0]
    choice[0] = order[:, 0]
    return choice


def robust_svd(
    src: np.ndarray,
    dst: np.ndarray,
    with_scale: bool,
    trim_rounds: int,
    scale_range: tuple[float, float],
) -> np.ndarray:
    """Similarity matrices (H, 4, 4) of batched correspondences (H, S, 3); after the first
    SVD, each of ``trim_rounds`` refits keeps the half of the matches that fit best."""
    weights = np.ones(src.shape[:2])
    for _ in range(trim_rounds + 1):
        matrix = _fit(src, dst, weights, with_scale, scale_range)
        residual = np.linalg.norm(apply(matrix, src) - dst, axis=2)
        weights = (residual <= np.median(residual, axis=1, keepdims=True)).astype(float)
    return matrix


def _fit(
    src: np.ndarray,
    dst: np.ndarray,
    weights: np.ndarray,
    with_scale: bool,
    scale_range: tuple[float, float],
) -> np.ndarray:
    """Weighted Umeyama with the scale clamped; the rotation does not depend on the scale,
    and the translation is re-solved for the clamped one."""
    scale, rot, _ = umeyama(src, dst, weights, with_scale)
    scale = np.clip(scale, *scale_range) if with_scale else scale
    w = weights / np.maximum(weights.sum(axis=-1, keepdims=True), 1e-300)
    mu_s = np.einsum("...n,...nk->...k", w, src)
    mu_d = np.einsum("...n,...nk->...k", w, dst)
    trans = mu_d - scale[..., None] * np.einsum("...ij,...j->...i", rot, mu_s)
    return similarity_matrix(scale, rot, trans)


def seen_target(
    points: np.ndarray, normals: np.ndarray, transforms: np.ndarray, view: View | None
) -> np.ndarray:
    """Which target points (M, 3) each hypothesis' camera sees (H, M).

    A point is seen when it faces the camera, whose centre is the image of R_g's optical
    centre (the origin of the gen frame) under the hypothesis (H, 4, 4), and, given a
    ``view``, when D_g at its pixel is not nearer than the point by more than the margin.
    """
    to_camera = transforms[:, None, :3, 3] - points[None]
    seen = np.einsum("hmk,mk->hm", to_camera, normals) > 0.0
    if view is None:
        return seen
    metric = apply(np.linalg.inv(transforms), points)
    lifted = metric * view.scale + view.offset
    z = lifted[..., 2]
    ahead = z > 1e-9
    pixel = (
        np.einsum("ij,hmj->hmi", view.K[:2, :2], lifted[..., :2])
        / np.where(ahead, z, 1.0)[..., None]
        + view.K[:2, 2]
    )
    u, v = np.floor(pixel[..., 0]).astype(int), np.floor(pixel[..., 1]).astype(int)
    rows, cols = view.depth_m.shape
    inside = ahead & (u >= 0) & (u < cols) & (v >= 0) & (v < rows)
    depth = np.where(inside, view.depth_m[np.clip(v, 0, rows - 1), np.clip(u, 0, cols - 1)], 0.0)
    return seen & ~(inside & (depth > 0.0) & (depth < z - view.margin_m))


def icp(
    source: np.ndarray,
    surface: Surface,
    init: np.ndarray,
    max_distance: float,
    iterations: int,
    with_scale: bool,
    scale_range: tuple[float, float],
    upright: bool = False,
    view: View | None = None,
) -> np.ndarray:
    """View-aware symmetric ICP of a batch of starts (H, 4, 4); returns the refined ones.

    Pairs: each source point with its nearest target point, and each target point the
    camera sees (:func:`seen_target`) with its nearest source point; pairs longer than
    ``max_distance`` [m] are dropped. Each step solves the weighted similarity of all pairs
    (Umeyama); ``upright`` keeps each start's tilt and only turns it about the world's
    vertical (:func:`_fit_yaw`).
    """
    target_tree = cKDTree(surface.points)
    source_tree = cKDTree(source)
    transforms = np.array(init, dtype=float)
    scales = np.cbrt(np.linalg.det(transforms[:, :3, :3]))
    tilts = transforms[:, :3, :3] / scales[:, None, None]
    h, n, m = len(transforms), len(source), len(surface.points)
    for _ in range(iterations):
        moved = apply(transforms, source)
        dist, idx = target_tree.query(moved.reshape(-1, 3), workers=-1)
        forward_w = (dist <= max_distance).reshape(h, n)
        forward_dst = surface.points[idx].reshape(h, n, 3)
        # Target points into each hypothesis' source frame, matched to the source cloud.
        inverse = np.linalg.inv(transforms)
        back = apply(inverse, np.broadcast_to(surface.points, (h, m, 3)))
        _, jdx = source_tree.query(back.reshape(-1, 3), workers=-1)
        reverse_src = source[jdx].reshape(h, m, 3)
        reverse_gap = np.linalg.norm(apply(transforms, reverse_src) - surface.points, axis=2)
        seen = seen_target(surface.points, surface.normals, transforms, view)
        reverse_w = seen & (reverse_gap <= max_distance)
        src = np.concatenate([np.broadcast_to(source, (h, n, 3)), reverse_src], axis=1)
        dst = np.concatenate([forward_dst, np.broadcast_to(surface.points, (h, m, 3))], axis=1)
        weights = np.concatenate([forward_w, reverse_w], axis=1).astype(float)
        enough = weights.sum(axis=1) >= 3
        if upright:
            turned = np.einsum("hij,hnj->hni", tilts, src)
            fitted = _fit_yaw(turned, dst, weights, with_scale, scale_range)
            fitted[:, :3, :3] = fitted[:, :3, :3] @ tilts
        else:
            fitted = _fit(src, dst, weights, with_scale, scale_range)
        transforms = np.where(enough[:, None, None], fitted, transforms)
    return transforms


def _fit_yaw(
    src: np.ndarray,
    dst: np.ndarray,
    weights: np.ndarray,
    with_scale: bool,
    scale_range: tuple[float, float],
) -> np.ndarray:
    """Weighted similarity (H, 4, 4) dst ~ s Rz(yaw) src + t, a turn about the world's z
    only: the 2D Procrustes angle of the horizontal parts, then the scale and translation."""
    w = weights / np.maximum(weights.sum(axis=-1, keepdims=True), 1e-300)
    mu_s = np.einsum("hn,hnk->hk", w, src)
    mu_d = np.einsum("hn,hnk->hk", w, dst)
    xs, xd = src - mu_s[:, None], dst - mu_d[:, None]
    a = np.einsum("hn,hn->h", w, xs[..., 0] * xd[..., 0] + xs[..., 1] * xd[..., 1])
    b = np.einsum("hn,hn->h", w, xs[..., 0] * xd[..., 1] - xs[..., 1] * xd[..., 0])
    yaw = np.arctan2(b, a)
    rot = np.zeros((len(yaw), 3, 3))
    rot[:, 0, 0] = rot[:, 1, 1] = np.cos(yaw)
    rot[:, 0, 1], rot[:, 1, 0] = -np.sin(yaw), np.sin(yaw)
    rot[:, 2, 2] = 1.0
    scale = np.ones(len(yaw))
    if with_scale:
        turned = np.einsum("hij,hnj->hni", rot, xs)
        num = np.einsum("hn,hnk,hnk->h", w, xd, turned)
        den = np.maximum(np.einsum("hn,hnk,hnk->h", w, xs, xs), 1e-300)
        scale = np.clip(num / den, *scale_range)
    trans = mu_d - scale[:, None] * np.einsum("hij,hj->hi", rot, mu_s)
    return similarity_matrix(scale, rot, trans)


def _pairs(
    source: np.ndarray,
    surface: Surface,
    target_tree: cKDTree,
    matrix: np.ndarray,
    max_distance: float,
    view: View | None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The view-aware ICP pairs of one affine map (4, 4): sources (P, 3), targets (P, 3) and
    weights (P,)."""
    moved = apply(matrix, source)
    dist, idx = target_tree.query(moved, workers=-1)
    seen = seen_target(surface.points, surface.normals, matrix[None], view)[0]
    gap, jdx = cKDTree(moved).query(surface.points, workers=-1)
    src = np.concatenate([source, source[jdx]])
    dst = np.concatenate([surface.points[idx], surface.points])
    weights = np.concatenate([dist <= max_distance, seen & (gap <= max_distance)])
    return src, dst, weights.astype(float)


def refine_axes(
    source: np.ndarray,
    surface: Surface,
    transform: np.ndarray,
    max_distance: float,
    iterations: int,
    max_stretch: float,
    prior_m: float,
    view: View | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """ICP with a scale per object axis after the similarity ``transform`` (4, 4).

    In the object frame, with x the source mapped by ``transform``, each step fits
    y = D R x + b to the view-aware pairs: R by Kabsch on x against D^-1 y, then each factor
    d_k = (sum w u_k v_k + lam) / (sum w u_k^2 + lam) of centred u = R x, v = y, where
    lam = sum(w) prior_m^2 acts like a spread of ``prior_m`` [m] seen at scale 1, and
    |d_k - 1| <= ``max_stretch``. ``view`` excuses hidden target points as in :func:`icp`.

    Returns:
        The affine map (4, 4) from R_g's camera frame to the world, and D's factors (3,).
    """
    T_wo = surface.T_world_object
    T_ow = np.linalg.inv(T_wo)
    local = Surface(apply(T_ow, surface.points), surface.normals @ T_wo[:3, :3], np.eye(4))
    tree = cKDTree(local.points)
    start = T_ow @ transform
    refine = np.eye(4)
    factors = np.ones(3)
    for _ in range(iterations):
        src, dst, w = _pairs(source, local, tree, refine @ start, max_distance, view)
        if w.sum() < 3:
            break
        x = apply(start, src)
        wn = w / w.sum()
        x_c = x - wn @ x
        y_c = dst - wn @ dst
        _, rot, _ = umeyama(x_c, y_c / factors, w)
        u = x_c @ rot.T
        lam = w.sum() * prior_m**2
        factors = (np.einsum("n,nk,nk->k", w, u, y_c) + lam) / (
            np.einsum("n,nk,nk->k", w, u, u) + lam
        )
        factors = np.clip(factors, 1.0 - max_stretch, 1.0 + max_stretch)
        refine = np.eye(4)
        refine[:3, :3] = factors[:, None] * rot
        refine[:3, 3] = wn @ dst - refine[:3, :3] @ (wn @ x)
    return T_wo @ refine @ start, factors


def overlap_scores(
    source: np.ndarray,
    surface: Surface,
    transforms: np.ndarray,
    distance: float,
    view: View | None = None,
) -> np.ndarray:
    """F-score (H,) of the overlap: the fraction of source points within ``distance`` [m] of
    the target and the fraction of the target points the camera sees (:func:`seen_target`)
    within it of the source."""
    target_tree = cKDTree(surface.points)
    seen_by = seen_target(surface.points, surface.normals, transforms, view)
    scores = np.zeros(len(transforms))
    for k, matrix in enumerate(transforms):
        moved = apply(matrix, source)
        near_target = target_tree.query(moved, distance_upper_bound=distance)[0] <= distance
        seen = surface.points[seen_by[k]]
        if len(seen) == 0:
            continue
        near_source = cKDTree(moved).query(seen, distance_upper_bound=distance)[0] <= distance
        a, b = near_target.mean(), near_source.mean()
        scores[k] = 0.0 if a + b == 0 else 2 * a * b / (a + b)
    return scores


def turn_about_object(transforms: np.ndarray, T_world_object: np.ndarray, turns: int):
    """Every transform (H, 4, 4) composed with turns by 360/turns degrees about the object's
    vertical axis: (H, turns, 4, 4)."""
    out = []
    for k in range(turns):
        angle = 2.0 * np.pi * k / turns
        rz = np.eye(4)
        rz[:2, :2] = [[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]]
        out.append(T_world_object @ rz @ np.linalg.inv(T_world_object) @ transforms)
    return np.stack(out, axis=1)


def level(transforms: np.ndarray, up_gen: np.ndarray, pivot_gen: np.ndarray) -> np.ndarray:
    """Transforms (H, 4, 4) turned about the image of ``pivot_gen`` by the smallest rotation
    that maps the gen frame's up direction onto the world's +z: objects stand upright."""
    out = np.array(transforms, dtype=float)
    for k, matrix in enumerate(out):
        linear = matrix[:3, :3].copy()
        up = linear @ up_gen
        up /= np.linalg.norm(up)
        axis = np.cross(up, UP)
        sin, cos = np.linalg.norm(axis), float(up @ UP)
        if sin < 1e-12:
            continue
        axis /= sin
        skew = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
        fix = np.eye(3) + sin * skew + (1.0 - cos) * skew @ skew
        pivot = linear @ pivot_gen + matrix[:3, 3]
        out[k, :3, :3] = fix @ linear
        out[k, :3, 3] = pivot - fix @ linear @ pivot_gen
    return out


def tilt_errors(transforms: np.ndarray, up_gen: np.ndarray | None) -> np.ndarray:
    """Angle [deg] (H,) between the mapped up direction of the gen frame and world +z."""
    if up_gen is None:
        return np.zeros(len(transforms))
    up = np.einsum("hij,j->hi", transforms[:, :3, :3], up_gen)
    up /= np.linalg.norm(up, axis=1, keepdims=True)
    return np.degrees(np.arccos(np.clip(up[:, 2], -1.0, 1.0)))


def facing_errors(
    transforms: np.ndarray, facing_gen: np.ndarray | None, T_world_object: np.ndarray
) -> np.ndarray:
    """Angle [deg] (H,) between the person's horizontal facing, mapped by each transform
    into the object frame, and the object's +x (the person faces the approach side)."""
    if facing_gen is None:
        return np.full(len(transforms), np.nan)
    world = np.einsum("hij,j->hi", transforms[:, :3, :3], facing_gen)
    local = world @ T_world_object[:3, :3]
    return np.degrees(np.abs(np.arctan2(local[:, 1], local[:, 0])))


def gates(tilts: np.ndarray, facing: np.ndarray, cfg: RegistrationCfg) -> np.ndarray:
    """The hypotheses (H,) the winner is chosen among: those that keep the object upright
    (tilt within ``max_tilt_deg``) and face the person to the approach side (facing error
    within ``max_facing_deg``; NaN, when the facing is unknown, passes). Each gate is
    dropped when no hypothesis passes it."""
    keep = tilts <= cfg.max_tilt_deg
    if not keep.any():
        keep = np.ones_like(keep)
    facing_ok = keep & ~(facing > cfg.max_facing_deg)
    return facing_ok if facing_ok.any() else keep


def select(overlaps: np.ndarray, keep: np.ndarray) -> int:
    """Index of the winner: the best overlap among the hypotheses ``keep`` lets through."""
    return int(np.argmax(np.where(keep, overlaps, -np.inf)))


def register(
    source: np.ndarray,
    surface: Surface,
    matches_src: np.ndarray,
    matches_dst: np.ndarray,
    valid: np.ndarray,
    person: Person,
    view: View | None,
    cfg: RegistrationCfg,
    rng: np.random.Generator,
    where: str,
) -> Registration:
    """Best similarity from the source cloud onto the object's surface.

    Args:
        source: R_g object cloud (N, 3), gen frame [m].
        surface: The simulated object's surface, scene world.
        matches_src: (S, 3) lifted sampled points of R_g [m].
        matches_dst: (S, T, 3) lifted top-T candidates in R_s, scene world [m].
        valid: (S, T) candidates with depth.
        person: The person's up and facing directions in the gen frame.
        view: R_g's depth, to excuse the surface hidden behind nearer things; None counts
            every camera-facing point.
        cfg: Registration settings.
        rng: Draws the hypotheses and thins the source cloud.
        where: Names the subtask in errors.

    Raises:
        SceneError: When fewer than three sampled points have a candidate with depth.
    """
    usable = valid.any(axis=1)
    if usable.sum() < 3:
        raise SceneError(
            f"{where}: only {int(usable.sum())} sampled points have a match with depth; "
            "registration needs 3"
        )
    matches_src, matches_dst, valid = matches_src[usable], matches_dst[usable], valid[usable]
    choice = draw_hypotheses(valid, cfg.iterations, rng)
    dst = np.take_along_axis(matches_dst[None], choice[..., None, None], axis=2)[:, :, 0]
    src = np.broadcast_to(matches_src, dst.shape)
    with_scale = cfg.transform == "similarity"
    scale_range = (float(cfg.scale_range[0]), float(cfg.scale_range[1]))
    starts = robust_svd(src, dst, with_scale, cfg.trim_rounds, scale_range)
    if person.up is not None:
        starts = level(starts, person.up, source.mean(axis=0))
    turned = turn_about_object(starts, surface.T_world_object, cfg.symmetry_turns)
    if len(source) > cfg.icp_points:
        source = source[np.sort(rng.choice(len(source), cfg.icp_points, replace=False))]
    size = float(np.linalg.norm(np.ptp(surface.points, axis=0)))
    flat = icp(
        source,
        surface,
        turned.reshape(-1, 4, 4),
        cfg.icp_distance * size,
        cfg.icp_iterations,
        with_scale,
        scale_range,
        upright=cfg.upright and person.up is not None,
        view=view,
    )
    overlaps = overlap_scores(source, surface, flat, cfg.overlap_distance * size, view)
    tilts = tilt_errors(flat, person.up)
    facing = facing_errors(flat, person.facing, surface.T_world_object)
    keep = gates(tilts, facing, cfg)
    best = select(overlaps, keep)
    shape = turned.shape[:2]
    iteration, turn = np.unravel_index(best, shape)
    affine, stretch = refine_axes(
        source,
        surface,
        flat[best],
        cfg.icp_distance * size,
        cfg.stretch_iterations,
        cfg.max_stretch,
        cfg.stretch_prior_m,
        view,
    )
    return Registration(
        transform=flat[best],
        affine=affine,
        stretch=stretch,
        overlap=float(overlaps[best]),
        iteration=int(iteration) + 1,
        turn=int(turn),
        overlaps=overlaps.reshape(shape),
        scales=np.cbrt(np.linalg.det(flat[:, :3, :3])).reshape(shape),
        tilt_deg=tilts.reshape(shape),
        facing_error_deg=facing.reshape(shape),
        candidates=flat.reshape(*shape, 4, 4),
        gated=keep.reshape(shape),
    )
