"""Whether the hands hold what the plan has them hold, measured on MuJoCo's contacts.

The controller feeds a carried object's planned wrench forward (its weight on the hands) and
the LIPM's centre of mass leans against it (:mod:`locoman.execute.balance`). When a grasp
slips and the object stays behind, both are wrong by the object's weight: on ``tiny`` the
centre of mass would stand 5 cm behind where a robot without the box balances. A hand that
has not touched its object for ``grace_s`` while the plan has it holding counts as having
lost it, until the plan's hold ends (:class:`GraspMonitor`); the simulation then drops that
wrench and replans the centre of mass (:func:`locoman.execute.simulate.execute`).
"""

from __future__ import annotations

import dataclasses

import mujoco
import numpy as np

from locoman.scene import g1


def hand_bodies(model: mujoco.MjModel) -> list[frozenset[int]]:
    """Each hand's (left, right) MuJoCo bodies that touch what it holds: the palm link and
    its parent, the wrist (both carry collision geoms)."""
    out = []
    for link in g1.HAND_LINKS:
        body = model.body(link).id
        out.append(frozenset({body, int(model.body_parentid[body])}))
    return out


def touching(
    model: mujoco.MjModel, data: mujoco.MjData, bodies: frozenset[int], other: int
) -> bool:
    """Whether any active contact joins a body in ``bodies`` and the body ``other``."""
    for c in range(data.ncon):
        contact = data.contact[c]
        a, b = model.geom_bodyid[contact.geom1], model.geom_bodyid[contact.geom2]
        if (a == other and b in bodies) or (b == other and a in bodies):
            return True
    return False


@dataclasses.dataclass
class GraspMonitor:
    """Per hand, whether it still holds the object of the plan's current hold.

    Attributes:
        hands: Each hand's bodies (:func:`hand_bodies`).
        objects: Each object's body id, in the plan's order.
        grace_steps: Control steps a holding hand may go without touching its object.
        holding: (2,) the object of each hand's current hold, -1 for none.
        untouched: (2,) control steps since it last touched it.
        lost: (2,) whether it lost it (until the hold ends).
    """

    hands: list[frozenset[int]]
    objects: list[int]
    grace_steps: int
    holding: np.ndarray = dataclasses.field(default_factory=lambda: np.full(2, -1))
    untouched: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(2, dtype=int))
    lost: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(2, dtype=bool))

    @classmethod
    def of(
        cls, model: mujoco.MjModel, objects: list[str], grace_s: float, timestep_s: float
    ) -> GraspMonitor:
        return cls(
            hand_bodies(model),
            [model.body(name).id for name in objects],
            max(1, round(grace_s / timestep_s)),
        )

    def update(self, model: mujoco.MjModel, data: mujoco.MjData, plan: np.ndarray) -> list[int]:
        """Advance one control step with the plan's holds ``plan`` (2,) (object per hand, -1
        for none); return the hands that lose their object at this step."""
        newly = []
        for k in range(2):
            if plan[k] != self.holding[k]:
                self.holding[k], self.untouched[k], self.lost[k] = plan[k], 0, False
            if plan[k] < 0 or self.lost[k]:
                continue
            if touching(model, data, self.hands[k], self.objects[plan[k]]):
                self.untouched[k] = 0
                continue
            self.untouched[k] += 1
            if self.untouched[k] > self.grace_steps:
                self.lost[k] = True
                newly.append(k)
        return newly
