"""Object kinds, built from primitive shapes, with their contact patches.

Every kind is a function from the object's extents to its primitive geoms and named contact
patches, registered in :data:`OBJECT_KINDS` (add a kind by registering a function). Frames:
the object's origin is the centre of its bottom face, x forward, z up.

A contact patch is a planar rectangle on the object's surface where a hand or a foot may act
(paper A, Sec. IV-B.1): centre and outward normal in the object frame, and half extents.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence

import numpy as np

from locoman.errors import ConfigError

BOX, CYLINDER, SPHERE = "box", "cylinder", "sphere"
PANEL = 0.02  # [m] thickness of table tops, shelf planks and basket walls


@dataclasses.dataclass(frozen=True)
class Primitive:
    """A primitive collision shape in the object frame.

    Attributes:
        shape: ``box`` (size = half extents x, y, z [m]), ``cylinder`` (radius, half height)
            or ``sphere`` (radius).
        pos: Centre [m].
        name: Part name, e.g. ``top`` or ``leg_0``.
    """

    shape: str
    size: tuple[float, ...]
    pos: tuple[float, float, float]
    name: str


def primitive_half_extents(shape: str, size: tuple[float, ...]) -> np.ndarray:
    """Half extents (3,) [m] of a primitive's bounding box in its own frame."""
    if shape == "box":
        return np.asarray(size, float)
    if shape == "cylinder":
        return np.array([size[0], size[0], size[1]])
    return np.full(3, size[0])


def bounding_box(primitives: Sequence[Primitive]) -> tuple[np.ndarray, np.ndarray]:
    """Lower and upper corners (3,), (3,) [m] of the box around ``primitives``, object
    frame."""
    lo = [np.asarray(p.pos) - primitive_half_extents(p.shape, p.size) for p in primitives]
    hi = [np.asarray(p.pos) + primitive_half_extents(p.shape, p.size) for p in primitives]
    return np.min(lo, axis=0), np.max(hi, axis=0)


@dataclasses.dataclass(frozen=True)
class ContactPatch:
    """A rectangular contact surface in the object frame.

    Attributes:
        name: e.g. ``left`` for the +y face of a box.
        centre: Patch centre [m].
        normal: Outward unit normal.
        half_extents: Half sizes [m] along the two in-plane axes.
    """

    name: str
    centre: tuple[float, float, float]
    normal: tuple[float, float, float]
    half_extents: tuple[float, float]


@dataclasses.dataclass(frozen=True)
class ObjectGeometry:
    """Primitives and contact patches of one object."""

    primitives: tuple[Primitive, ...]
    patches: tuple[ContactPatch, ...]


def _box_patches(lx: float, ly: float, lz: float, z0: float = 0.0) -> tuple[ContactPatch, ...]:
    hx, hy, hz = lx / 2, ly / 2, lz / 2
    c = z0 + hz
    return (
        ContactPatch("front", (hx, 0.0, c), (1.0, 0.0, 0.0), (hy, hz)),
        ContactPatch("back", (-hx, 0.0, c), (-1.0, 0.0, 0.0), (hy, hz)),
        ContactPatch("left", (0.0, hy, c), (0.0, 1.0, 0.0), (hx, hz)),
        ContactPatch("right", (0.0, -hy, c), (0.0, -1.0, 0.0), (hx, hz)),
        ContactPatch("top", (0.0, 0.0, z0 + lz), (0.0, 0.0, 1.0), (hx, hy)),
    )


def box_geometry(size: Sequence[float]) -> ObjectGeometry:
    """A solid box; ``size`` = (length, width, height) [m]."""
    lx, ly, lz = _expect(size, 3, BOX)
    return ObjectGeometry(
        (Primitive(BOX, (lx / 2, ly / 2, lz / 2), (0.0, 0.0, lz / 2), "body"),),
        _box_patches(lx, ly, lz),
    )


def cylinder_geometry(size: Sequence[float]) -> ObjectGeometry:
    """An upright cylinder (a bottle); ``size`` = (radius, height) [m]."""
    r, h = _expect(size, 2, CYLINDER)
    side = ContactPatch("side", (0.0, 0.0, h / 2), (1.0, 0.0, 0.0), (r, h / 2))
    top = ContactPatch("top", (0.0, 0.0, h), (0.0, 0.0, 1.0), (r, r))
    return ObjectGeometry(
        (Primitive(CYLINDER, (r, h / 2), (0.0, 0.0, h / 2), "body"),), (side, top)
    )


def table_geometry(size: Sequence[float]) -> ObjectGeometry:
    """A table: top slab and four legs; ``size`` = (length, width, height of the top) [m]."""
    lx, ly, lz = _expect(size, 3, "table")
    leg = 0.03
    parts = [Primitive(BOX, (lx / 2, ly / 2, PANEL / 2), (0.0, 0.0, lz - PANEL / 2), "top")]
    for i, (sx, sy) in enumerate(((1, 1), (1, -1), (-1, 1), (-1, -1))):
        pos = (sx * (lx / 2 - leg), sy * (ly / 2 - leg), (lz - PANEL) / 2)
        parts.append(Primitive(BOX, (leg, leg, (lz - PANEL) / 2), pos, f"leg_{i}"))
    top = ContactPatch("top", (0.0, 0.0, lz), (0.0, 0.0, 1.0), (lx / 2, ly / 2))
    return ObjectGeometry(tuple(parts), (top,))


