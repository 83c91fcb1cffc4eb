"""The TO's global runtime parameters: every number that a sweep or a user changes without
changing the problem's shape (DESIGN.md, "Structure vs parameters").

The compiled functions take them as an input, one vector shared by every node, so the C
code, and the cache of compiled libraries keyed by its hash, depends on the structure alone
(node count, contact schedule, which contact and collision kinds exist): a new box mass,
friction, cost weight or obstacle position re-solves without compiling. The references and
switches that vary along the trajectory are the per-node parameters of
:data:`locoman.to.layout.PARAMETERS`.

The vector holds, by name:

- ``weights.<field>``: every weight and reference of :class:`CostWeights` (Table I, (9),
  (10), the object goal, the collision weight; the clearance, base height and dt
  references);
- ``contact.<field>``: floor friction [-], the stiffness k_z of (2a) [1/s], the palm's
  half sizes [m];
- ``collision.<field>``: margin [m], smoothing [m], length L [m], softness [-] of (11), (12);
- ``object<j>.<field>``: each object's mass [kg], inertia about its CoM (3x3, body axes,
  column-major) [kg m^2], CoM in its frame [m], half sizes [m], friction [-];
- ``obstacle<i>.<field>``: each fixed box's centre [m], yaw [rad] and half sizes [m].

The symbolic side (:class:`SymbolicGlobals`) hands out the same configuration objects with
CasADi symbols in place of the numbers, so the cost and constraint code reads
``weights.slack`` whichever side built it.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import casadi as ca
import numpy as np

from locoman.to.collision import CollisionCfg, Obstacle
from locoman.to.costs import CostWeights
from locoman.to.layout import ObjectModel

# CostWeights fields that are switches of the structure, not numbers of the problem.
_WEIGHT_SWITCHES = ("average_over_nodes",)
_CONTACT_FIELDS = ("floor_friction", "stiffness", "palm_half_extents_m")
_COLLISION_FIELDS = ("margin_m", "smoothing_m", "length_m", "softness")
_OBJECT_FIELDS = ("mass", "inertia", "com", "half_extents", "friction")
_OBSTACLE_FIELDS = ("centre", "yaw", "half_extents")


def _flat(value) -> np.ndarray:
    """Column-major flat float array of a number, list or matrix."""
    return np.asarray(value, dtype=float).ravel(order="F")


@dataclasses.dataclass(frozen=True)
class GlobalParameters:
    """The numeric values of the global parameters, by name, in layout order.

    Attributes:
        values: name -> flat values (matrices column-major, as CasADi reshapes them).
    """

    values: dict[str, np.ndarray]

    @classmethod
    def of(
        cls,
        weights: CostWeights,
        contact,
        collision: CollisionCfg,
        objects: Sequence[ObjectModel],
        obstacles: Sequence[Obstacle],
    ) -> GlobalParameters:
        """The parameters of one scenario and settings (``contact``: a
        :class:`locoman.to.problem.ContactCfg`)."""
        values = {
            f"weights.{f.name}": _flat(getattr(weights, f.name))
            for f in dataclasses.fields(weights)
            if f.name not in _WEIGHT_SWITCHES
        }
        values |= {f"contact.{n}": _flat(getattr(contact, n)) for n in _CONTACT_FIELDS}
        values |= {f"collision.{n}": _flat(getattr(collision, n)) for n in _COLLISION_FIELDS}
        for j, obj in enumerate(objects):
            values |= {f"object{j}.{n}": _flat(getattr(obj, n)) for n in _OBJECT_FIELDS}
        for i, obstacle in enumerate(obstacles):
            values |= {f"obstacle{i}.{n}": _flat(getattr(obstacle, n)) for n in _OBSTACLE_FIELDS}
        bad = [name for name, v in values.items() if not np.all(np.isfinite(v))]
        if bad:
            raise ValueError(f"the TO's parameters must be finite; not: {bad}")
        return cls(values)

    @property
    def layout(self) -> tuple[tuple[str, int], ...]:
        """(name, size) of each entry: part of the problem's structure."""
        return tuple((name, v.size) for name, v in self.values.items())

    def vector(self) -> np.ndarray:
        """The values, concatenated in layout order."""
        return np.concatenate(list(self.values.values()))

    def objects(self, templates: Sequence[ObjectModel]) -> tuple[ObjectModel, ...]:
        """``templates`` with this vector's masses, inertias, CoMs, half sizes and
        frictions: the bounds and the initial guess of the TO use the same objects as its
        functions."""
        v = self.values
        return tuple(
            dataclasses.replace(
                template,
                mass=float(v[f"object{j}.mass"][0]),
                inertia=v[f"object{j}.inertia"].reshape(3, 3, order="F"),
                com=v[f"object{j}.com"].copy(),
                half_extents=v[f"object{j}.half_extents"].copy(),
                friction=float(v[f"object{j}.friction"][0]),
            )
            for j, template in enumerate(templates)
        )


