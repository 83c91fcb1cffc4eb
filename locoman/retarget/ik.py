"""Whole-body IK with placo: one G1 keyframe per subtask (paper A, Sec. III-A.3).

The paper's IK places the hands and feet on the transferred contacts, keeps the feet flat,
and is guided by the human's joint angles. Here, per keyframe (weights in
:class:`~locoman.config.retarget.RetargetCfg`):

- hands: position tasks of the palm centres at the hand contacts, moved out along the
  surface normal by the palm's radius so the hand rests on the surface;
- feet in contact: frame tasks of the sole centres at the foot contacts, flat and turned like
  the base; standing feet: flat on their support, with a low-weight pull in the plane
  towards the stance :mod:`.problem` derives from the human, so the robot may step closer;
- the heading of the human placement (roll and pitch free, so the robot may lean);
- the mapped human joint angles, a low-weight posture task, so they only guide;
- joint limits, hard; self-collision avoidance (placo's constraint on the pure-shape model
  of :mod:`.robot`, margin ``collision_margin_m``) and the CoM over the support polygon
  (margin ``com_margin_m``), both heavy but soft.

placo bounds each step by the velocity limits, and a hard task or constraint that one
bounded step cannot meet makes the QP infeasible; so everything but the joint limits is
soft, an unreachable contact cannot make the QP infeasible, and each hand
is pulled towards its contact by a bounded error (``reach_step_m``) that the much heavier
feet outweigh: an unreachable hand leans as far as it can without dragging the body off its
feet (the soft version), and the miss is reported with its distance.
"""

from __future__ import annotations

import contextlib
import ctypes
import dataclasses
import os
import sys
from collections.abc import Iterator, Sequence

import numpy as np
import placo

from locoman.config.retarget import RetargetCfg
from locoman.errors import SolverError
from locoman.retarget.robot import PALM_FRAMES, SOLE_FRAMES, contact_frames, placo_robot
from locoman.scene import g1

BASE_FRAME = "pelvis"


@dataclasses.dataclass(frozen=True)
class ContactTarget:
    """One end effector's target.

    Attributes:
        effector: ``left_hand``, ``right_hand``, ``left_foot`` or ``right_foot``.
        point: Contact location on the surface, world [m].
        normal: Outward surface normal there.
        in_contact: Whether the plan puts this end effector in contact (False: a foot that
            only stands).
        planted: A standing foot that keeps its place (it stands on an object an earlier
            subtask stepped onto; moving it would be a step the plan does not have).
    """

    effector: str
    point: np.ndarray
    normal: np.ndarray
    in_contact: bool
    planted: bool = False


@dataclasses.dataclass(frozen=True)
class IKProblem:
    """What one keyframe must satisfy.

    Attributes:
        hands: Hand contacts.
        feet: Foot contacts (``in_contact``) and the standing feet.
        R_world_base: Base orientation of the human placement.
        posture: Mapped human joint angles (29,) [rad].
        base_xy: (2,) where the base starts [m].
    """

    hands: tuple[ContactTarget, ...]
    feet: tuple[ContactTarget, ...]
    R_world_base: np.ndarray
    posture: np.ndarray
    base_xy: np.ndarray


@dataclasses.dataclass(frozen=True)
class IKResult:
    """A solved keyframe.

    Attributes:
        q: Pinocchio configuration (36,).
        q35: Keyframe configuration (35,): base position [m], roll-pitch-yaw [rad], joints.
        effectors: End effectors, hands then feet.
        targets: (E, 3) where each end effector's palm or sole centre should be [m] (for a
            standing foot: on its support, below where it is).
        reached: (E, 3) where it is [m].
        residual_m: (E,) distance between the two [m].
        unreachable: Hand -> how far it stays from its target [m], for those missed by more
            than ``reach_tolerance_m``.
        iterations: IK steps taken.
    """

    q: np.ndarray
    q35: np.ndarray
    effectors: list[str]
    targets: np.ndarray
    reached: np.ndarray
    residual_m: np.ndarray
    unreachable: dict[str, float]
    iterations: int


@dataclasses.dataclass(frozen=True)
class IKRound:
    """The weights of one round of starts (see :meth:`Retargeter.solve`).

    Attributes:
        posture_weight: Mapped human joint angles [-].
        collision_margin_m: Self-collision margin [m].
        palm_facing_weight: Each palm's normal into its contact surface (0: free) [-].
    """

    posture_weight: float
    collision_margin_m: float
    palm_facing_weight: float


