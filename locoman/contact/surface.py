"""Closest points on the surfaces of objects built from primitives (box, cylinder, sphere).

Paper A, Sec. III-A.2, last step: "to avoid penetrations between the real object and L, we
apply a simple heuristic to L to make sure these are projected to the closest object's
surface". An object is a union of primitives in its own frame (``locoman.scene.objects``);
the closest point of the union's surface is the closest point on any primitive's surface that
is not buried inside another primitive. Feet may only stand on upward surfaces: the floor and
the tops of the primitives.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from locoman.scene.objects import BOX, CYLINDER, SPHERE, ContactPatch, Primitive

BURIED_TOL = 1e-9  # [m] a surface point deeper than this inside another primitive is buried
ON_SURFACE_TOL = 1e-6  # [m] a patch centre this close to a primitive's surface lies on it
UP = np.array([0.0, 0.0, 1.0])


def signed_distance(points: np.ndarray, prim: Primitive) -> np.ndarray:
    """Signed distance (N,) [m] of points (N, 3) to a primitive: < 0 inside, > 0 outside."""
    p = np.asarray(points, dtype=float) - np.asarray(prim.pos)
    if prim.shape == BOX:
        q = np.abs(p) - np.asarray(prim.size)
        outside = np.linalg.norm(np.maximum(q, 0.0), axis=1)
        return outside + np.minimum(q.max(axis=1), 0.0)
    if prim.shape == CYLINDER:
        r, hh = prim.size
        q = np.stack([np.linalg.norm(p[:, :2], axis=1) - r, np.abs(p[:, 2]) - hh], axis=1)
        return np.linalg.norm(np.maximum(q, 0.0), axis=1) + np.minimum(q.max(axis=1), 0.0)
    if prim.shape == SPHERE:
        return np.linalg.norm(p, axis=1) - prim.size[0]
    raise ValueError(f"unknown primitive shape {prim.shape!r}")


def closest_on_primitive(points: np.ndarray, prim: Primitive) -> tuple[np.ndarray, np.ndarray]:
    """Closest surface points (N, 3) [m] and outward unit normals (N, 3) of one primitive,
    for points inside or outside it."""
    centre = np.asarray(prim.pos, dtype=float)
    p = np.asarray(points, dtype=float) - centre
    if prim.shape == BOX:
        q, n = _box_surface(p, np.asarray(prim.size, dtype=float))
    elif prim.shape == CYLINDER:
        q, n = _cylinder_surface(p, *prim.size)
    elif prim.shape == SPHERE:
        n = _unit(p, fallback=UP)
        q = prim.size[0] * n
    else:
        raise ValueError(f"unknown primitive shape {prim.shape!r}")
    return q + centre, n


def _unit(v: np.ndarray, fallback: np.ndarray) -> np.ndarray:
    norm = np.linalg.norm(v, axis=-1, keepdims=True)
    return np.where(norm > 1e-12, v / np.maximum(norm, 1e-12), fallback)


def _box_surface(p: np.ndarray, half: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    q = np.clip(p, -half, half)
    inside = np.all(np.abs(p) < half, axis=1)
    # Inside: leave through the nearest face. Outside: the clamped point; its face is the
    # axis along which the point sticks out furthest relative to the box.
    gap = half - np.abs(p)
    axis = np.where(inside, gap.argmin(axis=1), (np.abs(p) / half).argmax(axis=1))
    rows = np.arange(len(p))
    sign = np.where(p[rows, axis] >= 0.0, 1.0, -1.0)
    q[rows[inside], axis[inside]] = sign[inside] * half[axis[inside]]
    n = np.zeros_like(p)
    n[rows, axis] = sign
    outside = ~inside & (np.linalg.norm(p - q, axis=1) > 1e-12)
    n[outside] = _unit(p[outside] - q[outside], fallback=UP)
    return q, n


def _cylinder_surface(p: np.ndarray, r: float, hh: float) -> tuple[np.ndarray, np.ndarray]:
    radial = np.linalg.norm(p[:, :2], axis=1)
    dirs = _unit(np.column_stack([p[:, :2], np.zeros(len(p))]), np.array([1.0, 0.0, 0.0]))
    inside = (radial < r) & (np.abs(p[:, 2]) < hh)
    to_cap = inside & (hh - np.abs(p[:, 2]) < r - radial)
    q = p.copy()
    q[:, :2] = np.where(radial[:, None] > r, dirs[:, :2] * r, p[:, :2])
    q[:, 2] = np.clip(p[:, 2], -hh, hh)
    side = inside & ~to_cap
    q[side, :2] = dirs[side, :2] * r
    sign = np.where(p[:, 2] >= 0.0, 1.0, -1.0)
    q[to_cap, 2] = sign[to_cap] * hh
    n = np.where(to_cap[:, None], sign[:, None] * UP, dirs)
    outside = ~inside & (np.linalg.norm(p - q, axis=1) > 1e-12)
    n[outside] = _unit(p[outside] - q[outside], fallback=UP)
    return q, n


def project_to_surface(
    points: np.ndarray, primitives: Sequence[Primitive], onto: Sequence[Primitive] | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Closest points (N, 3) [m] on the surface of a union of primitives, and outward normals.

    Points inside the object move out to its surface; points outside move onto it. The
    result lies on or outside every primitive. ``onto`` (default: all of ``primitives``)
    restricts the surface to some of them, e.g. the parts a hand holds (:func:`held_parts`).
    """
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    candidates = [closest_on_primitive(points, prim) for prim in (onto or primitives)]
    return _pick_unburied(points, candidates, primitives)


