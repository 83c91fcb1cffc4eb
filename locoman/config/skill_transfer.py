"""Typed configuration of the mobile-manipulator branch (paper B): demos, KMP and HQP."""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field
from pathlib import PurePosixPath
from typing import ClassVar

from omegaconf import MISSING

from locoman.config.cost import at_most


def _vec(name: str, values: list[float] | None, n: int) -> list[tuple[str, str]]:
    if values is not None and len(values) != n:
        return [(name, f"needs {n} values, got {len(values)}")]
    return []


@dataclass
class DemosCfg:
    """Human demonstrations of the bottle pick-and-place (paper B, Sec. IV-A).

    The synthetic source reproduces the paper's protocol: the subject starts from the same
    pose, walks to the table, grasps the bottle on the move at ``grasp_time_s`` with
    ``grasp_velocity`` and places it at the plan's target. The bottle and the target come
    from the scenario; the pelvis and wrist waypoints below describe how the human moves.

    Attributes:
        source: ``synthetic`` (generated here) or ``csv`` (recorded files in ``csv_dir``).
        csv_dir: Folder of recorded demonstrations (``*.csv``, layout in
            :mod:`locoman.kmp.mocap_csv`), relative to the repository root and inside it:
            the ``demos`` stage depends on it, so DVC reruns it when a recording changes.
        scenario: The scenario holding the bottle, the table and the place target.
        rate_hz: Sampling rate [Hz] (paper: 100).
        duration_s: Length of every demonstration [s] (paper: 26).
        n_recorded: Demonstrations recorded (paper: 10).
        n_selected: Demonstrations kept for learning (paper: 5), those whose wrist passes
            closest to the bottle at the grasp time.
        pelvis_start: Pelvis (x [m], y [m], yaw [rad]) at t = 0.
        wrist_start: Wrist position [m] at t = 0.
        walk_end_time_s: End of the walking phase [s] (paper: 15).
        walk_end_pelvis: Pelvis pose at the end of the walk (paper: x = 2.411 m).
        walk_end_wrist: Wrist position at the end of the walk [m] (paper: z = 0.956 m).
        walk_end_wrist_velocity: Wrist velocity at the end of the walk [m/s] (paper: 0.254).
        grasp_time_s: Grasp instant [s] (paper: 18.15).
        grasp_velocity: Wrist velocity at the grasp [m/s] (paper: [0.056, 0.164, 0.072]).
        grasp_height: Wrist (gripper centre) above the bottle's base at grasp and place [m].
        pelvis_at_grasp: Pelvis pose at the grasp.
        place_time_s: The bottle reaches the target [s]; the human then stands still.
        pelvis_at_place: Pelvis pose at the place instant.
        timing_jitter_s: Std of the per-demo shift of every phase boundary [s].
        path_jitter_m: Std of free waypoint offsets [m].
        contact_jitter_m: Std of the wrist's miss of the bottle and of the target [m].
        yaw_jitter_rad: Std of pelvis yaw offsets [rad].
        grasp_miss_max_m: The check of the ``demos`` stage: every selected demonstration's
            wrist passes within this distance of the grasp point at ``grasp_time_s`` [m]; a
            demonstration farther away did not show the task.
    """

    source: str = "synthetic"
    csv_dir: str = "data/mm_pick_place/recorded"
    scenario: str = "mm_pick_place"
    rate_hz: float = 100.0
    duration_s: float = 26.0
    n_recorded: int = 10
    n_selected: int = 5
    pelvis_start: list[float] = MISSING
    wrist_start: list[float] = MISSING
    walk_end_time_s: float = 15.0
    walk_end_pelvis: list[float] = MISSING
    walk_end_wrist: list[float] = MISSING
    walk_end_wrist_velocity: list[float] = MISSING
    grasp_time_s: float = 18.15
    grasp_velocity: list[float] = MISSING
    grasp_height: float = 0.1
    pelvis_at_grasp: list[float] = MISSING
    place_time_s: float = 23.5
    pelvis_at_place: list[float] = MISSING
    timing_jitter_s: float = 0.2
    path_jitter_m: float = 0.03
    contact_jitter_m: float = 0.004
    yaw_jitter_rad: float = 0.04
    grasp_miss_max_m: float = 0.05

    def check(self) -> list[tuple[str, str]]:
        errors = []
        if self.source not in ("synthetic", "csv"):
            errors.append(("source", f"must be synthetic or csv, got {self.source!r}"))
        folder = PurePosixPath(self.csv_dir or "")
        if not self.csv_dir or folder.is_absolute() or ".." in folder.parts:
            errors.append(
                (
                    "csv_dir",
                    f"must be a folder inside the repository, relative to its root, got "
                    f"{self.csv_dir!r}: copy the recordings into e.g. "
                    f"data/{self.scenario}/recorded/ so that DVC tracks them",
                )
            )
        if not 10.0 <= self.rate_hz <= 1000.0:
            errors.append(("rate_hz", f"must be in [10, 1000] Hz, got {self.rate_hz}"))
        if not 0 < self.n_selected <= self.n_recorded:
            errors.append(("n_selected", "must be in [1, n_recorded]"))
        if not 0.0 < self.walk_end_time_s < self.grasp_time_s < self.place_time_s:
            errors.append(("grasp_time_s", "need 0 < walk_end_time_s < grasp_time_s < place"))
        if self.place_time_s >= self.duration_s:
            errors.append(("place_time_s", "must be before duration_s"))
        for name, n in (
            ("pelvis_start", 3),
            ("wrist_start", 3),
            ("walk_end_pelvis", 3),
            ("walk_end_wrist", 3),
            ("walk_end_wrist_velocity", 3),
            ("grasp_velocity", 3),
            ("pelvis_at_grasp", 3),
            ("pelvis_at_place", 3),
        ):
            errors += _vec(name, getattr(self, name), n)
        if min(self.timing_jitter_s, self.path_jitter_m, self.contact_jitter_m) < 0.0:
            errors.append(("timing_jitter_s", "jitters must be >= 0"))
        samples = self.n_recorded * self.duration_s * self.rate_hz
        errors += at_most("duration_s", self.duration_s, 600.0, "ten minutes is a long task")
        errors += at_most("n_recorded", samples, 2e6, "samples in all (n x duration x rate)")
        if not self.grasp_miss_max_m > 0.0:
            errors.append(("grasp_miss_max_m", f"must be > 0 m, got {self.grasp_miss_max_m}"))
        return errors


