"""The contact mode of every node: which feet are down and on what, which object each hand
touches, which objects are simulated and what each rests on (paper A fixes the contact
schedule; :mod:`locoman.to.problem.schedule` makes it from the plan)."""

from __future__ import annotations

import dataclasses

from locoman.to.collisions.boxes import Seat, seat_on
from locoman.to.problem.inputs import Keyframe, TOInputs
from locoman.to.problem.schedule import Schedule
from locoman.to.terms.supports import OnObject, Support, Surface

# A surface up to this high is the floor: an object resting on it is in the feet's way
# (the ``feet_object`` kind) [m].
FLOOR_HEIGHT_MAX = 0.01


@dataclasses.dataclass(frozen=True)
class ObjectMode:
    """One object's state of contact at a node.

    Attributes:
        active: Simulated: its variables are free and obey (1). An inactive object rests
            where the scene put it.
        support: What it rests on (:mod:`locoman.to.terms.supports`); None while carried.
        seat: Where a fixed surface above the floor holds it (:mod:`locoman.to.collisions.boxes`):
            its bottom boxes reach down through the support there; None elsewhere.
    """

    active: bool
    support: Support | None
    seat: Seat | None = None


@dataclasses.dataclass(frozen=True)
class NodeMode:
    """Which contacts hold at one node.

    Attributes:
        feet: (left, right) foot in contact.
        hands: (left, right): the index of the object the hand touches, or None.
        objects: Each object's :class:`ObjectMode`.
        feet_on: (left, right): the object a foot in contact stands on (its top face, at
            the node's ``foot_surface_z``), None: the ground. The object receives the
            foot's wrench (6) and carries it to its own support.
        underfoot: The objects resting on the floor, where a foot can reach them: the
            feet are kept off them (the ``feet_object`` kind), but for a foot standing on
            one.
    """

    feet: tuple[bool, bool]
    hands: tuple[int | None, int | None]
    objects: tuple[ObjectMode, ...]
    feet_on: tuple[int | None, int | None] = (None, None)
    underfoot: tuple[int, ...] = ()

    @property
    def stance(self) -> bool:
        return all(self.feet)

    def supported(self, j: int) -> bool:
        """Object j is active and rests on a support."""
        return self.objects[j].active and self.objects[j].support is not None

    def carried(self, j: int) -> bool:
        """Object j is held off any support."""
        return self.objects[j].active and self.objects[j].support is None

    def riders(self, j: int) -> list[int]:
        """The active objects that rest on object j."""
        return [
            o
            for o, m in enumerate(self.objects)
            if m.active and isinstance(m.support, OnObject) and m.support.base == j
        ]


def supports_per_node(
    inputs: TOInputs, schedule: Schedule
) -> list[list[tuple[Support | None, float]]]:
    """Per node, each object's (support, surface height [m]): where the scene has it until
    a subtask carries it, None while carried, then what its ``place`` subtask sets it on."""
    current = list(zip(inputs.supports, inputs.support_heights, strict=True))
    out = []
    for n in range(schedule.nodes):
        phase = schedule.phase(n)
        kf = inputs.keyframes[phase.subtask]
        if n == 0 or kf.object is None:
            pass
        elif phase.carried:
            current[kf.object] = (None, 0.0)
        elif current[kf.object][0] is None:
            if kf.support is None:
                raise ValueError(
                    f"subtask {phase.subtask} ({kf.predicate}) sets object {kf.object} down "
                    "without a support to set it on"
                )
            current[kf.object] = (kf.support, kf.support_height)
        out.append(list(current))
    return out


def seats_per_node(inputs: TOInputs, schedule: Schedule, supports) -> list[list[Seat | None]]:
    """Per node, each object's seat on a fixed surface above the floor (None: on the
    floor, on another object, carried): where the scene has it until a subtask carries it,
    then where its ``place`` keyframe sets it down."""
    rest = list(inputs.object_starts)
    out = []
    for n in range(schedule.nodes):
        kf = inputs.keyframes[schedule.phase(n).subtask]
        row = []
        for j, (support, height) in enumerate(supports[n]):
            if n > 0 and supports[n - 1][j][0] is None and support is not None:
                rest[j] = kf.object_poses[j]
            elevated = isinstance(support, Surface) and height > FLOOR_HEIGHT_MAX
            row.append(seat_on(rest[j], inputs.obstacles, height) if elevated else None)
        out.append(row)
    return out


def active_from(inputs: TOInputs, schedule: Schedule, supports) -> list[int]:
    """Per object, the first node at which it is simulated: a hand touches it, or it rests
    on, or carries, a simulated object (the trolley once the box is set on it); never:
    the node count."""
    n = schedule.nodes
    first = [n] * len(inputs.objects)
    for k in range(1, n):
        phase = schedule.phase(k)
        if any(phase.hands):
            j = inputs.keyframes[phase.subtask].object
            first[j] = min(first[j], k)
    changed = True
    while changed:
        changed = False
        for k in range(n):
            for j, (support, _) in enumerate(supports[k]):
                if not isinstance(support, OnObject):
                    continue
                b = support.base
                if min(first[j], first[b]) <= k < max(first[j], first[b]):
                    # The later of the two joins the simulation here; the earlier keeps
                    # its start (the box stays simulated from its pick on).
                    first[j if first[j] > k else b] = k
                    changed = True
    return first


def stood_on(inputs: TOInputs, subtask: int) -> Keyframe | None:
    """The keyframe of the last ``step`` up to ``subtask``: where raised feet stand."""
    steps = [kf for kf in inputs.keyframes[: subtask + 1] if kf.predicate == "step"]
    return steps[-1] if steps else None


def node_modes(inputs: TOInputs, schedule: Schedule) -> list[NodeMode]:
    """The contact mode of every node."""
    supports = supports_per_node(inputs, schedule)
    first = active_from(inputs, schedule, supports)
    seats = seats_per_node(inputs, schedule, supports)
    modes = []
    for n in range(schedule.nodes):
        phase = schedule.phase(n)
        touched = inputs.keyframes[phase.subtask].object
        hands = tuple(touched if (h and n > 0) else None for h in phase.hands)
        step = stood_on(inputs, phase.subtask)
        feet_on = tuple(
            step.object if (on and down and step is not None) else None
            for on, down in zip(phase.feet_raised, phase.feet, strict=True)
        )
        objects = tuple(
            ObjectMode(n >= first[j], supports[n][j][0], seats[n][j])
            for j in range(len(inputs.objects))
        )
        underfoot = tuple(
            j
            for j, (support, height) in enumerate(supports[n])
            if support is not None and support.base is None and height <= FLOOR_HEIGHT_MAX
        )
        modes.append(NodeMode(phase.feet, hands, objects, feet_on, underfoot))
    return modes