@contextlib.contextmanager
def _quiet_stdout() -> Iterator[None]:
    """Silence C++ output on file descriptors 1 and 2 (placo reports neutral-pose collisions of the
    hanging arms, which the keyframes never keep)."""
    sys.stdout.flush()
    sys.stderr.flush()
    libc = ctypes.CDLL(None)
    saved = [os.dup(1), os.dup(2)]
    try:
        with open(os.devnull, "w") as devnull:
            os.dup2(devnull.fileno(), 1)
            os.dup2(devnull.fileno(), 2)
            yield
            libc.fflush(None)
    finally:
        for fd, copy in ((1, saved[0]), (2, saved[1])):
            os.dup2(copy, fd)
            os.close(copy)


def yaw_of(rot: np.ndarray) -> float:
    """Heading [rad] of a rotation's x axis in the horizontal plane."""
    return float(np.arctan2(rot[1, 0], rot[0, 0]))


def yaw_matrix(yaw: float) -> np.ndarray:
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def support_polygon(soles: Sequence[np.ndarray], yaws: Sequence[float]) -> np.ndarray:
    """Convex hull (P, 2) [m], counter-clockwise, of the foot soles' rectangles, given their
    centres (3,) [m] and headings [rad]."""
    half = contact_frames().sole_half_extents
    corners = []
    for centre, yaw in zip(soles, yaws, strict=True):
        rot = yaw_matrix(yaw)[:2, :2]
        for sx in (-1.0, 1.0):
            for sy in (-1.0, 1.0):
                corners.append(centre[:2] + rot @ (half * np.array([sx, sy])))
    return convex_hull(np.array(corners))


def convex_hull(points: np.ndarray) -> np.ndarray:
    """Counter-clockwise convex hull (P, 2) of 2D points (monotone chain)."""
    pts = sorted({(float(x), float(y)) for x, y in points})
    if len(pts) < 3:
        return np.array(pts)

    def half(seq: list[tuple[float, float]]) -> list[tuple[float, float]]:
        out: list[tuple[float, float]] = []
        for p in seq:
            while len(out) >= 2:
                (ax, ay), (bx, by) = out[-2], out[-1]
                if (bx - ax) * (p[1] - ay) - (by - ay) * (p[0] - ax) > 0.0:
                    break
                out.pop()
            out.append(p)
        return out

    lower, upper = half(pts), half(pts[::-1])
    return np.array(lower[:-1] + upper[:-1])


def polygon_margin(point: np.ndarray, polygon: np.ndarray) -> float:
    """Signed distance [m] of a 2D point inside a counter-clockwise convex polygon: > 0
    inside (distance to the nearest edge), < 0 outside."""
    margins = []
    for a, b in zip(polygon, np.roll(polygon, -1, axis=0), strict=True):
        edge = b - a
        normal = np.array([edge[1], -edge[0]]) / np.linalg.norm(edge)  # outward for CCW
        margins.append(-float(normal @ (point - a)))
    return min(margins)