@dataclass
class ViaPointCfg:
    """A desired point inserted into the KMP reference (KMP paper, Sec. IV).

    A value left ``null`` is not constrained: that output keeps the reference's mean.

    Attributes:
        time_s: When [s].
        wrist_pos: Wrist position [m], or ``null``.
        wrist_vel: Wrist velocity [m/s], or ``null``.
        pelvis: Pelvis (x [m], y [m], yaw [rad]), or ``null``.
        at: ``grasp`` or ``place``: the wrist position is the plan's grasp point (the
            object's position) or place point (the plan's target) raised by
            ``demos.grasp_height``; overrides ``wrist_pos``.
        wrist_pos_variance: Variance of each constrained wrist position [m^2]; ``null``:
            ``kmp.via_point_variance``. Tiny pins the output, large leaves it to the demos.
        wrist_vel_variance: Same for the wrist velocity [(m/s)^2].
        pelvis_variance: Same for the pelvis (x, y [m^2], yaw [rad^2]).
    """

    # An entry NaN leaves that one output free, as ``null`` leaves the whole group.
    NAN_MEANS_FREE: ClassVar[tuple[str, ...]] = ("wrist_pos", "wrist_vel", "pelvis")

    time_s: float = MISSING
    wrist_pos: list[float] | None = None
    wrist_vel: list[float] | None = None
    pelvis: list[float] | None = None
    at: str | None = None
    wrist_pos_variance: float | None = None
    wrist_vel_variance: float | None = None
    pelvis_variance: float | None = None

    def check(self) -> list[tuple[str, str]]:
        errors = _vec("wrist_pos", self.wrist_pos, 3) + _vec("wrist_vel", self.wrist_vel, 3)
        errors += _vec("pelvis", self.pelvis, 3)
        for name in ("wrist_pos_variance", "wrist_vel_variance", "pelvis_variance"):
            value = getattr(self, name)
            if value is not None and not 0.0 < value < math.inf:
                errors.append((name, f"must be a finite variance > 0, got {value}"))
        if self.at not in (None, "grasp", "place"):
            errors.append(("at", f"must be grasp, place or null, got {self.at!r}"))
        if self.time_s < 0.0:
            errors.append(("time_s", "must be >= 0 s"))
        return errors


