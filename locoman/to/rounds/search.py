"""The rounds of found pairs (paper A's minimal set is the start).

After a solve, the solution is replayed in the MuJoCo scene (:mod:`locoman.sim.audit`): every
pair of bodies closer than a margin that the contact schedule does not let touch is mapped
to the TO's own pairs that keep them apart (:mod:`locoman.to.rounds.found_pairs`). Those the
problem does not have yet join it, under the ``found`` kind's treatment, and the solve goes
on from the previous primal-dual point. Since the terms are compiled once per robot, a
round costs a new assembly (seconds) and the warm-started solve.
"""

from __future__ import annotations

import dataclasses
import logging
import time

import mujoco
import numpy as np

from locoman.config.to import CollisionCfg
from locoman.retarget.robot import contact_frames
from locoman.sim.audit import ClosePair, close_pairs
from locoman.to.collisions.pairs import CollisionPair
from locoman.to.rounds.found_pairs import (
    PROMOTED,
    Check,
    SolutionScene,
    arm_pairs,
    round_pairs,
    unmodelled,
)
from locoman.to.solve.optimizer import TrajectoryOptimizer
from locoman.to.solve.trajectory import Trajectory

log = logging.getLogger(__name__)


def trajectory_arrays(traj: Trajectory, names: list[str]) -> dict[str, np.ndarray]:
    """What :func:`locoman.sim.audit.close_pairs` reads of a trajectory."""
    fields = (
        "q",
        "object_q",
        "foot_object",
        "feet_contact",
        "hand_object",
        "support_kind",
        "support_base",
    )
    return {f: getattr(traj, f) for f in fields} | {
        "object_active": traj.object_active,
        "object_names": np.array(names),
    }


@dataclasses.dataclass(frozen=True)
class Round:
    """One check of a solution, and the solve it led to.

    Attributes:
        close_pairs: Pairs closer than the margin the schedule does not allow.
        deepest_m: The least distance among them [m] (negative: inside).
        pairs_added: Pairs the problem lacked that join it.
        iterations, solve_time_s, status: Of the warm-started solve with them (0, 0, "":
            none, after the last check).
        deepest_pair: The geoms of the closest pair (``a | b``; "" with none).
        demoted: Pairs promoted to (11) in this round whose solve ended infeasible, left out of the
            second attempt (:func:`search`).
        restart: No check: the solve started again from the guess with every pair found
            (the rounds before had left pairs missing or unfreed).
    """

    close_pairs: int
    deepest_m: float
    pairs_added: int
    iterations: int = 0
    solve_time_s: float = 0.0
    status: str = ""
    deepest_pair: str = ""
    demoted: int = 0
    restart: bool = False


@dataclasses.dataclass(frozen=True)
class SearchResult:
    """What :func:`search` ends with.

    Attributes:
        trajectory: The last solve (its iterations and solve time those of every solve);
            not a success, with status ``Collision_Pairs_Missing`` or
            ``Collision_Pairs_Unfreed``, where pairs are left missing or unfreed.
        rounds: Every check and the solve it led to, restarts included.
        missing: Close pairs the problem still lacks pairs for at the last check.
        unfreed: Close pairs still deeper than ``cfg.unfreed_m`` there, modelled or not.
    """

    trajectory: Trajectory
    rounds: list[Round]
    missing: list[ClosePair]
    unfreed: list[ClosePair]


def _ended(
    traj: Trajectory, rounds: list[Round], missing: list[ClosePair], unfreed: list[ClosePair]
) -> SearchResult:
    if (missing or unfreed) and traj.success:
        # The rounds ran out with pairs the solution needs still missing, or left a pair
        # they could not free: not a solution.
        status = "Collision_Pairs_Missing" if missing else "Collision_Pairs_Unfreed"
        traj = dataclasses.replace(traj, success=False, status=status)
    return SearchResult(traj, rounds, missing, unfreed)


@dataclasses.dataclass
class _Search:
    """The state the rounds share: the problem's solver and the scene a check replays in,
    the pairs so far, the rounds and totals so far, every close pair seen, and whether a
    round may still promote found pairs to (11) (``cfg.found_hard`` or ``off``)."""

    optimizer: TrajectoryOptimizer
    model: mujoco.MjModel
    scene: SolutionScene
    cfg: CollisionCfg
    pairs: list[CollisionPair]
    rounds: list[Round]
    totals: _Totals
    promote: str
    seen: list[ClosePair]


# IPOPT's statuses for "no feasible point here": a round ending so with promotions is
# solved again without them (:func:`search`).
INFEASIBLE = ("Infeasible_Problem_Detected", "Restoration_Failed")


