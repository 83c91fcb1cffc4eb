"""Artifacts of the demos and kmp_fit stages."""

from __future__ import annotations

from locoman.artifacts import ArtifactSchema, Field

DEMOS = ArtifactSchema(
    "demos.demos",
    1,
    "demos",
    (
        Field("time_s", "float64", ("N",), "s", "sample times", values="increasing"),
        Field("wrist_pos", "float64", ("M", "N", 3), "m", "wrist position, world"),
        Field("wrist_vel", "float64", ("M", "N", 3), "m/s", "wrist velocity, world"),
        Field("pelvis", "float64", ("M", "N", 3), "mixed", "pelvis x [m], y [m], yaw [rad]"),
        Field("selected", "int64", ("S",), "-", "indices of the demos kept", values="index:M"),
        Field("grasp_miss_m", "float64", ("M",), "m", "wrist-to-grasp-point distance"),
    ),
)
GMR = ArtifactSchema(
    "kmp.gmr",
    1,
    "kmp_fit",
    (
        Field("s", "float64", ("N",), "s", "reference inputs s_n", values="increasing"),
        Field("mean", "float64", ("N", 9), "mixed", "mu_n: wrist pos [m], vel [m/s], pelvis"),
        Field("cov", "float64", ("N", 9, 9), "mixed", "Sigma_n"),
    ),
)
REFERENCE = ArtifactSchema(
    "kmp.reference",
    2,
    "kmp_fit",
    (
        Field("time_s", "float64", ("T",), "s", "prediction times", values="increasing"),
        Field("wrist_pos", "float64", ("T", 3), "m", "x_d: desired end-effector position"),
        Field("wrist_vel", "float64", ("T", 3), "m/s", "xd_dot: desired end-effector velocity"),
        Field("pelvis", "float64", ("T", 3), "mixed", "learned pelvis x [m], y [m], yaw [rad]"),
        Field("base", "float64", ("T", 3), "mixed", "q_b,d: base frame Sigma_B x, y, yaw"),
        Field("via_time_s", "float64", ("V",), "s", "via point inputs"),
        Field(
            "via_mean",
            "float64",
            ("V", 9),
            "mixed",
            "via point outputs; NaN = free",
            nan_allowed=True,
        ),
        Field("via_cov", "float64", ("V", 9, 9), "mixed", "via point covariances"),
        Field("cov_time_s", "float64", ("C",), "s", "covariance inputs", values="increasing"),
        Field("cov", "float64", ("C", 9, 9), "mixed", "KMP's predicted covariance"),
    ),
)
