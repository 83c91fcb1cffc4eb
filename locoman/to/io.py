"""Artifacts of the ``solve`` stage.

Layout under ``data/<scenario>/solve/``::

    trajectory.npz     the TO's trajectory (robot, object, contact wrenches, slacks, dt)
    trajectory.mcap    link and object poses over time (foxglove.FrameTransforms, /tf)
    metrics.json       solver status and statistics

Configurations are paper A's: q = (base position [m], roll-pitch-yaw [rad], 29 joints
[rad]), v = dq/dt; the object's q = (position of its bottom centre [m], roll-pitch-yaw).
Wrenches are in world axes: each foot's at its sole centre, each hand's (the object's push
on the robot; the object receives its opposite) at the hand's contact point on the object.
"""

from __future__ import annotations

from locoman.artifacts import ArtifactSchema, Field

TRAJECTORY_FILE = "trajectory.npz"
MCAP_FILE = "trajectory.mcap"

TRAJECTORY = ArtifactSchema(
    "to.trajectory",
    1,
    "solve",
    (
        Field("status", "str", (), "-", "IPOPT's return status"),
        Field("success", "bool", (), "-", "IPOPT converged"),
        Field("q", "float64", ("N", 35), "mixed", "robot configuration per node"),
        Field("v", "float64", ("N", 35), "mixed", "dq/dt per node"),
        Field("foot_wrench", "float64", ("N", 2, 6), "N, N m", "left, right: force, moment"),
        Field("hand_wrench", "float64", ("N", 2, 6), "N, N m", "object's wrench on each hand"),
        Field("hand_points", "float64", (2, 3), "m", "hand contacts in the object frame"),
        Field("object_q", "float64", ("N", 6), "mixed", "object position, roll-pitch-yaw"),
        Field("object_v", "float64", ("N", 6), "mixed", "d(object_q)/dt"),
        Field("support_wrench", "float64", ("N", 6), "N, N m", "support on the object"),
        Field("foot_slack", "float64", ("N", 2), "m", "slack of (2a)"),
        Field("hand_slack", "float64", ("N", 2, 3), "m", "slack of (4)"),
        Field("dt", "float64", ("N",), "s", "time step to the next node (last unused)"),
        Field("feet_contact", "bool", ("N", 2), "-", "foot on the ground"),
        Field("hands_contact", "bool", ("N", 2), "-", "hand on the object"),
        Field("object_active", "bool", ("N",), "-", "object simulated (touched)"),
        Field("object_supported", "bool", ("N",), "-", "object on a support"),
        Field("phase", "str", ("N",), "-", "schedule phase of each node"),
        Field("subtask", "int64", ("N",), "-", "plan subtask of each node"),
        Field("object_goal", "float64", (3,), "mixed", "target x, y [m], yaw [rad]"),
        Field("object_name", "str", (), "-", "the manipulated object"),
        Field("mu", "float64", (3,), "-", "friction of floor, hands on object, object"),
        Field("sole_half_extents", "float64", (2,), "m", "CoP patch of a sole"),
        Field("palm_half_extents", "float64", (2,), "m", "CoP patch of a palm"),
        Field("object_half_extents", "float64", (2,), "m", "CoP patch of the object"),
        Field("hand_frames", "float64", (2, 3, 3), "-", "hand contact frames, object frame"),
        Field("prehensile", "bool", (), "-", "hands exempt from (3)"),
    ),
)