def held_parts(
    primitives: Sequence[Primitive], patches: Sequence[ContactPatch]
) -> tuple[Primitive, ...]:
    """The primitives a hand may hold: those whose surface carries a contact patch's centre
    (a trolley's handle bar and platform, not its posts, struts or wheels; a table's top, not
    its legs); all of them when none does."""
    centres = np.array([p.centre for p in patches], dtype=float).reshape(-1, 3)
    held = tuple(
        prim
        for prim in primitives
        if np.any(np.abs(signed_distance(centres, prim)) < ON_SURFACE_TOL)
    )
    return held or tuple(primitives)


def project_to_support(
    points: np.ndarray, primitives: Sequence[Primitive], floor_z: float | None
) -> tuple[np.ndarray, np.ndarray]:
    """Closest points (N, 3) [m] on upward surfaces a foot can stand on: the tops of the
    primitives and, unless None, the floor plane z = ``floor_z`` (object frame) [m]."""
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    candidates = []
    for prim in primitives:
        centre = np.asarray(prim.pos, dtype=float)
        if prim.shape == BOX:
            half = np.asarray(prim.size, dtype=float)
            q = np.column_stack(
                [
                    np.clip(points[:, :2], centre[:2] - half[:2], centre[:2] + half[:2]),
                    np.full(len(points), centre[2] + half[2]),
                ]
            )
        elif prim.shape == CYLINDER:
            r, hh = prim.size
            offset = points[:, :2] - centre[:2]
            radial = np.linalg.norm(offset, axis=1, keepdims=True)
            xy = centre[:2] + offset * np.minimum(1.0, r / np.maximum(radial, 1e-12))
            q = np.column_stack([xy, np.full(len(points), centre[2] + hh)])
        else:
            continue
        candidates.append((q, np.tile(UP, (len(points), 1))))
    if floor_z is not None:
        floor = points.copy()
        floor[:, 2] = floor_z
        candidates.append((floor, np.tile(UP, (len(points), 1))))
    return _pick_unburied(points, candidates, primitives)


def _pick_unburied(
    points: np.ndarray,
    candidates: list[tuple[np.ndarray, np.ndarray]],
    primitives: Sequence[Primitive],
) -> tuple[np.ndarray, np.ndarray]:
    q = np.stack([c[0] for c in candidates])  # (M, N, 3)
    n = np.stack([c[1] for c in candidates])
    dist = np.linalg.norm(q - points[None], axis=2)
    for prim in primitives:
        depth = signed_distance(q.reshape(-1, 3), prim).reshape(dist.shape)
        dist = np.where(depth < -BURIED_TOL, np.inf, dist)
    best = dist.argmin(axis=0)
    cols = np.arange(len(points))
    return q[best, cols], n[best, cols]


def sample_surface(
    primitives: Sequence[Primitive], count: int, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """About ``count`` points (M, 3) [m] spread uniformly over the union's outer surface, and
    their outward normals (M, 3).

    Points are drawn on each primitive's surface in proportion to its area; those buried
    inside another primitive are dropped.
    """
    areas = np.array([_area(p) for p in primitives])
    counts = np.maximum(np.round(count * areas / areas.sum()).astype(int), 1)
    points, normals = [], []
    for prim, n in zip(primitives, counts, strict=True):
        p = _sample_primitive(prim, n, rng)
        points.append(p)
        normals.append(closest_on_primitive(p, prim)[1])
    pts, nrm = np.vstack(points), np.vstack(normals)
    keep = np.ones(len(pts), dtype=bool)
    for prim in primitives:
        keep &= signed_distance(pts, prim) >= -1e-6
    return pts[keep], nrm[keep]


def _area(prim: Primitive) -> float:
    if prim.shape == BOX:
        x, y, z = (2.0 * s for s in prim.size)
        return 2.0 * (x * y + y * z + x * z)
    if prim.shape == CYLINDER:
        r, hh = prim.size
        return 2.0 * np.pi * r * (r + 2.0 * hh)
    return 4.0 * np.pi * prim.size[0] ** 2


def _sample_primitive(prim: Primitive, n: int, rng: np.random.Generator) -> np.ndarray:
    """Uniform random points (n, 3) [m] on a primitive's surface."""
    centre = np.asarray(prim.pos, dtype=float)
    if prim.shape == BOX:
        half = np.asarray(prim.size, dtype=float)
        face_area = np.array([half[1] * half[2], half[0] * half[2], half[0] * half[1]])
        axis = rng.choice(3, size=n, p=face_area / face_area.sum())
        p = rng.uniform(-half, half, size=(n, 3))
        p[np.arange(n), axis] = rng.choice([-1.0, 1.0], size=n) * half[axis]
        return p + centre
    if prim.shape == SPHERE:
        direction = rng.normal(size=(n, 3))
        return centre + prim.size[0] * direction / np.linalg.norm(direction, axis=1, keepdims=True)
    r, hh = prim.size
    # Side area 4 pi r hh against 2 pi r^2 for both caps: z beyond +-hh (by up to r / 2) is a cap.
    z = rng.uniform(-hh - 0.5 * r, hh + 0.5 * r, size=n)
    angle = rng.uniform(0.0, 2.0 * np.pi, size=n)
    side = np.abs(z) <= hh
    radius = np.where(side, r, r * np.sqrt(rng.uniform(0.0, 1.0, size=n)))
    p = np.column_stack([radius * np.cos(angle), radius * np.sin(angle), np.clip(z, -hh, hh)])
    return p + centre
