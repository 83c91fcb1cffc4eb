"""What the TO takes from a scenario: the robot's start, the movable objects, what they rest
on, and one keyframe per subtask (:mod:`locoman.to.pipeline` reads them from the stages'
artifacts)."""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np
import pinocchio as pin

from locoman.errors import ConfigError
from locoman.retarget.robot import contact_frames
from locoman.scene import g1
from locoman.scene.rotations import matrix_to_rpy
from locoman.to.problem.objects import ObjectModel, Obstacle
from locoman.to.terms.supports import Support


@dataclasses.dataclass(frozen=True)
class Keyframe:
    """What the TO takes from one subtask's keyframe.

    Attributes:
        predicate: The subtask's verb (``walk``, ``pick``, ``grab``, ``place``, ``push``,
            ``step``).
        q35: The retargeted configuration.
        object: Index of the subtask's object in :attr:`TOInputs.objects`; None for a walk
            towards a fixed object.
        object_poses: (M, 6) every object's (p, rpy) in the keyframe [m, rad].
        goal: (3,) x, y [m] and yaw [rad] the subtask's object must reach by the subtask's
            end, or None.
        support: What the object rests on once a ``place`` subtask sets it down (None for
            the other predicates).
        support_height: [m] that support's surface height (world z, or in the supporting
            object's frame for :class:`OnObject`).
        step_height: [m] world height of the top face a ``step`` puts the feet on.
        feet_xy: (2, 2) x, y [m] of the left and right foot contacts that (10) aims at, where
            they differ from the keyframe's soles (the naive baseline's feet on an object,
            Sec. V-B); None: the keyframe's soles.
        guides: Its keyframe guides the TO ((9), (10), the warm start); otherwise it gives
            only the contact schedule and the yaw reference (paper A's S1 uses three
            keyframes for its four subtasks).
    """

    predicate: str
    q35: np.ndarray
    object: int | None
    object_poses: np.ndarray
    goal: np.ndarray | None = None
    support: Support | None = None
    support_height: float = 0.0
    step_height: float = 0.0
    feet_xy: np.ndarray | None = None
    guides: bool = True

    def foot_midpoint(self) -> np.ndarray:
        """(2,) x, y [m] of the feet's midpoint that (10) aims at."""
        feet = sole_points(self.q35)[:, :2] if self.feet_xy is None else self.feet_xy
        return feet.mean(axis=0)


@dataclasses.dataclass(frozen=True)
class TOInputs:
    """A scenario, as the TO needs it.

    Attributes:
        q_start: (35,) the robot at rest at the start.
        objects: The scene's movable objects.
        object_starts: (M, 6) each object's (p, rpy) at the start.
        supports: What each object rests on at the start.
        support_heights: (M,) [m] the height of each of those supports' surface.
        keyframes: One per subtask, in plan order.
        hand_points: (M, 2, 3) left and right hand contacts in each object's frame [m].
        hand_frames: (M, 2, 3, 3) their contact frames in the object's frame (z: outward
            normal).
        obstacles: The scene's fixed boxes (tables, shelves) for the collision terms.
    """

    q_start: np.ndarray
    objects: tuple[ObjectModel, ...]
    object_starts: np.ndarray
    supports: tuple[Support, ...]
    support_heights: np.ndarray
    keyframes: Sequence[Keyframe]
    hand_points: np.ndarray
    hand_frames: np.ndarray
    obstacles: tuple[Obstacle, ...] = ()


def guided_by(inputs: TOInputs, subtasks: Sequence[int] | None) -> TOInputs:
    """``inputs`` with only the keyframes of ``subtasks`` (plan indices; None: all) guiding.

    Raises:
        ConfigError: An index beyond the plan.
    """
    if subtasks is None:
        return inputs
    n = len(inputs.keyframes)
    if max(subtasks) >= n:
        raise ConfigError(
            f"solve.keyframes names subtask {max(subtasks)}, but the plan has {n} (0 .. {n - 1})"
        )
    keyframes = [
        dataclasses.replace(kf, guides=i in subtasks) for i, kf in enumerate(inputs.keyframes)
    ]
    return dataclasses.replace(inputs, keyframes=keyframes)


def guiding_keyframe(inputs: TOInputs, subtask: int) -> Keyframe:
    """The keyframe a subtask's nodes start at: its own where it guides, else the next one
    that does (S1's step: the grab on the box), the last one after the last."""
    keyframes = inputs.keyframes
    later = [kf for kf in keyframes[subtask:] if kf.guides]
    return later[0] if later else [kf for kf in keyframes if kf.guides][-1]


def base_yaw(q35: np.ndarray) -> float:
    return float(q35[5])


def sole_points(q35: np.ndarray) -> np.ndarray:
    """(2, 3) left and right sole centres [m] at a configuration."""
    model = g1.g1_pinocchio_model()
    data = model.createData()
    pin.framesForwardKinematics(model, data, g1.q35_to_pin(q35))
    centre = contact_frames().sole["left_sole"]
    return np.array([data.oMf[model.getFrameId(link)].act(centre) for link in g1.FOOT_LINKS])


def object_pose(T: np.ndarray) -> np.ndarray:
    """(6,) (p, rpy) of a 4x4 transform."""
    return np.r_[T[:3, 3], matrix_to_rpy(T[:3, :3])]