class SymbolicGlobals:
    """The global parameters as one SX vector ``theta``, and the configuration objects of
    :class:`GlobalParameters.of` rebuilt with its elements in place of their numbers.

    Args:
        layout: :attr:`GlobalParameters.layout`.
    """

    def __init__(self, layout: tuple[tuple[str, int], ...]) -> None:
        self.layout = layout
        self.size = sum(size for _, size in layout)
        self.theta = ca.SX.sym("theta", self.size)
        self._slices: dict[str, slice] = {}
        start = 0
        for name, size in layout:
            self._slices[name] = slice(start, start + size)
            start += size

    def __getitem__(self, name: str) -> ca.SX:
        return self.theta[self._slices[name]]

    def _scalars(self, name: str) -> list[ca.SX]:
        entry = self[name]
        return [entry[i] for i in range(entry.numel())]

    def weights(self, numeric: CostWeights) -> CostWeights:
        """``numeric`` with every weight and reference symbolic."""
        fields = {}
        for f in dataclasses.fields(numeric):
            if f.name in _WEIGHT_SWITCHES:
                continue
            scalars = self._scalars(f"weights.{f.name}")
            fields[f.name] = scalars if isinstance(getattr(numeric, f.name), list) else scalars[0]
        return dataclasses.replace(numeric, **fields)

    def contact(self, numeric):
        """``numeric`` (a :class:`locoman.to.problem.ContactCfg`) with its numbers symbolic;
        ``prehensile`` stays: it is structure."""
        return dataclasses.replace(
            numeric,
            floor_friction=self["contact.floor_friction"],
            stiffness=self["contact.stiffness"],
            palm_half_extents_m=self._scalars("contact.palm_half_extents_m"),
        )

    def collision(self, numeric: CollisionCfg) -> CollisionCfg:
        """``numeric`` with its numbers symbolic; the pairs and switches stay."""
        return dataclasses.replace(
            numeric, **{n: self[f"collision.{n}"] for n in _COLLISION_FIELDS}
        )

    def objects(self, numeric: Sequence[ObjectModel]) -> tuple[ObjectModel, ...]:
        """Each object with symbolic mass, inertia (3, 3), CoM, half sizes and friction;
        its kind (solid, prehensile, wheeled) stays: it is structure."""
        return tuple(
            dataclasses.replace(
                obj,
                mass=self[f"object{j}.mass"],
                inertia=ca.reshape(self[f"object{j}.inertia"], 3, 3),
                com=self[f"object{j}.com"],
                half_extents=self[f"object{j}.half_extents"],
                friction=self[f"object{j}.friction"],
            )
            for j, obj in enumerate(numeric)
        )

    def obstacles(self, numeric: Sequence[Obstacle]) -> tuple[Obstacle, ...]:
        """Each obstacle with a symbolic centre, yaw and half sizes."""
        return tuple(
            dataclasses.replace(
                obstacle,
                centre=self[f"obstacle{i}.centre"],
                yaw=self[f"obstacle{i}.yaw"],
                half_extents=self[f"obstacle{i}.half_extents"],
            )
            for i, obstacle in enumerate(numeric)
        )