class Retargeter:
    """placo kinematics solver for G1 keyframes; holds the robot model between subtasks."""

    def __init__(self, cfg: RetargetCfg) -> None:
        self.cfg = cfg
        with _quiet_stdout():
            self.robot = placo_robot()
        self.frames = contact_frames()

    def solve(self, problem: IKProblem) -> IKResult:
        """Solve one keyframe, from each of the starts of :func:`start_configurations` in
        turn until one meets every contact with the base's roll and pitch within
        ``base_tilt_max_rad``; otherwise the one that comes closest (a tilted base ranks
        after every upright one).

        When no start succeeds, the starts are tried again at ``fallback_posture_weight``,
        ``fallback_collision_margin_m`` and ``fallback_palm_facing_weight``: the human's
        angles then guide less than the contacts demand, the arms may pass closer to the
        legs (a robot with a shorter reach bends further to a box on the floor) and the
        palms face their surfaces (a wrist turned under a palm would go through the shelf
        the palm reaches over).

        Raises:
            SolverError: When placo's QP fails (the message names the step).
        """
        best: IKResult | None = None
        steps = 0
        cfg = self.cfg
        rounds = [IKRound(cfg.posture_weight, cfg.collision_margin_m, 0.0)]
        if cfg.fallback_posture_weight is not None and cfg.fallback_collision_margin_m is not None:
            rounds.append(
                IKRound(
                    cfg.fallback_posture_weight,
                    cfg.fallback_collision_margin_m,
                    cfg.fallback_palm_facing_weight,
                )
            )
        starts = start_configurations(problem, cfg.start_knees_rad)
        for ik_round in rounds:
            for q_start in starts:
                result = self._solve_from(problem, q_start, ik_round)
                steps += result.iterations
                if best is None or self._rank(result) < self._rank(best):
                    best = result
                if self._rank(result) == (False, 0.0):
                    return dataclasses.replace(result, iterations=steps)
        if best is None:
            raise SolverError("retarget.start_knees_rad is empty: the IK has no start")
        return dataclasses.replace(best, iterations=steps)

    def _rank(self, result: IKResult) -> tuple[bool, float]:
        """(base tilted beyond the bound, total miss [m]): smaller is better."""
        tilted = bool(np.max(np.abs(result.q35[3:5])) > self.cfg.base_tilt_max_rad)
        return tilted, _total_miss(result)

    def _solve_from(self, problem: IKProblem, q_start: np.ndarray, ik_round: IKRound) -> IKResult:
        cfg, robot = self.cfg, self.robot
        robot.state.q = q_start.copy()
        robot.update_kinematics()
        solver = placo.KinematicsSolver(robot)
        solver.mask_fbase(False)
        solver.enable_joint_limits(True)
        solver.enable_velocity_limits(True)
        solver.dt = cfg.step_s
        solver.add_regularization_task(cfg.regularization)
        base_yaw = yaw_of(problem.R_world_base)
        targets: dict[str, np.ndarray] = {}
        hand_tasks: dict[str, placo.PositionTask] = {}
        for hand in problem.hands:
            target = hand.point + self.frames.palm_radius * hand.normal
            task = solver.add_position_task(PALM_FRAMES[hand.effector], target)
            task.configure(hand.effector, "soft", cfg.hand_weight)
            targets[hand.effector] = target
            hand_tasks[hand.effector] = task
            if ik_round.palm_facing_weight > 0.0:
                # The palm's outward normal into the surface, as the demonstrator holds it.
                frame = PALM_FRAMES[hand.effector]
                facing = solver.add_axisalign_task(
                    frame, self.frames.palm_axes[frame][:, 2], -np.asarray(hand.normal)
                )
                facing.configure(f"{hand.effector}_facing", "soft", ik_round.palm_facing_weight)
        for foot in problem.feet:
            frame = SOLE_FRAMES[foot.effector]
            if foot.in_contact or foot.planted:
                task = solver.add_frame_task(frame, _flat_pose(foot.point, base_yaw))
                task.configure(foot.effector, "soft", cfg.foot_weight, cfg.foot_flat_weight)
                continue
            # A standing foot: flat on its support, and only guided to the human's stance in
            # the plane, so a shorter robot may step closer to what it reaches for.
            height = solver.add_position_task(frame, foot.point)
            height.configure(f"{foot.effector}_height", "soft", cfg.foot_weight)
            height.mask.set_axises("z", "world")
            stance = solver.add_position_task(frame, foot.point)
            stance.configure(f"{foot.effector}_stance", "soft", cfg.stance_weight)
            stance.mask.set_axises("xy", "world")
            flat = solver.add_orientation_task(frame, yaw_matrix(base_yaw))
            flat.configure(f"{foot.effector}_flat", "soft", cfg.foot_flat_weight)
        # The heading of the human placement; roll and pitch stay free, so the robot may lean
        # where the taller human only bent its back.
        base = solver.add_orientation_task(BASE_FRAME, problem.R_world_base)
        base.configure("base", "soft", cfg.base_weight)
        base.mask.set_axises("z", "world")
        posture = solver.add_joints_task()
        posture.set_joints(dict(zip(g1.G1_JOINT_NAMES, problem.posture.tolist(), strict=True)))
        posture.configure("posture", "soft", ik_round.posture_weight)
        collisions = solver.add_avoid_self_collisions_constraint()
        collisions.configure("self_collisions", "soft", cfg.collision_weight)
        collisions.self_collisions_margin = ik_round.collision_margin_m
        collisions.self_collisions_trigger = cfg.collision_trigger_m
        com = solver.add_com_polygon_constraint([], cfg.com_margin_m)
        com.configure("com_support", "soft", cfg.com_weight)
        steps = self._iterate(
            solver,
            {PALM_FRAMES[n]: (t, targets[n]) for n, t in hand_tasks.items()},
            com,
            [SOLE_FRAMES[foot.effector] for foot in problem.feet],
            base_yaw,
        )
        # The QP meets the joint limits up to its tolerance (1e-16 rad); the keyframe meets
        # them exactly.
        q = robot.state.q.copy()
        model = robot.model
        q[7:] = np.clip(q[7:], model.lowerPositionLimit[7:], model.upperPositionLimit[7:])
        robot.state.q = q.copy()
        robot.update_kinematics()
        effectors, want, got = [], [], []
        for hand in problem.hands:
            effectors.append(hand.effector)
            want.append(targets[hand.effector])
            got.append(robot.get_T_world_frame(PALM_FRAMES[hand.effector])[:3, 3])
        for foot in problem.feet:
            effectors.append(foot.effector)
            sole = robot.get_T_world_frame(SOLE_FRAMES[foot.effector])[:3, 3]
            # A standing foot may step in the plane; only its support's height is a target.
            fixed = foot.in_contact or foot.planted
            want.append(foot.point if fixed else np.r_[sole[:2], foot.point[2]])
            got.append(sole)
        want_a, got_a = np.array(want).reshape(-1, 3), np.array(got).reshape(-1, 3)
        residual = np.linalg.norm(got_a - want_a, axis=1)
        return IKResult(
            q=q,
            q35=g1.pin_to_q35(q),
            effectors=effectors,
            targets=want_a,
            reached=got_a,
            residual_m=residual,
            unreachable={
                e: float(r)
                for e, r in zip(effectors, residual, strict=True)
                if e.endswith("_hand") and r > cfg.reach_tolerance_m
            },
            iterations=steps,
        )

    def _iterate(
        self,
        solver: placo.KinematicsSolver,
        goals: dict[str, tuple[placo.PositionTask, np.ndarray]],
        com: placo.CoMPolygonConstraint,
        soles: list[str],
        yaw: float,
    ) -> int:
        """IK steps until q moves by less than the tolerance; returns how many.

        Each goal's task is aimed at most ``reach_step_m`` from where its frame is: a far
        goal is approached by small linearised steps instead of one that overshoots, and an
        unreachable one pulls with a bounded error, so it cannot drag the feet along. The
        support polygon follows the soles, since a standing foot may step.
        """
        robot, limit = self.robot, self.cfg.reach_step_m
        for step in range(1, self.cfg.iterations + 1):
            centres = [robot.get_T_world_frame(frame)[:3, 3] for frame in soles]
            # placo wants the polygon clockwise.
            com.polygon = list(support_polygon(centres, [yaw] * len(centres))[::-1])
            for frame, (task, goal) in goals.items():
                here = robot.get_T_world_frame(frame)[:3, 3]
                gap = goal - here
                norm = float(np.linalg.norm(gap))
                task.target_world = here + gap * min(1.0, limit / norm) if norm > 0.0 else goal
            before = robot.state.q.copy()
            try:
                solver.solve(True)
            except RuntimeError as err:
                raise SolverError(f"placo IK failed at step {step}: {err}") from None
            robot.update_kinematics()
            if np.linalg.norm(robot.state.q - before) < self.cfg.tolerance:
                return step
        return self.cfg.iterations