def search(
    optimizer: TrajectoryOptimizer,
    traj: Trajectory,
    model: mujoco.MjModel,
    scene: SolutionScene,
    cfg: CollisionCfg,
) -> SearchResult:
    """Check ``traj``, add the pairs it needs and solve on from it, at most ``cfg.rounds``
    times (:func:`_rounds`); if pairs are left missing or unfreed or a round fails, solve
    again from Sec. IV-C.2's guess with every pair found so far and go on with the rounds
    from there, at most ``cfg.restarts`` times (:class:`SearchResult`); with ``found`` off,
    no rounds or a failed ``traj``: ``traj``.

    Why start again: pairs that join a solution already through an object can hold it in
    a local minimum that they cannot free. S1 without the keyframes' warm start: the first
    solve, without the wrist's pairs against the basket, reaches under the basket's floor;
    once found, the floor's pair pushes the wrist down into the shelf and the shelf's pair
    pushes it up (three rounds, 30 mm deep at the end). Present from the first iteration,
    the same pairs kept the reach out in three of the six S1 Fig. 6 cells that ended so
    (docs/figures.md). A round whose solve fails (out of iterations, its point no motion to
    check) starts again the same way while restarts remain (S2's Fig. 6 Foot at 5 kg,
    1.2 rad: the first round runs out of iterations, the restart converges); a failed
    restart ends the search with its failure.
    """
    pairs = list(optimizer.transcription.pairs)
    rounds: list[Round] = []
    totals = _Totals(traj)
    if cfg.found == "off" or cfg.rounds == 0 or not traj.success:
        return SearchResult(traj, rounds, [], [])  # a failed solve is no solution to check
    state = _Search(optimizer, model, scene, cfg, pairs, rounds, totals, cfg.found_hard, [])
    restarts, seen = 0, state.seen
    while True:
        traj, remaining, unfreed = _rounds(state, traj)
        # A round that failed (out of iterations from an optimum its new pairs moved by
        # centimetres) leaves no motion to check: like pairs left missing or unfreed, it
        # sends the search back to the guess, now with every pair found.
        if restarts == cfg.restarts or (traj.success and not (remaining or unfreed)):
            return _ended(totals.of(traj), rounds, remaining, unfreed)
        restarts += 1
        arms = []
        if cfg.restart_arm_nodes > 0:
            arms = arm_pairs(seen, pairs, _checked(scene, traj, cfg), cfg.restart_arm_nodes)
            pairs.extend(arms)
        why = (
            f"{len(remaining)} pairs missing, {len(unfreed)} unfreed"
            if traj.success
            else f"the round ended {traj.status}"
        )
        log.info(
            f"restart {restarts}: {why}; solving again from the guess with the "
            f"{len(pairs)} pairs"
            + (f" ({len(arms)} of them the found arms' whole)" if arms else "")
        )
        tic = time.perf_counter()
        traj = optimizer.solve(pairs=pairs, label=f"restart {restarts}")
        seconds = time.perf_counter() - tic
        solved = _round([], None, arms, traj, seconds, traj.iterations)
        rounds.append(dataclasses.replace(solved, restart=True))
        totals.add(traj)
        if not traj.success:
            return SearchResult(totals.of(traj), rounds, [], [])