@dataclass
class KmpCaseCfg:
    """An adaptation case of the KMP: the via points inserted into the reference."""

    via_points: list[ViaPointCfg] = field(default_factory=list)


@dataclass
class KmpCfg:
    """GMM/GMR reference and KMP (paper B, eq. (1)-(3)).

    Attributes:
        gmm_components: Gaussians of the GMM over (time, outputs).
        gmm_tolerance: EM stops when the mean log-likelihood gains less than this.
        n_reference: Reference points {s_n, mu_n, Sigma_n} extracted by GMR over the task.
        regularization: KMP's lambda (paper: 10).
        kernel_width_s: Width ``l`` of the RBF kernel k(s, s') = exp(-(s - s')^2 / (2 l^2)) [s].
        via_point_variance: Default variance of a via point's constrained outputs
            (units^2); 1e-8 or smaller makes the prediction pass through the point.
        via_point_time_tol_s: A via point this close to a reference point's input replaces
            that point's constrained outputs; any other is inserted [s] (one control period).
        covariance_regularization: lambda_c of the covariance prediction (KMP paper), which
            scales it by N / lambda_c.
        via_point_error_max_m: The check of the ``kmp_fit`` stage: every case's prediction
            passes within this distance of its via points' wrist positions [m].
        rate_hz: Rate of the predicted reference the controller tracks [Hz] (paper: 1 kHz).
        pelvis_to_base_m: Sigma_R sits this far ahead of Sigma_B (paper: 0.3875 m); the
            learned pelvis maps to Sigma_R, the base command is in Sigma_B.
        cases: Named adaptations, each with its via points (``replica`` has the grasp and
            place points only; ``generalisation`` adds the paper's new initial state).
    """

    gmm_components: int = 16
    gmm_tolerance: float = 1e-2
    n_reference: int = 260
    regularization: float = 10.0
    kernel_width_s: float = 1.0
    via_point_variance: float = 1e-10
    via_point_time_tol_s: float = 1e-3
    covariance_regularization: float = 260.0
    via_point_error_max_m: float = 0.01
    rate_hz: float = 1000.0
    pelvis_to_base_m: float = 0.3875
    cases: dict[str, KmpCaseCfg] = field(default_factory=dict)

    def check(self) -> list[tuple[str, str]]:
        errors = []
        if self.gmm_components < 1 or self.n_reference < 10:
            errors.append(("n_reference", "need gmm_components >= 1 and n_reference >= 10"))
        if self.regularization <= 0.0:
            errors.append(("regularization", f"must be > 0, got {self.regularization}"))
        if self.kernel_width_s <= 0.0:
            errors.append(("kernel_width_s", f"must be > 0 s, got {self.kernel_width_s}"))
        if not 0.0 < self.via_point_variance < math.inf:
            errors.append(("via_point_variance", "must be a finite variance > 0"))
        if not 0.0 <= self.via_point_time_tol_s < math.inf:
            errors.append(("via_point_time_tol_s", "must be a finite time >= 0 s"))
        if not 0.0 < self.covariance_regularization < math.inf:
            errors.append(("covariance_regularization", "must be finite and > 0"))
        # KMP solves a 9 n_reference square system: 1000 points is a 0.65 GB matrix.
        errors += at_most("n_reference", self.n_reference, 1000, "KMP's system is 9N x 9N")
        errors += at_most("gmm_components", self.gmm_components, 100, "EM's cost grows with each")
        errors += at_most("rate_hz", self.rate_hz, 10_000.0, "the controller runs at 1 kHz")
        if not self.via_point_error_max_m > 0.0:
            errors.append(("via_point_error_max_m", "must be > 0 m"))
        if not self.cases:
            errors.append(("cases", "define at least one case"))
        for name, case in self.cases.items():
            times = sorted((p.time_s, i) for i, p in enumerate(case.via_points))
            for (t0, i), (t1, j) in itertools.pairwise(times):
                # Two via points at one input average into a point neither asked for.
                if t1 - t0 <= self.via_point_time_tol_s:
                    errors.append(
                        (
                            f"cases.{name}.via_points[{j}].time_s",
                            f"{t1} s is within via_point_time_tol_s of via_points[{i}] "
                            f"({t0} s): merge them into one via point",
                        )
                    )
        return errors


