"""The contact schedule of the TO, per node, from the task plan and the keyframes.

Paper A fixes which contacts hold at each shooting node (Sec. IV): walking phases alternate
single and double support, stance phases keep both feet down, and a hand touches the box
only while it manipulates it. Keyframes sit at subtask boundaries (Sec. IV-C). Where the
feet must move between two keyframes the schedule inserts steps; where they land is left
to the TO (the walking costs of Table I and the keyframe foot cost (10) place them).

A subtask becomes phases by its predicate:

- ``walk``: steps to the keyframe stance.
- ``pick``: steps if needed, ``reach`` (hands free), ``grasp`` (hands on the object while it
  rests on its support; the keyframe), ``lift`` (the object carried).
- ``place``: steps carrying the object, ``lower``, ``set`` (the object on its target
  support, hands still on it; the keyframe).
- ``push``: steps if needed, ``reach``, ``grasp`` (hands on the handle, the object still;
  the keyframe: "the beginning of pushing", Sec. V-C.2), then steps with the hands on it
  while it rolls on its support, and a last ``stance``.
- ``step``: steps on the floor if needed, then two swings, each landing one foot on the
  object's top (``step_up``), and a ``stance`` on it (the keyframe). From then on the feet
  stand on that object.
- ``grab``: a ``pick`` (reach, grasp, lift) of an object the robot takes from where it
  stands, possibly on another object.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from locoman.config.to import MAX_NODES, TOO_MANY_NODES, ScheduleCfg
from locoman.errors import ConfigError
from locoman.to.problem.inputs import Keyframe, TOInputs, base_yaw, sole_points


@dataclasses.dataclass(frozen=True)
class Phase:
    """Consecutive nodes sharing one contact mode.

    Attributes:
        name: ``stance``, ``swing_left``, ``swing_right``, ``reach``, ``grasp``, ``lift``,
            ``lower`` or ``set``.
        subtask: Index of the plan's subtask.
        nodes: Number of nodes.
        feet: (left, right) in contact with the ground.
        feet_raised: (left, right) a foot in contact stands on the object the plan stepped
            onto; a swinging one lands there.
        hands: (left, right) in contact with the subtask's object.
        object_supported: The subtask's object rests on a support (a table, its wheels).
        keyframe: The phase's last node is its subtask's keyframe.
    """

    name: str
    subtask: int
    nodes: int
    feet: tuple[bool, bool] = (True, True)
    feet_raised: tuple[bool, bool] = (False, False)
    hands: tuple[bool, bool] = (False, False)
    object_supported: bool = True
    keyframe: bool = False

    @property
    def stance(self) -> bool:
        """b_st of (8): both feet down."""
        return all(self.feet)

    @property
    def carried(self) -> bool:
        """The object moves with the hands, off its support."""
        return any(self.hands) and not self.object_supported


def step_count(
    feet_from: np.ndarray, feet_to: np.ndarray, yaw_from: float, yaw_to: float, cfg: ScheduleCfg
) -> int:
    """Steps (even, so that both feet move) to go from one stance to another: enough that no
    step is longer than ``step_length_m`` or turns more than ``step_yaw_rad``; none if the
    feet move less than ``step_min_m`` and the base turns less than one step's turn.

    Args:
        feet_from, feet_to: (2, 2) left and right foot xy [m].
        yaw_from, yaw_to: Base yaw [rad].
    """
    travel = float(np.max(np.linalg.norm(np.asarray(feet_to) - np.asarray(feet_from), axis=1)))
    turn = abs(math.remainder(yaw_to - yaw_from, math.tau))
    if travel < cfg.step_min_m and turn < cfg.step_yaw_rad:
        return 0
    steps = max(math.ceil(travel / cfg.step_length_m), math.ceil(turn / cfg.step_yaw_rad), 1)
    return steps + steps % 2


def _steps(subtask: int, steps: int, first_right: bool, cfg: ScheduleCfg, **mode) -> list[Phase]:
    phases = []
    for s in range(steps):
        right = (s % 2 == 0) == first_right
        feet = (True, False) if right else (False, True)
        name = "swing_right" if right else "swing_left"
        phases.append(Phase(name, subtask, cfg.swing_nodes, feet=feet, **mode))
        phases.append(Phase("stance", subtask, cfg.double_support_nodes, **mode))
    return phases


def _step_up(subtask: int, first_right: bool, cfg: ScheduleCfg) -> list[Phase]:
    """Two swings, each landing one foot on the object's top, and the stance on it."""
    first = 1 if first_right else 0
    phases, raised = [], [False, False]
    for i in (first, 1 - first):
        feet = (i != 0, i != 1)  # the other foot stands
        raised[i] = True
        name = "step_up_right" if i == 1 else "step_up_left"
        phases.append(Phase(name, subtask, cfg.swing_nodes, feet=feet, feet_raised=tuple(raised)))
        phases.append(Phase("stance", subtask, cfg.double_support_nodes, feet_raised=tuple(raised)))
    phases[-1] = dataclasses.replace(phases[-1], keyframe=True)
    return phases


