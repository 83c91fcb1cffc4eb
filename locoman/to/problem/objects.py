"""The objects of a TO problem: a carried or pushed object's rigid-body model
(:class:`ObjectModel`, its mass, inertia, faces and boxes) and a fixed object as the box
the robot and the objects keep out of (:class:`Obstacle`)."""

from __future__ import annotations

import dataclasses

import numpy as np

from locoman.scene.rotations import rpy_to_matrix


@dataclasses.dataclass(frozen=True)
class Obstacle:
    """A fixed box of the scene.

    Attributes:
        name: ``<object>/<primitive>``.
        centre: (3,) world [m].
        yaw: About world z [rad].
        half_extents: (3,) [m].
    """

    name: str
    centre: np.ndarray
    yaw: float
    half_extents: np.ndarray

    @property
    def rotation(self) -> np.ndarray:
        return rpy_to_matrix(np.array([0.0, 0.0, self.yaw]))


def obstacles_from_objects(objects: dict[str, dict]) -> tuple[Obstacle, ...]:
    """One box per fixed object of the scene (``objects.json``): the bounding box of its
    primitives in the object's frame (a table's top and legs make one block, so that nothing
    passes under the top)."""
    out = []
    for name, spec in sorted(objects.items()):
        if spec["movable"]:
            continue
        lows, highs = [], []
        for prim in spec["primitives"]:
            if prim["shape"] != "box":
                raise ValueError(
                    f"{name}/{prim['name']}: the TO's collision model knows boxes, "
                    f"not {prim['shape']!r}"
                )
            lows.append(np.asarray(prim["pos"]) - prim["size"])
            highs.append(np.asarray(prim["pos"]) + prim["size"])
        if not lows:
            continue
        low, high = np.min(lows, axis=0), np.max(highs, axis=0)
        R = rpy_to_matrix(np.array([0.0, 0.0, spec["yaw_rad"]]))
        centre = np.asarray(spec["pos_m"], dtype=float) + R @ (0.5 * (low + high))
        out.append(Obstacle(name, centre, float(spec["yaw_rad"]), 0.5 * (high - low)))
    return tuple(out)