def _rounds(
    state: _Search, traj: Trajectory
) -> tuple[Trajectory, list[ClosePair], list[ClosePair]]:
    """At most ``cfg.rounds`` rounds from ``traj`` (a successful solve): check it, add the
    pairs it needs to ``state.pairs`` and solve on from its primal-dual point. Appends to
    ``state.rounds`` and ``state.totals``, each check's close pairs to ``state.seen``, and
    sets ``state.promote`` to ``off`` once a round must not promote. Returns the last
    trajectory, the close pairs still unmodelled and those deeper than ``cfg.unfreed_m`` at
    its check.

    A round whose solve ends infeasible (:data:`INFEASIBLE`) with pairs promoted to (11) is
    solved again without the promotions (their pairs keep the penalty (12) they joined
    with), and no later round promotes: (11) on a pair that keeps coming back can leave no
    feasible point near the previous optimum (S1: an elbow held out of the shelf while the
    hand holds the basket). Another failure is not retried from the same point: a solve
    that ran out of iterations would likely run out again; :func:`search` restarts from
    the guess instead.
    """
    optimizer, model, cfg, pairs = state.optimizer, state.model, state.cfg, state.pairs
    after = 0
    while True:
        scene = _checked(state.scene, traj, cfg)
        close = close_pairs(model, scene.schedule, cfg.audit_margin_m, cfg.audit_substeps)
        state.seen.extend(close)
        deepest = min(close, key=lambda c: c.distance, default=None)
        check = Check(close, scene)
        new = round_pairs(check, pairs, dataclasses.replace(cfg, found_hard=state.promote))
        if not new or after == cfg.rounds:
            state.rounds.append(_round(close, deepest, []))
            unfreed = [c for c in close if c.distance < -cfg.unfreed_m]
            return traj, unmodelled(check, pairs), unfreed
        after += 1
        log.info(
            f"round {after}: {len(close)} close pairs (deepest {_mm(deepest)}), "
            f"{len(new)} pairs added; solving on"
        )
        tic = time.perf_counter()
        # From an optimum, the exact Hessian converges in a few iterations where the
        # Gauss-Newton one, cycling near the penalties' optimum, used all 150 of its own.
        label = f"round {after}"
        solved = optimizer.solve(pairs=pairs + new, warm_start=traj, hessian="exact", label=label)
        iterations, promoted = solved.iterations, [p for p in new if p.kind == PROMOTED]
        demoted = len(promoted) if solved.status in INFEASIBLE else 0
        if demoted:
            log.info(
                f"round {after} ended {solved.status} with {demoted} pairs "
                "promoted to (11); solving it again without them, and promoting none from here"
            )
            state.totals.add(solved)
            state.promote = "off"
            new = [p for p in new if p.kind != PROMOTED]
            solved = optimizer.solve(
                pairs=pairs + new, warm_start=traj, hessian="exact", label=label
            )
            iterations += solved.iterations
        pairs.extend(new)
        seconds = time.perf_counter() - tic
        state.rounds.append(_round(close, deepest, new, solved, seconds, iterations, demoted))
        state.totals.add(solved)
        traj = solved
        if not traj.success:
            return traj, [], []


def solution_scene(
    optimizer: TrajectoryOptimizer, traj: Trajectory, cfg: CollisionCfg
) -> SolutionScene:
    """The scene a check replays ``traj`` in: the problem's objects along it, its
    obstacles, the robot's contact frames, each node's seats and the solution's contact
    schedule."""
    inputs = optimizer.inputs
    seats = tuple(tuple(m.seat for m in mode.objects) for mode in optimizer.modes)
    obstacles = {o.name: o for o in inputs.obstacles}
    scene = SolutionScene(inputs.objects, traj.object_q, obstacles, contact_frames(), seats=seats)
    return _checked(scene, traj, cfg)


def _checked(scene: SolutionScene, traj: Trajectory, cfg: CollisionCfg) -> SolutionScene:
    """``scene`` along ``traj``: its objects' poses and its contact schedule."""
    arrays = trajectory_arrays(traj, scene.names)
    return dataclasses.replace(
        scene, object_q=traj.object_q, schedule=arrays, spacing_m=cfg.found_spacing_m
    )


def _mm(pair: ClosePair | None) -> str:
    return "none" if pair is None else f"{pair.distance * 1000:.1f} mm, {pair.label}"


def _round(
    close: list[ClosePair],
    deepest: ClosePair | None,
    new: list[CollisionPair],
    traj: Trajectory | None = None,
    seconds: float = 0.0,
    iterations: int = 0,
    demoted: int = 0,
) -> Round:
    """The record of one check (and of the solve it led to, if ``traj``: ``iterations``
    and ``seconds`` of its one or two attempts)."""
    solved = (
        {}
        if traj is None
        else {
            "iterations": iterations,
            "solve_time_s": seconds,
            "status": traj.status,
            "demoted": demoted,
        }
    )
    return Round(
        len(close),
        0.0 if deepest is None else deepest.distance,
        len(new),
        deepest_pair="" if deepest is None else deepest.label,
        **solved,
    )


class _Totals:
    """A solve's counts summed over its IPOPT calls (the first phase, the rounds)."""

    def __init__(self, first: Trajectory) -> None:
        self.iterations, self.exact_iterations = first.iterations, first.exact_iterations
        self.solve_time_s, self.function_time_s = first.solve_time_s, first.function_time_s

    def add(self, traj: Trajectory) -> None:
        self.iterations += traj.iterations
        self.exact_iterations += traj.exact_iterations
        self.solve_time_s += traj.solve_time_s
        self.function_time_s += traj.function_time_s

    def of(self, traj: Trajectory) -> Trajectory:
        return dataclasses.replace(
            traj,
            iterations=self.iterations,
            exact_iterations=self.exact_iterations,
            solve_time_s=self.solve_time_s,
            function_time_s=self.function_time_s,
        )
