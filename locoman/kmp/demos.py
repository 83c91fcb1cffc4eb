"""Human demonstrations of the bottle pick-and-place, as recorded in paper B (Sec. IV-A).

A demonstration is the wrist position and velocity and the pelvis pose (x, y, yaw) sampled
at a fixed rate; these are the outputs xi = [x_wr, xdot_wr, x_pe] the KMP learns (Sec. III-A).

:func:`synthetic_demos` stands in for the motion-capture sessions: the subject starts from
the same pose, walks towards the table (the pelvis does most of the motion), turns, grasps
the bottle on the move at the grasp instant with the paper's wrist velocity, carries it and
places it at the target, then stands still. Every demonstration moves its phase boundaries
and free waypoints by a random amount and sways laterally while walking, so the set varies
like a human's. The waypoints are joined by cubic Hermite segments, whose derivative gives
the wrist velocity.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy.interpolate import CubicHermiteSpline

from locoman.config.skill_transfer import DemosCfg
from locoman.errors import SceneError

#: Lateral pelvis sway while walking: amplitude [m] and step frequency [Hz].
SWAY_AMPLITUDE_M = 0.015
SWAY_FREQUENCY_HZ = 0.9
#: The carried bottle is lifted this much above the straight grasp-to-place line [m].
CARRY_LIFT_M = 0.08


@dataclasses.dataclass(frozen=True)
class Demos:
    """A set of demonstrations on a common time grid.

    Attributes:
        time_s: (N,) sample times [s].
        wrist_pos: (M, N, 3) wrist position, world [m].
        wrist_vel: (M, N, 3) wrist velocity, world [m/s].
        pelvis: (M, N, 3) pelvis pose (x [m], y [m], yaw [rad]), world.
    """

    time_s: np.ndarray
    wrist_pos: np.ndarray
    wrist_vel: np.ndarray
    pelvis: np.ndarray

    @property
    def outputs(self) -> np.ndarray:
        """(M, N, 9) the KMP outputs xi = [x_wr, xdot_wr, x_pe] per sample."""
        return np.concatenate([self.wrist_pos, self.wrist_vel, self.pelvis], axis=2)

    def subset(self, index: np.ndarray) -> Demos:
        return Demos(self.time_s, self.wrist_pos[index], self.wrist_vel[index], self.pelvis[index])


@dataclasses.dataclass(frozen=True)
class TaskPoints:
    """Where the task happens, from the scene.

    Attributes:
        grasp: Wrist position at the grasp [m]: the bottle raised by the grasp height.
        place: Wrist position at the place instant [m]: the target raised likewise.
    """

    grasp: np.ndarray
    place: np.ndarray


def _hermite(times: np.ndarray, points: np.ndarray, vels: list[np.ndarray | None]):
    """Cubic Hermite through ``points``; a ``None`` velocity is Catmull-Rom's estimate."""
    v = np.empty_like(points)
    for i, given in enumerate(vels):
        if given is not None:
            v[i] = given
        else:
            a, b = max(i - 1, 0), min(i + 1, len(times) - 1)
            v[i] = (points[b] - points[a]) / (times[b] - times[a])
    return CubicHermiteSpline(times, points, v, axis=0)


