"""From the human and the transferred contacts to an IK problem (paper A, Sec. III-A.3).

The human configuration that is remapped:

- joint angles: the pose artifact's, through :data:`~locoman.retarget.mapping.JOINT_MAP`;
- base orientation: the human's pelvis as contact transfer placed it relative to the
  object, turned from the human model's axes (x forward, y up) into the G1's (x forward,
  z up);
- foot positions: for feet in contact, the transferred contacts. Standing feet go where
  the human's stand, retargeted: the G1's pelvis stands off the hand contacts like the
  human's pelvis, scaled by the ratio of the two bodies' standing pelvis heights (a shorter
  robot has shorter arms), and each foot keeps the human's planar offset from the pelvis,
  in the pelvis' heading frame, scaled the same way and at least the G1's own stance
  half-width from the middle (a narrower human stance would cross the G1's feet). Their
  height is the floor's. Feet that an earlier subtask put on an object stay where they
  stood (planted): the plan has no step off it.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pinocchio as pin

from locoman.retarget.ik import ContactTarget, IKProblem, yaw_matrix, yaw_of
from locoman.retarget.mapping import map_human_joints
from locoman.retarget.robot import contact_frames
from locoman.scene import g1, human

FLOOR_Z = 0.0  # [m]
UP = np.array([0.0, 0.0, 1.0])
FEET = ("left_foot", "right_foot")  # also the demonstrator's sole keypoints
#: G1 base axes in the human pelvis frame (columns): x forward, y = -z (left), z = y (up).
R_HUMAN_G1 = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


def g1_stance_half_width() -> float:
    """Lateral distance [m] of the standing G1's soles from its pelvis."""
    model = g1.g1_pinocchio_model()
    data = model.createData()
    pin.framesForwardKinematics(model, data, g1.q35_to_pin(g1.standing_q35()))
    sole = contact_frames().sole["left_sole"]
    oMf = data.oMf[model.getFrameId("left_ankle_roll_link")]
    return float(abs((oMf.rotation @ sole + oMf.translation)[1]))


def body_scale() -> float:
    """G1 / human standing pelvis heights [-]."""
    return float(g1.standing_q35()[2] / human.standing_pelvis_height())


def build_problem(
    contacts: dict[str, Any],
    pose: dict[str, Any],
    stance_half_width: float,
    scale: float,
    stand_on: dict[str, np.ndarray],
) -> IKProblem:
    """The IK problem of one subtask.

    Args:
        contacts: The subtask's ``contact.transfer`` artifact.
        pose: The subtask's ``perception.pose`` artifact.
        stance_half_width: :func:`g1_stance_half_width` [m].
        scale: :func:`body_scale` [-].
        stand_on: Foot -> sole centre [m] where a foot keeps standing from an earlier
            subtask that put it on an object (empty: the feet stand on the floor).
    """
    effectors = [str(e) for e in contacts["effectors"]]
    points, normals = contacts["points_world_m"], contacts["normals_world"]
    T_world_pelvis = contacts["T_world_pelvis"]
    R_world_base = T_world_pelvis[:3, :3] @ R_HUMAN_G1
    hands = tuple(
        ContactTarget(e, points[k], normals[k], True)
        for k, e in enumerate(effectors)
        if e.endswith("_hand")
    )
    feet_in_contact = {
        e: ContactTarget(e, points[k], normals[k], True)
        for k, e in enumerate(effectors)
        if e.endswith("_foot")
    }
    # The human's soles relative to the pelvis, in the pelvis' heading frame.
    names = [str(n) for n in pose["keypoint_names"]]
    R_world_cam = T_world_pelvis[:3, :3] @ pose["T_cam_pelvis"][:3, :3].T
    heading = yaw_matrix(yaw_of(R_world_base))
    pelvis_cam = pose["T_cam_pelvis"][:3, 3]
    hand_points = [h.point[:2] for h in hands]
    anchor = np.mean(hand_points, axis=0) if hand_points else T_world_pelvis[:2, 3]
    base_xy = anchor + scale * (T_world_pelvis[:2, 3] - anchor)
    feet = []
    for foot in FEET:
        if foot in feet_in_contact:
            feet.append(feet_in_contact[foot])
            continue
        if foot in stand_on:
            feet.append(ContactTarget(foot, stand_on[foot], UP, False, planted=True))
            continue
        sole_cam = pose["keypoints_cam_m"][names.index(foot)]
        local = heading.T @ (R_world_cam @ (sole_cam - pelvis_cam))
        offset = scale * local[:2]
        side = 1.0 if foot.startswith("left") else -1.0
        offset[1] = side * max(side * offset[1], stance_half_width)
        point = np.r_[base_xy + (heading @ np.r_[offset, 0.0])[:2], FLOOR_Z]
        feet.append(ContactTarget(foot, point, UP, False))
    posture = map_human_joints([str(n) for n in pose["joint_names"]], pose["joint_angles_rad"])
    lower, upper = joint_limits()
    posture = np.clip(posture, lower, upper)
    return IKProblem(
        hands=hands,
        feet=tuple(feet),
        R_world_base=R_world_base,
        posture=posture,
        base_xy=np.mean([f.point[:2] for f in feet], axis=0),
    )


def joint_limits() -> tuple[np.ndarray, np.ndarray]:
    """Lower and upper limits (29,) [rad] of the G1's joints."""
    model = g1.g1_pinocchio_model()
    return model.lowerPositionLimit[7:].copy(), model.upperPositionLimit[7:].copy()