@dataclass
class HqpCfg:
    """Hierarchical QP and low-level control of the mobile manipulator (Sec. III-B, III-C).

    Attributes:
        dt: Control period and simulation step [s] (paper: 0.001).
        kp: CLIK position/orientation gain, the diagonal of K_p in eq. (4) (paper: 4).
        kv: CLIK velocity gain, the diagonal of K_v in eq. (4) (paper: 1).
        measured_velocity_feedback: Use eq. (4) literally, K_v (xd_dot - xa_dot) with the
            measured xa_dot; ``false`` (default) uses the feed-forward K_v xd_dot instead,
            because feeding the measured velocity back in a velocity-resolved law lags
            and chatters (see :mod:`locoman.hqp.tasks`).
        level2_gain: Level 2 drives q* to its targets at this rate [1/s]: eq. (6) divided by
            dt reads H qdot = (q_d - q*) / dt, and ``null`` keeps that 1 / dt. A dead-beat
            gain under the acceleration limits (9) overshoots and chatters, so the default
            spreads the correction over 1 s.
        arm_mid_range_weight: Weight of eq. (6)'s arm mid-range term against the base term
            (paper: 1). Both terms pull on the four degrees of freedom level 1 leaves free;
            at 1, the arm's pull moves the base up to 0.75 m off the learned pose, into the
            table, so the default lets the base term lead.
        joint_stiffness: K_{q_a,p} of the joint impedance law (10) [N m/rad] (paper: 20).
        joint_damping: K_{q_a,d} of (10) [N m s/rad] (paper: 8).
        base_velocity_max: Base velocity limits (x [m/s], y [m/s], yaw [rad/s]).
        base_acceleration_max: Base acceleration limits ([m/s^2], [m/s^2], [rad/s^2]).
        arm_velocity_max: Panda joint velocity limits [rad/s] (Franka datasheet).
        arm_acceleration_max: Panda joint acceleration limits [rad/s^2] (Franka datasheet).
        position_margin: Margin kept inside the Panda's position limits [rad].
        success_tolerance_m: The task succeeds if the bottle ends this close to the target.
    """

    dt: float = 0.001
    kp: float = 4.0
    kv: float = 1.0
    measured_velocity_feedback: bool = False
    level2_gain: float | None = 1.0
    arm_mid_range_weight: float = 0.05
    joint_stiffness: float = 20.0
    joint_damping: float = 8.0
    base_velocity_max: list[float] = field(default_factory=lambda: [0.5, 0.5, 0.5])
    base_acceleration_max: list[float] = field(default_factory=lambda: [0.5, 0.5, 0.3])
    arm_velocity_max: list[float] = MISSING
    arm_acceleration_max: list[float] = MISSING
    position_margin: float = 0.05
    success_tolerance_m: float = 0.03

    def check(self) -> list[tuple[str, str]]:
        errors = []
        if not 1e-4 <= self.dt <= 1e-2:
            errors.append(("dt", f"must be in [1e-4, 1e-2] s, got {self.dt}"))
        if self.kp <= 0.0 or self.kv < 0.0:
            errors.append(("kp", "need kp > 0 and kv >= 0"))
        if self.level2_gain is not None and self.level2_gain <= 0.0:
            errors.append(("level2_gain", f"must be > 0 [1/s] or null, got {self.level2_gain}"))
        if self.arm_mid_range_weight <= 0.0:
            errors.append(("arm_mid_range_weight", "must be > 0"))
        if self.joint_stiffness <= 0.0 or self.joint_damping < 0.0:
            errors.append(("joint_stiffness", "need stiffness > 0 and damping >= 0"))
        errors += _vec("base_velocity_max", self.base_velocity_max, 3)
        errors += _vec("base_acceleration_max", self.base_acceleration_max, 3)
        errors += _vec("arm_velocity_max", self.arm_velocity_max, 7)
        errors += _vec("arm_acceleration_max", self.arm_acceleration_max, 7)
        limits = (
            self.base_velocity_max
            + self.base_acceleration_max
            + self.arm_velocity_max
            + self.arm_acceleration_max
        )
        if any(v <= 0.0 for v in limits):
            errors.append(("base_velocity_max", "velocity and acceleration limits must be > 0"))
        return errors