def subtask_phases(
    predicate: str,
    subtask: int,
    steps: int,
    first_right: bool,
    cfg: ScheduleCfg,
    push_steps: int = 0,
    raised: bool = False,
) -> list[Phase]:
    """Phases of one subtask (see the module's docstring); ``push_steps``: the steps of a
    ``push`` after its keyframe; ``raised``: the feet stand on an object an earlier ``step``
    put them on (every phase keeps them there, and a subtask that needs steps is refused:
    the plan has no step down)."""
    phases = _phases(predicate, subtask, steps, first_right, cfg, push_steps)
    if not raised:
        return phases
    if any(not p.stance for p in phases):
        raise ConfigError(
            f"subtask {subtask} ({predicate!r}) needs steps, but the feet stand on an object an "
            "earlier 'step' put them on, and the TO has no step down"
        )
    return [dataclasses.replace(p, feet_raised=(True, True)) for p in phases]


def _phases(
    predicate: str,
    subtask: int,
    steps: int,
    first_right: bool,
    cfg: ScheduleCfg,
    push_steps: int,
) -> list[Phase]:
    if predicate == "walk":
        phases = _steps(subtask, steps, first_right, cfg)
        if not phases:
            phases = [Phase("stance", subtask, cfg.double_support_nodes)]
        last = phases[-1]
        return [*phases[:-1], dataclasses.replace(last, keyframe=True)]
    if predicate in ("pick", "grab"):
        both = (True, True)
        return [
            *_steps(subtask, steps, first_right, cfg),
            Phase("reach", subtask, cfg.reach_nodes),
            Phase("grasp", subtask, cfg.grasp_nodes, hands=both, keyframe=True),
            Phase("lift", subtask, cfg.lift_nodes, hands=both, object_supported=False),
        ]
    if predicate == "place":
        both = (True, True)
        carry = {"hands": both, "object_supported": False}
        return [
            *_steps(subtask, steps, first_right, cfg, **carry),
            Phase("lower", subtask, cfg.lower_nodes, **carry),
            Phase("set", subtask, cfg.set_nodes, hands=both, keyframe=True),
        ]
    if predicate == "push":
        both = (True, True)
        return [
            *_steps(subtask, steps, first_right, cfg),
            Phase("reach", subtask, cfg.reach_nodes),
            Phase("grasp", subtask, cfg.grasp_nodes, hands=both, keyframe=True),
            *_steps(subtask, push_steps, False, cfg, hands=both),
            Phase("stance", subtask, cfg.double_support_nodes, hands=both),
        ]
    if predicate == "step":
        return [*_steps(subtask, steps, first_right, cfg), *_step_up(subtask, first_right, cfg)]
    raise ConfigError(
        f"subtask {subtask} ({predicate!r}): the TO has contact schedules for 'walk', 'pick', "
        "'grab', 'place', 'push' and 'step' only"
    )


