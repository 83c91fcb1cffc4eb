"""Where each quantity of a node sits in the NLP's decision vector: the index arithmetic
the transcription's sections share (:class:`NodeIndex`)."""

from __future__ import annotations

import numpy as np

from locoman.to.collisions.spheres import RobotSphere, SphereSet, link_sphere_list
from locoman.to.problem.layout import (
    FEET,
    HANDS,
    KINEMATICS,
    N_KIN,
    NodeLayout,
    limb,
)


class NodeIndex:
    """Indices into the NLP's x (node-major blocks of ``layout.width``), then into its
    virtual variables (node-major blocks: the kinematics, the sphere centres)."""

    def __init__(self, layout: NodeLayout, spheres: SphereSet, nodes: int) -> None:
        self.layout, self.spheres, self.width, self.nodes = layout, spheres, layout.width, nodes
        self.n_x = nodes * layout.width
        self.virtual_width = N_KIN + 3 * len(spheres)
        # Sphere centres between two nodes: (node, fraction, link or point name) -> their
        # virtual indices, after every node's, handed out as the pairs ask for them.
        self.between: dict[tuple[int, float, str], np.ndarray] = {}
        self.n_y = nodes * self.virtual_width
        # A sphere's entries in a node's virtual block: the pairs ask for them by the
        # hundred thousand.
        self._sphere_slots: dict[str, np.ndarray] = {}

    def var(self, k: int, name: str) -> np.ndarray:
        return self._at(k, self.layout.variables[name])

    def limb(self, k: int, name: str, i: int) -> np.ndarray:
        """Limb i's share of a per-limb variable (``foot_wrench``, ``hand_slack``, ...)."""
        return self._at(k, limb(self.layout.variables[name], i))

    def _at(self, k: int, s: slice) -> np.ndarray:
        return k * self.width + np.arange(s.start, s.stop)

    def virtual(self, k: int) -> int:
        """Node k's first virtual variable."""
        return self.n_x + k * self.virtual_width

    def kinematics(self, k: int) -> np.ndarray:
        return self.virtual(k) + np.arange(N_KIN)

    def kin(self, k: int, name: str) -> np.ndarray:
        s = KINEMATICS[name]
        return self.virtual(k) + np.arange(s.start, s.stop)

    def obj(self, k: int, j: int, quantity: str) -> np.ndarray:
        return self._at(k, self.layout.object_variables(j, quantity))

    def foot(self, k: int, i: int, quantity: str) -> np.ndarray:
        return self.kin(k, f"{FEET[i]}_{quantity}")

    def hand(self, k: int, i: int, quantity: str) -> np.ndarray:
        return self.kin(k, f"{HANDS[i]}_{quantity}")

    def sphere(self, k: int, sphere: RobotSphere) -> np.ndarray:
        return self.virtual(k) + self._slots(sphere)

    def _slots(self, sphere: RobotSphere) -> np.ndarray:
        slots = self._sphere_slots.get(sphere.name)
        if slots is None:
            slots = self._sphere_slots[sphere.name] = N_KIN + self.spheres.slots(sphere)
        return slots

    # The same, for many nodes at once: (n,) nodes -> (n, size) indices.

    def vars_at(self, k: np.ndarray, name: str) -> np.ndarray:
        s = self.layout.variables[name]
        return k[:, None] * self.width + np.arange(s.start, s.stop)

    def objects_at(self, k: np.ndarray, objects: list[int], quantity: str) -> np.ndarray:
        """Object ``objects[i]``'s ``quantity`` at node ``k[i]``."""
        owners = np.asarray(objects, dtype=int)
        slices = {j: self.layout.object_variables(j, quantity) for j in set(objects)}
        size = {s.stop - s.start for s in slices.values()}.pop()
        starts = np.zeros(max(slices) + 1, dtype=int)
        for j, s in slices.items():
            starts[j] = s.start
        return k[:, None] * self.width + starts[owners][:, None] + np.arange(size)

    def spheres_at(self, k: np.ndarray, spheres: list[RobotSphere]) -> np.ndarray:
        """The centre of ``spheres[i]`` at node ``k[i]``."""
        slots = np.array([self._slots(sphere) for sphere in spheres]).reshape(len(k), 3)
        return self.n_x + k[:, None] * self.virtual_width + slots

    def link_spheres(self, k: int, link: str) -> np.ndarray:
        return self.virtual(k) + N_KIN + self.spheres.link_slots(link)

    def sphere_between(self, k: int, fraction: float, sphere: RobotSphere) -> np.ndarray:
        """(3,) the virtual centre of ``sphere`` at the configuration ``fraction`` along
        the step from node k (a capsule's link's spheres come together)."""
        if sphere.index is None:
            key = (k, fraction, sphere.name)
            count = 1
        else:
            key = (k, fraction, sphere.link)
            count = len(link_sphere_list(sphere.link))
        if key not in self.between:
            self.between[key] = self.n_x + self.n_y + np.arange(3 * count)
            self.n_y += 3 * count
        start = 0 if sphere.index is None else 3 * sphere.index
        return self.between[key][start : start + 3]
