"""Artifacts of the ``solve`` stage.

Layout under ``data/<scenario>/solve/``::

    trajectory.npz     the TO's trajectory (robot, objects, contact wrenches, slacks, dt)
    trajectory.mcap    link and object poses over time (foxglove.FrameTransforms, /tf)
    metrics.json       solver status and statistics

Configurations are paper A's: q = (base position [m], roll-pitch-yaw [rad], 29 joints
[rad]), v = dq/dt; an object's q = (position of its frame origin [m]: its bottom centre, a
trolley's chassis frame on the ground; roll-pitch-yaw). Wrenches are in world axes: each
foot's at its sole centre, each hand's (the touched object's push on the robot; the object
receives its opposite) at the hand's contact point on the object, each support's at the
supported object's origin (an object resting on another hands it the opposite).
"""

from __future__ import annotations

from locoman.artifacts import ArtifactSchema, Field

TRAJECTORY_FILE = "trajectory.npz"

MCAP_FILE = "trajectory.mcap"

TRAJECTORY = ArtifactSchema(
    "to.trajectory",
    3,
    "solve",
    (
        Field("status", "str", (), "-", "IPOPT's return status"),
        Field("success", "bool", (), "-", "IPOPT converged"),
        Field("q", "float64", ("N", 35), "mixed", "robot configuration per node"),
        Field("v", "float64", ("N", 35), "mixed", "dq/dt per node"),
        Field("foot_wrench", "float64", ("N", 2, 6), "N, N m", "left, right: force, moment"),
        Field("hand_wrench", "float64", ("N", 2, 6), "N, N m", "touched object's wrench on hand"),
        Field("object_names", "str", ("M",), "-", "the scene's movable objects, TO order"),
        Field("object_q", "float64", ("N", "M", 6), "mixed", "object position, roll-pitch-yaw"),
        Field("object_v", "float64", ("N", "M", 6), "mixed", "d(object_q)/dt"),
        Field("support_wrench", "float64", ("N", "M", 6), "N, N m", "support on each object"),
        Field("foot_slack", "float64", ("N", 2), "m", "slack of (2a)"),
        Field("hand_slack", "float64", ("N", 2, 3), "m", "slack of (4)"),
        Field("support_slack", "float64", ("N", "M"), "m", "slack of each support's (2a)"),
        Field("dt", "float64", ("N",), "s", "time step to the next node (last unused)"),
        Field("feet_contact", "bool", ("N", 2), "-", "foot in contact"),
        Field(
            "foot_object",
            "int64",
            ("N", 2),
            "-",
            "object a foot is on, -1: ground",
            values="index:M|-1",
        ),
        Field(
            "hand_object",
            "int64",
            ("N", 2),
            "-",
            "object a hand touches, -1: none",
            values="index:M|-1",
        ),
        Field("object_active", "bool", ("N", "M"), "-", "object simulated"),
        Field("support_kind", "str", ("N", "M"), "-", "surface, on_object, chassis or none"),
        Field(
            "support_base",
            "int64",
            ("N", "M"),
            "-",
            "supporting object, -1: world",
            values="index:M|-1",
        ),
        Field("phase", "str", ("N",), "-", "schedule phase of each node"),
        Field("subtask", "int64", ("N",), "-", "plan subtask of each node"),
        Field(
            "object_goal",
            "float64",
            ("M", 3),
            "mixed",
            "target x, y [m], yaw [rad]; NaN: none",
            nan_allowed=True,
        ),
        Field(
            "goal_node",
            "int64",
            ("M",),
            "-",
            "node the goal holds at, -1: none",
            values="index:N|-1",
        ),
        Field("floor_friction", "float64", (), "-", "mu of the feet on the floor"),
        Field("object_friction", "float64", ("M",), "-", "mu of each object's surfaces"),
        Field("object_half_extents", "float64", ("M", 2), "m", "CoP patch of each object"),
        Field(
            "rear_axle_x",
            "float64",
            ("M",),
            "m",
            "a chassis's rear axle x; NaN: none",
            nan_allowed=True,
        ),
        Field("prehensile", "bool", ("M",), "-", "hands on the object exempt from (3)"),
        Field("sole_half_extents", "float64", (2,), "m", "CoP patch of a sole"),
        Field("palm_half_extents", "float64", (2,), "m", "CoP patch of a palm"),
        Field("hand_points", "float64", ("M", 2, 3), "m", "hand contacts, object frame"),
        Field("hand_frames", "float64", ("M", 2, 3, 3), "-", "hand contact frames, object frame"),
    ),
)