def _one_demo(
    cfg: DemosCfg, task: TaskPoints, t: np.ndarray, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    jt, jp, jc, jy = (
        cfg.timing_jitter_s,
        cfg.path_jitter_m,
        cfg.contact_jitter_m,
        cfg.yaw_jitter_rad,
    )
    t_walk = cfg.walk_end_time_s + rng.normal(0, jt)
    t_grasp = cfg.grasp_time_s + rng.normal(0, jt)
    t_place = cfg.place_time_s + rng.normal(0, jt)
    if not 0.0 < t_walk < t_grasp < t_place < cfg.duration_s:
        t_walk, t_grasp, t_place = cfg.walk_end_time_s, cfg.grasp_time_s, cfg.place_time_s
    t_carry = 0.5 * (t_grasp + t_place)

    def jitter(sd: float, n: int = 3) -> np.ndarray:
        return rng.normal(0.0, sd, n)

    w0 = np.asarray(cfg.wrist_start) + jitter(jc)
    w_walk = np.asarray(cfg.walk_end_wrist) + jitter(jp)
    w_grasp = task.grasp + jitter(jc)
    w_place = task.place + jitter(jc)
    w_carry = 0.5 * (w_grasp + w_place) + np.r_[0.0, 0.0, CARRY_LIFT_M] + jitter(jp)
    w_mid = 0.5 * (w0 + w_walk) + np.r_[0.0, 0.0, 0.03] + jitter(jp)
    speed_scale = 1.0 + rng.normal(0.0, 0.08)
    wrist = _hermite(
        np.array([0.0, 0.5 * t_walk, t_walk, t_grasp, t_carry, t_place, cfg.duration_s]),
        np.array([w0, w_mid, w_walk, w_grasp, w_carry, w_place, w_place]),
        [
            np.zeros(3),
            None,
            speed_scale * np.asarray(cfg.walk_end_wrist_velocity),
            speed_scale * np.asarray(cfg.grasp_velocity),
            None,
            np.zeros(3),
            np.zeros(3),
        ],
    )

    def pose(base: list[float], sd_xy: float) -> np.ndarray:
        return np.asarray(base) + np.r_[jitter(sd_xy, 2), rng.normal(0.0, jy)]

    p0 = pose(cfg.pelvis_start, jc)
    p_walk = pose(cfg.walk_end_pelvis, jp)
    p_grasp = pose(cfg.pelvis_at_grasp, jp)
    p_place = pose(cfg.pelvis_at_place, jp)
    p_mid = 0.5 * (p0 + p_walk) + np.r_[jitter(jp, 2), 0.0]
    pelvis = _hermite(
        np.array([0.0, 0.5 * t_walk, t_walk, t_grasp, t_place, cfg.duration_s]),
        np.array([p0, p_mid, p_walk, p_grasp, p_place, p_place]),
        [np.zeros(3), None, None, None, np.zeros(3), np.zeros(3)],
    )

    # Gait sway: lateral in the pelvis frame, faded in and out over the walk.
    phase = rng.uniform(0.0, 2.0 * np.pi)
    window = np.where(t < t_walk, np.sin(np.pi * np.clip(t / t_walk, 0.0, 1.0)) ** 2, 0.0)
    sway = SWAY_AMPLITUDE_M * window * np.sin(2.0 * np.pi * SWAY_FREQUENCY_HZ * t + phase)
    pel = pelvis(t)
    pel[:, 0] -= sway * np.sin(pel[:, 2])
    pel[:, 1] += sway * np.cos(pel[:, 2])
    return wrist(t), wrist(t, 1), pel


def synthetic_demos(
    cfg: DemosCfg, task: TaskPoints, seed: int
) -> tuple[Demos, np.ndarray, np.ndarray]:
    """Record ``cfg.n_recorded`` demonstrations and select ``cfg.n_selected`` of them.

    The selection keeps the demonstrations whose wrist is closest to the grasp point at the
    nominal grasp instant, as an experimenter keeps the trials where the grasp happened on
    time.

    Returns:
        (all recorded demos, indices of the selected ones (sorted), grasp miss per demo [m]).
    """
    rng = np.random.default_rng(seed)
    n = round(cfg.duration_s * cfg.rate_hz) + 1
    t = np.linspace(0.0, cfg.duration_s, n)
    runs = [_one_demo(cfg, task, t, rng) for _ in range(cfg.n_recorded)]
    demos = Demos(
        t,
        np.stack([r[0] for r in runs]),
        np.stack([r[1] for r in runs]),
        np.stack([r[2] for r in runs]),
    )
    return demos, *select_demos(demos, task, cfg.grasp_time_s, cfg.n_selected)


def select_demos(
    demos: Demos, task: TaskPoints, grasp_time_s: float, n_selected: int
) -> tuple[np.ndarray, np.ndarray]:
    """Indices (sorted) of the ``n_selected`` demos nearest the grasp point at the grasp time.

    Returns:
        (selected indices, per-demo distance from the wrist to the grasp point [m]).
    """
    k = int(np.argmin(np.abs(demos.time_s - grasp_time_s)))
    miss = np.linalg.norm(demos.wrist_pos[:, k] - task.grasp, axis=1)
    return np.sort(np.argsort(miss, kind="stable")[:n_selected]), miss


#: The bottle is released this far above the table [m], so it never starts inside it.
PLACE_CLEARANCE_M = 0.005


def task_points(objects: dict, plan: dict, grasp_height: float) -> tuple[str, TaskPoints]:
    """The carried object and the wrist's grasp and place points from the scene artifacts.

    The grasp point is the object's base raised by ``grasp_height``; the place point is the
    first subtask target for that object, raised by the same height plus
    :data:`PLACE_CLEARANCE_M`.

    Raises:
        SceneError: If the plan has no subtask that moves an object to a target.
    """
    moving = [s for s in plan["subtasks"] if s["target"] is not None]
    if not moving:
        raise SceneError("the plan has no subtask with a target; nothing to pick and place")
    name = moving[0]["object"]
    up = np.array([0.0, 0.0, grasp_height])
    grasp = np.asarray(objects[name]["pos_m"], dtype=float) + up
    place = np.asarray(moving[0]["target"]["pos_m"], dtype=float) + up
    return name, TaskPoints(grasp, place + np.array([0.0, 0.0, PLACE_CLEARANCE_M]))
