"""Artifacts of the ``contacts`` stage.

Layout under ``data/<scenario>/contacts/``::

    subtasks/subtask_<i>.npz    contact locations L, object transform, human placement, pool
    plots/subtask_<i>.png       R_g next to R_s with true, transferred and naive contacts
    metrics.json                contact errors of both methods against ground truth

Frames: ``world`` is the scene's world; ``object`` is the subtask's object frame (origin at
the centre of its bottom face, x forward, z up); ``gen`` is R_g's metric camera frame, the
frame of the 3D pose estimate (the clouds stage's lifted cloud, with its heuristic
intrinsics and estimated depth, is mapped into it by the pose anchor). ``T_a_b`` maps frame
b into a.
"""

from __future__ import annotations

from pathlib import Path

from locoman.artifacts import ArtifactSchema, Field

SUBTASKS_DIR = "subtasks"
PLOTS_DIR = "plots"

CONTACTS = ArtifactSchema(
    "contact.transfer",
    4,
    "contacts",
    (
        Field("method", "str", (), "-", "registration or naive"),
        Field("object", "str", (), "-", "the subtask's object"),
        Field("effectors", "str", ("C",), "-", "end effectors in contact, plan order"),
        Field("surfaces", "str", ("C",), "-", "object or floor"),
        Field("points_world_m", "float64", ("C", 3), "m", "contact locations L"),
        Field("points_object_m", "float64", ("C", 3), "m", "L in the object frame"),
        Field("normals_world", "float64", ("C", 3), "-", "outward surface normals at L"),
        Field("raw_points_world_m", "float64", ("C", 3), "m", "L before surface projection"),
        # Sec. V-B's geometry-unaware baseline, kept beside L for the TO's ablations.
        Field("naive_points_object_m", "float64", ("C", 3), "m", "naive contacts, object frame"),
        Field("naive_normals_world", "float64", ("C", 3), "-", "normals nearest to them"),
        Field("T_world_object", "float64", (4, 4), "m", "the object's pose in the scene"),
        Field("T_world_gen", "float64", (4, 4), "m", "registration: gen -> world (similarity)"),
        Field("scale", "float64", (), "-", "scale of T_world_gen"),
        Field("overlap", "float64", (), "-", "overlap score of the best hypothesis"),
        Field("iteration", "int64", (), "-", "1-based hypothesis that won"),
        # How far the registration can be trusted without the ground truth
        # (locoman.contact.confidence), and whose contacts L is.
        Field("runner_up", "float64", (), "-", "best overlap of a hypothesis placing it otherwise"),
        Field("margin", "float64", (), "-", "overlap - runner_up"),
        Field("silhouette_iou", "float64", (), "-", "registered silhouette vs R_g's mask"),
        Field("contact_gaps_m", "float64", ("C",), "m", "how far each L moved onto the object"),
        Field("doubtful", "bool", (), "-", "a confidence signal below its threshold"),
        Field("used", "str", (), "-", "whose contacts L holds: registration or naive"),
        Field("T_world_pelvis", "float64", (4, 4), "m", "human pelvis placed in the scene"),
        Field("T_object_pelvis", "float64", (4, 4), "m", "pelvis pose relative to the object"),
        Field("pool_gen_px", "float64", ("S", 2), "px", "points sampled on the object in R_g"),
        Field("pool_sim_px", "float64", ("S", "N", 2), "px", "their top-N candidates in R_s"),
        Field("pool_scores", "float64", ("S", "N"), "-", "cosine scores of the candidates"),
    ),
)

# Which fields hold each method's contact locations L (object frame) and normals (world):
# the TO's ``solve.contacts`` picks one. ``naive`` is the geometry-unaware baseline of
# Sec. V-B (the top-1 semantic match lifted with D_s, not projected onto the surface).
CONTACT_FIELDS = {
    "registration": ("points_object_m", "normals_world"),
    "naive": ("naive_points_object_m", "naive_normals_world"),
}


def subtask_file(contacts_dir: Path, index: int) -> Path:
    """``<contacts_dir>/subtasks/subtask_<index>.npz``."""
    return Path(contacts_dir) / SUBTASKS_DIR / f"subtask_{index}.npz"