def _flat_pose(point: np.ndarray, yaw: float) -> np.ndarray:
    pose = np.eye(4)
    pose[:3, :3] = yaw_matrix(yaw)
    pose[:3, 3] = point
    return pose


def start_configurations(problem: IKProblem, knees: Sequence[float]) -> list[np.ndarray]:
    """Pinocchio configurations (36,) to start from: the G1's own standing posture with its
    knees bent by each of ``knees`` [rad] (hips and ankles by half as much, so the torso stays
    upright), at ``problem.base_xy`` with the base's heading, soles on the feet's support.

    Not the mapped human posture: a human's straight legs put the G1 at its knee limits,
    where the bounded IK steps get stuck, and a human's arms at the sides go through the
    G1's wider torso; the posture task pulls towards the human's angles from there. A
    crouched start reaches low contacts that the local IK does not find from standing.
    """
    support = float(np.mean([foot.point[2] for foot in problem.feet]))
    starts = []
    for knee in knees:
        joints = dict(g1.STANDING_JOINTS)
        for side in ("left", "right"):
            joints[f"{side}_knee_joint"] = knee
            joints[f"{side}_hip_pitch_joint"] = -0.5 * knee
            joints[f"{side}_ankle_pitch_joint"] = -0.5 * knee
        q35 = g1.standing_q35(joints)
        q35[:2] = problem.base_xy
        q35[2] += support
        q35[5] = yaw_of(problem.R_world_base)
        starts.append(g1.q35_to_pin(q35))
    return starts


def _total_miss(result: IKResult) -> float:
    return float(sum(result.unreachable.values()))
