"""Human joint angles -> G1 joint angles, following the mapping idea of HumanPlus.

HumanPlus keeps the human joints that have a counterpart on the humanoid and copies their
angles; the ones without (clavicles, neck, fingers) are dropped. The demonstrator model
(``human_description``) has ball-like joints split into revolute Z, X, Y joints in a y-up
frame (x forward, z to the person's right); the G1 has pitch (y, left), roll (x) and yaw (z)
joints in a z-up frame. With both models upright at their zero posture, each G1 joint's axis
is the same line as its human counterpart's, with the same or the opposite direction: the
sign below. The G1's elbow is bent by 90 deg at zero where the human's arm is straight,
hence the offset. ``tests/test_retarget.py`` checks every row against both models.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from locoman.scene.g1 import G1_JOINT_NAMES

HALF_PI = 0.5 * np.pi


@dataclasses.dataclass(frozen=True)
class JointMap:
    """q_g1 = offset + sum(sign * q_human) over the human joints of one G1 joint.

    Attributes:
        g1: G1 joint name.
        human: (human joint name, sign) pairs; several for the waist, which the human bends
            at the lumbar and the thoracic spine.
        offset: [rad].
    """

    g1: str
    human: tuple[tuple[str, float], ...]
    offset: float = 0.0


def _legs(side: str, s: float) -> tuple[JointMap, ...]:
    # s: +1 for the left side, -1 for the right, where the human's X and Y axes flip.
    return (
        JointMap(f"{side}_hip_pitch_joint", ((f"{side}_hip_Z", -1.0),)),
        JointMap(f"{side}_hip_roll_joint", ((f"{side}_hip_X", s),)),
        JointMap(f"{side}_hip_yaw_joint", ((f"{side}_hip_Y", -s),)),
        JointMap(f"{side}_knee_joint", ((f"{side}_knee_Z", 1.0),)),
        JointMap(f"{side}_ankle_pitch_joint", ((f"{side}_ankle_Z", -1.0),)),
        JointMap(f"{side}_ankle_roll_joint", ((f"{side}_ankle_X", -s),)),
    )


def _arms(side: str, s: float) -> tuple[JointMap, ...]:
    return (
        JointMap(f"{side}_shoulder_pitch_joint", ((f"{side}_shoulder_Z", -1.0),)),
        JointMap(f"{side}_shoulder_roll_joint", ((f"{side}_shoulder_X", s),)),
        JointMap(f"{side}_shoulder_yaw_joint", ((f"{side}_shoulder_Y", -s),)),
        JointMap(f"{side}_elbow_joint", ((f"{side}_elbow_Z", -1.0),), offset=HALF_PI),
        JointMap(f"{side}_wrist_roll_joint", ((f"{side}_elbow_Y", s),)),
        JointMap(f"{side}_wrist_pitch_joint", ((f"{side}_wrist_Z", -1.0),)),
        JointMap(f"{side}_wrist_yaw_joint", ((f"{side}_wrist_X", s),)),
    )


#: The mapping table, one row per G1 joint that has a human counterpart (all 29 do).
JOINT_MAP: tuple[JointMap, ...] = (
    *_legs("left", 1.0),
    *_legs("right", -1.0),
    JointMap("waist_yaw_joint", (("middle_thoracic_Y", 1.0),)),
    JointMap("waist_roll_joint", (("middle_lumbar_X", 1.0), ("middle_thoracic_X", 1.0))),
    JointMap("waist_pitch_joint", (("middle_lumbar_Z", 1.0), ("middle_thoracic_Z", 1.0))),
    *_arms("left", 1.0),
    *_arms("right", -1.0),
)


def map_human_joints(names: Sequence[str], angles: np.ndarray) -> np.ndarray:
    """G1 joint angles (29,) [rad], in :data:`G1_JOINT_NAMES` order, from the human's.

    Args:
        names: Human joint names.
        angles: Their angles [rad].

    Raises:
        KeyError: When a human joint of the table is missing (the message names it).
    """
    index = {str(n): k for k, n in enumerate(names)}
    out = np.zeros(len(G1_JOINT_NAMES))
    for row in JOINT_MAP:
        value = row.offset
        for name, sign in row.human:
            if name not in index:
                raise KeyError(f"the human pose has no joint {name!r} (needed for {row.g1})")
            value += sign * float(angles[index[name]])
        out[G1_JOINT_NAMES.index(row.g1)] = value
    return out