@dataclasses.dataclass(frozen=True)
class ObjectModel:
    """A rigid object of the scene (paper A: objects obey the same dynamics (1)).

    Attributes:
        name: Object name in the scene.
        mass: [kg].
        inertia: (3, 3) about the CoM, body axes [kg m^2].
        com: (3,) CoM in the body frame [m]; the body frame sits at the bottom face's centre
            (a trolley's: the chassis contact frame on the ground below its platform centre);
            a solid object's collision box is its bottom patch up to twice the CoM's height.
        half_extents: (2,) half sizes of the bottom patch [m] (a trolley's: of its wheelbase).
        friction: Coefficient of its surfaces [-].
        solid: Its bounding box is solid, so that the robot's body and the obstacles are
            kept out of it (a trolley's open frame and a basket are not: their ``parts``).
        prehensile: The hands grasp it (a handle): their contacts drop (3) (Sec. IV-A.2).
        rear_axle_x: A wheeled chassis (Sec. IV-A.3): x of its fixed-direction (rear)
            wheels' axle in its frame [m]; None for an object that rests on a face.
        parts: The collision boxes of an object that is not solid as a whole, each
            (centre (3,), half sizes (3,)) in its frame [m]: a trolley's chassis (platform,
            struts and wheels) and its handle frame, which the robot's body must keep out
            of while it walks round and pushes.
        wheels: A wheeled object's wheels as boxes (centre (3,), half sizes (3,)) in its
            frame [m]: what the feet keep out of (its platform is over them: its chassis
            box would keep the feet a stride back from the handle).
        reached_from_outside: A hand that holds nothing keeps out of its bounding box, not
            only its parts: it takes the object from outside. A basket's parts leave its
            inside free, and a palm crossed a 20 mm wall between two nodes into it.
    """

    name: str
    mass: float
    inertia: np.ndarray
    com: np.ndarray
    half_extents: np.ndarray
    friction: float
    solid: bool = True
    prehensile: bool = False
    rear_axle_x: float | None = None
    parts: tuple[tuple[tuple[float, ...], tuple[float, ...]], ...] = ()
    wheels: tuple[tuple[tuple[float, ...], tuple[float, ...]], ...] = ()
    reached_from_outside: bool = False

    @property
    def wheeled(self) -> bool:
        return self.rear_axle_x is not None

    @classmethod
    def from_spec(cls, name: str, spec: dict) -> ObjectModel:
        """The object of the scene's object table (``objects.json``) entry ``spec``: a
        trolley (kind ``trolley``) is a wheeled chassis with the mass of a box of its size,
        the wheels' layout read from its ``wheel_*`` primitives; a basket an open box, its
        floor and walls its parts, reached from outside; anything else a solid box."""
        size = np.array(spec["size_m"], dtype=float)
        model = cls.box(name, size, spec["mass_kg"], spec["friction"])
        primitives = spec["primitives"]
        if spec["kind"] == "basket":
            # Open: a hand holding a wall keeps its forearm out of the floor and the walls
            # (as a solid box its holding forearm went unchecked, 5 cm into the floor).
            return dataclasses.replace(
                model, solid=False, parts=_boxes(primitives), reached_from_outside=True
            )
        if spec["kind"] != "trolley":
            return model
        wheels = np.array([p["pos"][:2] for p in primitives if p["name"].startswith("wheel")])
        return dataclasses.replace(
            model,
            half_extents=np.abs(wheels).max(axis=0),
            solid=False,
            prehensile=True,
            rear_axle_x=float(wheels[wheels[:, 0] < 0.0, 0].mean()),
            parts=_chassis_and_frame(primitives),
            wheels=_boxes([p for p in primitives if p["name"].startswith("wheel")]),
        )

    @classmethod
    def box(cls, name: str, size: np.ndarray, mass: float, friction: float) -> ObjectModel:
        """A solid box of full ``size`` (3,) [m] with its frame at the bottom centre."""
        a, b, c = np.asarray(size, dtype=float)
        inertia = mass / 12.0 * np.diag([b * b + c * c, a * a + c * c, a * a + b * b])
        com = np.array([0.0, 0.0, c / 2])
        return cls(name, mass, inertia, com, np.array([a, b]) / 2, friction)


def _chassis_and_frame(primitives: list[dict]) -> tuple:
    """A trolley's two collision boxes (centre, half sizes) in its frame [m]: the bounding
    box of what lies up to the platform's top (platform, struts, wheels), and that of what
    rises above it (the handle's posts and bar)."""
    low = np.array([np.asarray(p["pos"]) - _half_sizes(p) for p in primitives])
    high = np.array([np.asarray(p["pos"]) + _half_sizes(p) for p in primitives])
    top = next(high[i, 2] for i, p in enumerate(primitives) if p["name"] == "platform")
    chassis = high[:, 2] <= top + 1e-9
    boxes = []
    for rows in (chassis, ~chassis):
        if rows.any():
            lo, hi = low[rows].min(axis=0), high[rows].max(axis=0)
            boxes.append((tuple((0.5 * (lo + hi)).tolist()), tuple((0.5 * (hi - lo)).tolist())))
    return tuple(boxes)


def _boxes(primitives: list[dict]) -> tuple:
    """Each primitive as a collision box (centre, half sizes) in its object's frame [m]."""
    return tuple((tuple(map(float, p["pos"])), tuple(_half_sizes(p).tolist())) for p in primitives)


def _half_sizes(primitive: dict) -> np.ndarray:
    """(3,) half sizes of a box or sphere primitive of ``objects.json`` [m]."""
    size = np.asarray(primitive["size"], dtype=float)
    return np.repeat(size, 3) if primitive["shape"] == "sphere" else size
