"""Artifacts of the ``retarget`` stage.

Layout under ``data/<scenario>/retarget/``::

    keyframes/subtask_<i>.npz   one G1 keyframe (35-D) per subtask, with its contact set
    keyframes.mcap              link poses of every keyframe (foxglove.FrameTransforms), one
                                message per subtask at t = subtask index [s]
    plots/subtask_<i>.png       the generated image next to the G1 in the keyframe, in the scene
    metrics.json                residuals, limits, self-collisions, CoM margin, speed, errors
"""

from __future__ import annotations

from pathlib import Path

from locoman.artifacts import ArtifactSchema, Field

KEYFRAMES_DIR = "keyframes"
PLOTS_DIR = "plots"
MCAP_FILE = "keyframes.mcap"

KEYFRAME = ArtifactSchema(
    "retarget.keyframe",
    2,
    "retarget",
    (
        Field("q35", "float64", (35,), "mixed", "base position [m], roll-pitch-yaw [rad], joints"),
        Field("object", "str", (), "-", "the subtask's object"),
        Field("effectors", "str", ("E",), "-", "hands, then both feet"),
        Field("in_contact", "bool", ("E",), "-", "the plan puts it in contact"),
        Field("surfaces", "str", ("E",), "-", "object, floor, or the support it stands on"),
        Field("contact_points_m", "float64", ("E", 3), "m", "contact on the surface, world"),
        Field("contact_normals", "float64", ("E", 3), "-", "outward surface normals, world"),
        Field("targets_m", "float64", ("E", 3), "m", "palm centre / sole centre targets"),
        Field("reached_m", "float64", ("E", 3), "m", "palm centre / sole centre in the keyframe"),
        Field("residual_m", "float64", ("E",), "m", "distance between the two"),
        Field("reachable", "bool", ("E",), "-", "met within retarget.reach_tolerance_m"),
        Field("T_world_object", "float64", (4, 4), "m", "the object's pose in the keyframe"),
        Field("movable_objects", "str", ("M",), "-", "every movable object of the scene"),
        Field(
            "T_world_movable", "float64", ("M", 4, 4), "m", "their poses where the plan left them"
        ),
        Field("stands_on", "str", (), "-", "the object the feet stand on, or floor"),
        Field("com_m", "float64", (3,), "m", "centre of mass"),
        Field("iterations", "int64", (), "-", "IK steps"),
    ),
)


def keyframe_file(retarget_dir: Path, index: int) -> Path:
    """``<retarget_dir>/keyframes/subtask_<index>.npz``."""
    return Path(retarget_dir) / KEYFRAMES_DIR / f"subtask_{index}.npz"