@dataclasses.dataclass(frozen=True)
class Schedule:
    """Per-node view of the phases, with a leading node for the initial state.

    Attributes:
        phases: In order; node 0 (the initial state) belongs to none.
        phase_of: (N,) phase index per node, -1 for node 0.
    """

    phases: tuple[Phase, ...]
    phase_of: np.ndarray

    @classmethod
    def from_phases(cls, phases: list[Phase]) -> Schedule:
        index = [-1] + [i for i, phase in enumerate(phases) for _ in range(phase.nodes)]
        return cls(tuple(phases), np.asarray(index, dtype=int))

    @property
    def nodes(self) -> int:
        return len(self.phase_of)

    def phase(self, node: int) -> Phase:
        """The phase of a node; node 0 shares the first phase's mode (the robot at rest,
        both feet down, the object untouched)."""
        return self.phases[max(int(self.phase_of[node]), 0)]

    def keyframe_nodes(self) -> dict[int, int]:
        """Subtask -> its keyframe node (the last node of its keyframe phase)."""
        out, node = {}, 0
        for phase in self.phases:
            node += phase.nodes
            if phase.keyframe:
                out[phase.subtask] = node
        return out

    def subtask_of(self, node: int) -> int:
        return self.phase(node).subtask

    def first_touch(self) -> int | None:
        """First node at which a hand touches the object (from then on it is simulated)."""
        for node in range(self.nodes):
            if any(self.phase(node).hands):
                return node
        return None


def push_steps(inputs: TOInputs, keyframe: Keyframe, cfg: ScheduleCfg) -> int:
    """Steps of a ``push`` after its keyframe: each foot steps often enough to follow the
    object from its keyframe pose to its goal with steps of at most ``step_length_m``."""
    if keyframe.goal is None:
        return 0
    travel = float(np.linalg.norm(keyframe.goal[:2] - keyframe.object_poses[keyframe.object][:2]))
    return 2 * math.ceil(travel / cfg.step_length_m)


def build_schedule(inputs: TOInputs, cfg: ScheduleCfg) -> Schedule:
    """Phases of every subtask; steps where the keyframes' feet move (Sec. IV); a ``step``'s
    two swings onto its object cover two of them."""
    phases = []
    feet_before, yaw_before = sole_points(inputs.q_start)[:, :2], base_yaw(inputs.q_start)
    raised = False
    for i, kf in enumerate(inputs.keyframes):
        feet = sole_points(kf.q35)[:, :2]
        steps = step_count(feet_before, feet, yaw_before, base_yaw(kf.q35), cfg)
        if kf.predicate == "step":
            steps = max(steps - 2, 0)
        # Lead with the foot on the side the robot moves or turns to.
        heading = np.array([math.cos(yaw_before), math.sin(yaw_before)])
        move = feet.mean(axis=0) - feet_before.mean(axis=0)
        lateral = heading[0] * move[1] - heading[1] * move[0]
        turn = math.remainder(base_yaw(kf.q35) - yaw_before, math.tau)
        first_right = (lateral + 0.3 * turn) < 0.0
        pushed = push_steps(inputs, kf, cfg) if kf.predicate == "push" else 0
        phases += subtask_phases(kf.predicate, i, steps, first_right, cfg, pushed, raised)
        raised = raised or kf.predicate == "step"
        feet_before, yaw_before = feet, base_yaw(kf.q35)
        if pushed:  # the feet follow the object to its goal
            feet_before = feet_before + (kf.goal[:2] - kf.object_poses[kf.object][:2])
    nodes = 1 + sum(p.nodes for p in phases)
    if nodes > MAX_NODES:
        raise ConfigError(
            f"the contact schedule has {nodes} nodes, more than the TO's {MAX_NODES}: "
            f"{TOO_MANY_NODES}; lower solve.schedule's node counts or step sizes"
        )
    return Schedule.from_phases(phases)