def shelf_geometry(size: Sequence[float]) -> ObjectGeometry:
    """An open shelf: two side panels, a middle and a top plank; ``size`` = (depth, width,
    height of the top plank's upper face) [m]."""
    lx, ly, lz = _expect(size, 3, "shelf")
    parts = [
        Primitive(BOX, (lx / 2, PANEL / 2, lz / 2), (0.0, sy * (ly - PANEL) / 2, lz / 2), name)
        for sy, name in ((1, "side_left"), (-1, "side_right"))
    ]
    inner = ly / 2 - PANEL
    parts.append(Primitive(BOX, (lx / 2, inner, PANEL / 2), (0.0, 0.0, lz - PANEL / 2), "top"))
    parts.append(Primitive(BOX, (lx / 2, inner, PANEL / 2), (0.0, 0.0, lz / 2), "middle"))
    top = ContactPatch("top", (0.0, 0.0, lz), (0.0, 0.0, 1.0), (lx / 2, ly / 2))
    return ObjectGeometry(tuple(parts), (top,))


def basket_geometry(size: Sequence[float]) -> ObjectGeometry:
    """An open laundry basket: a floor and four walls; ``size`` = (length, width, height) [m].

    Its hand patches are the outer faces of the two side walls (``left``, ``right``).
    """
    lx, ly, lz = _expect(size, 3, "basket")
    t = PANEL / 2
    parts = [
        Primitive(BOX, (lx / 2, ly / 2, t), (0.0, 0.0, t), "floor"),
        Primitive(BOX, (t, ly / 2, lz / 2), (lx / 2 - t, 0.0, lz / 2), "wall_front"),
        Primitive(BOX, (t, ly / 2, lz / 2), (-lx / 2 + t, 0.0, lz / 2), "wall_back"),
        Primitive(BOX, (lx / 2 - PANEL, t, lz / 2), (0.0, ly / 2 - t, lz / 2), "wall_left"),
        Primitive(BOX, (lx / 2 - PANEL, t, lz / 2), (0.0, -ly / 2 + t, lz / 2), "wall_right"),
    ]
    patches = tuple(p for p in _box_patches(lx, ly, lz) if p.name != "top")
    return ObjectGeometry(tuple(parts), patches)


TROLLEY_WHEEL_RADIUS = 0.05  # [m]
TROLLEY_HANDLE_RISE = 0.4  # [m] handle bar above the platform


def trolley_geometry(size: Sequence[float]) -> ObjectGeometry:
    """A platform trolley with a push handle at its back (-x) end.

    ``size`` = (length, width, platform top height) [m]. Four wheels carry the platform; the
    chassis contact frame for the nonholonomic constraint (paper A, eq. (7)) is the origin.
    Hand patches: ``handle`` (the bar, facing -x) and ``platform`` (its top, for loads).
    """
    lx, ly, lz = _expect(size, 3, "trolley")
    r = TROLLEY_WHEEL_RADIUS
    parts = [Primitive(BOX, (lx / 2, ly / 2, PANEL / 2), (0.0, 0.0, lz - PANEL / 2), "platform")]
    # Chassis struts from the wheel axles up to the platform.
    strut_h = (lz - PANEL - r) / 2
    for i, (sx, sy) in enumerate(((1, 1), (1, -1), (-1, 1), (-1, -1))):
        xy = (sx * (lx / 2 - r), sy * (ly / 2 - r))
        parts.append(Primitive(SPHERE, (r,), (xy[0], xy[1], r), f"wheel_{i}"))
        parts.append(
            Primitive(BOX, (0.015, 0.015, strut_h), (xy[0], xy[1], r + strut_h), f"strut_{i}")
        )
    post_h = TROLLEY_HANDLE_RISE / 2
    for sy, name in ((1, "post_left"), (-1, "post_right")):
        parts.append(
            Primitive(
                BOX,
                (0.015, 0.015, post_h),
                (-lx / 2 + 0.015, sy * (ly / 2 - 0.015), lz + post_h),
                name,
            )
        )
    bar_z = lz + TROLLEY_HANDLE_RISE
    parts.append(Primitive(BOX, (0.015, ly / 2, 0.015), (-lx / 2 + 0.015, 0.0, bar_z), "handle"))
    patches = (
        ContactPatch("handle", (-lx / 2, 0.0, bar_z), (-1.0, 0.0, 0.0), (ly / 2, 0.015)),
        ContactPatch("platform", (0.0, 0.0, lz), (0.0, 0.0, 1.0), (lx / 2, ly / 2)),
    )
    return ObjectGeometry(tuple(parts), patches)


OBJECT_KINDS: dict[str, Callable[[Sequence[float]], ObjectGeometry]] = {
    "box": box_geometry,
    "cylinder": cylinder_geometry,
    "table": table_geometry,
    "shelf": shelf_geometry,
    "basket": basket_geometry,
    "trolley": trolley_geometry,
}


def object_geometry(kind: str, size: Sequence[float]) -> ObjectGeometry:
    """Primitives and patches of a registered object kind."""
    try:
        build = OBJECT_KINDS[kind]
    except KeyError:
        raise ConfigError(
            f"unknown object kind {kind!r}; registered: {sorted(OBJECT_KINDS)}"
        ) from None
    return build(size)


def _expect(size: Sequence[float], n: int, kind: str) -> tuple[float, ...]:
    if len(size) != n:
        raise ConfigError(f"a {kind} needs {n} size values [m], got {list(size)}")
    return tuple(float(s) for s in size)


def patch_corners(patch: ContactPatch) -> np.ndarray:
    """The four corners (4, 3) of a patch in the object frame [m]."""
    n = np.asarray(patch.normal)
    helper = np.array([0.0, 0.0, 1.0]) if abs(n[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    u = np.cross(helper, n)
    u /= np.linalg.norm(u)
    v = np.cross(n, u)
    a, b = patch.half_extents
    c = np.asarray(patch.centre)
    return np.array([c + sa * a * u + sb * b * v for sa in (-1, 1) for sb in (-1, 1)])
