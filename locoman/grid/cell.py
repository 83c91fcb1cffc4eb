"""One cell of a figure's grid: rebuild the scene, solve, evaluate, record.

A cell reads the pipeline's parameters (``params.yaml``) and its upstream artifacts under
``data/<scenario>/`` (``contacts/subtasks``, ``retarget/keyframes``, ``scene``), and changes
only what the cell names: the box mass [kg] and the initial yaw [rad] (the scene is rebuilt
with them) and the run's switches (:mod:`locoman.grid.runs`). The upstream stages read the
objects' geometry and poses and the plan, which neither knob changes; a cell checks that and
refuses otherwise, so reused keyframes always belong to the cell's scene.

Layout, per cell, under ``data/<scenario>/grid/<figure>/<cell>/``::

    cell.json              the record: status, reason, keys, the figures' numbers
    log.txt                what the solve printed (IPOPT's iterations)
    scene/ solve/ evaluate/    the stages' usual outputs (no filmstrip, no MP4)

The record is written last, and the cell's folder is swapped in whole: a killed cell leaves
its previous result or none. Two keys decide what a rerun does, as DVC's stages would:
``solve_key`` hashes what the solve reads (the cell, the parameters but the evaluation's, the
upstream files, the code the solve imports) and ``key`` adds the evaluation's parameters and
code. A cell whose ``key`` matches its record is skipped; one whose ``solve_key`` alone
matches is evaluated again on its trajectory (seconds, where a solve takes minutes).
"""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import json
import math
import os
import shutil
import sys
import time
import traceback
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from locoman.artifacts import write_json_atomic
from locoman.artifacts.folder import staging_folder, swap_in
from locoman.config.schema import RootCfg, ScenarioCfg
from locoman.config.to import EvaluateCfg, SolveCfg
from locoman.errors import ArtifactError, ConfigError
from locoman.grid.provenance import results_settings
from locoman.grid.runs import find_run
from locoman.grid.sources import (
    CELL_FILE,
    EVALUATE_MODULES,
    PACKAGE,
    SOLVE_MODULES,
    imported_sources,
)
from locoman.scene.builder import build_scene
from locoman.scene.io import write_scene
from locoman.sim.pipeline import evaluate_scenario
from locoman.stage import valid_scenario_name
from locoman.to.io import TRAJECTORY_FILE
from locoman.to.pipeline import solve_scenario

RECORD_FILE = "cell.json"
LOG_FILE = "log.txt"
# The upstream outputs a cell reads, under data/<scenario>/.
UPSTREAM = ("scene/objects.json", "scene/plan.json", "contacts/subtasks", "retarget/keyframes")
# What the record keeps from a solve when only the evaluation runs again.
SOLVE_NUMBERS = (
    "status",
    "reason",
    "solver_status",
    "iterations",
    "solve_time_s",
    "collision_rounds",
    "pairs_found",
    "restarts",
)
# Statuses of a record: the TO converged, it stopped without converging (iteration or time
# limit, infeasibility: IPOPT's status says which), or the cell could not run (the reason).
STATUSES = ("converged", "not_converged", "error")


@dataclasses.dataclass(frozen=True)
class CellCfg:
    """One cell of a grid (the Hydra app's ``cell`` section).

    Attributes:
        scenario: A humanoid scenario with upstream artifacts under ``data/<scenario>/``.
        figure: ``fig5``, ``fig6`` or ``vb`` (:data:`locoman.grid.runs.FIGURE_RUNS`).
        run: One of the figure's runs.
        box_mass: Mass of the object named ``box`` [kg].
        initial_yaw: The robot's initial yaw [rad].
    """

    scenario: str = "tiny"
    figure: str = "fig6"
    run: str = "all"
    box_mass: float = 5.0
    initial_yaw: float = 0.0

    def check(self) -> list[tuple[str, str]]:
        errors = []
        if not valid_scenario_name(self.scenario):
            errors.append(("scenario", f"{self.scenario!r} is not a scenario name"))
        try:
            find_run(self.figure, self.run)
        except ConfigError as exc:
            errors.append(("run", str(exc)))
        if not (math.isfinite(self.box_mass) and self.box_mass > 0.0):
            errors.append(("box_mass", f"must be finite and > 0 kg, got {self.box_mass}"))
        if not (math.isfinite(self.initial_yaw) and abs(self.initial_yaw) <= math.pi):
            errors.append(("initial_yaw", f"must be in [-pi, pi] rad, got {self.initial_yaw}"))
        return errors

    @property
    def name(self) -> str:
        """The cell's folder: ``<run>_m<mass>_yaw<yaw>``, e.g. ``all_m5_yaw+0.6``."""
        return f"{self.run}_m{self.box_mass:g}_yaw{self.initial_yaw:+g}"


def cell_dir(data_dir: Path, cell: CellCfg) -> Path:
    """``<data_dir>/<scenario>/grid/<figure>/<cell>/``."""
    return Path(data_dir) / cell.scenario / "grid" / cell.figure / cell.name


def read_record(folder: Path) -> dict[str, Any] | None:
    """A cell's record, or None when it has none (never ran, or was killed)."""
    try:
        return json.loads((Path(folder) / RECORD_FILE).read_text())
    except (OSError, ValueError):
        return None


def cell_scenario(scenario: ScenarioCfg, cell: CellCfg) -> ScenarioCfg:
    """The scenario with the cell's knobs: the mass of the object named ``box`` and the
    robot's initial yaw (``scenario.box_mass`` and ``scenario.initial_yaw`` in conf/)."""
    objects = dict(scenario.objects)
    if "box" in objects:
        objects["box"] = dataclasses.replace(objects["box"], mass=cell.box_mass)
    start = dataclasses.replace(scenario.start, yaw=cell.initial_yaw)
    return dataclasses.replace(scenario, objects=objects, start=start)


def _files(root: Path, entries: tuple[str, ...]) -> list[Path]:
    out = []
    for entry in entries:
        path = root / entry
        out += sorted(p for p in path.rglob("*") if p.is_file()) if path.is_dir() else [path]
    return out


def with_time_limit(solve: SolveCfg, limit_s: float) -> SolveCfg:
    """``solve`` with IPOPT's wall time capped at ``limit_s`` [s] (``figures.time_limit_s``;
    a tighter ``solve.solver.max_wall_time_s`` stays). It goes into the cell's key: where
    it stops a solve, it decides the cell's outcome."""
    configured = solve.solver.max_wall_time_s
    limit = limit_s if configured is None else min(configured, limit_s)
    return dataclasses.replace(
        solve, solver=dataclasses.replace(solve.solver, max_wall_time_s=limit)
    )


def _solve_sources() -> list[Path]:
    return sorted({*imported_sources(SOLVE_MODULES), PACKAGE / CELL_FILE})


def solve_key(cell: CellCfg, scenario: ScenarioCfg, solve: SolveCfg, upstream: Path) -> str:
    """SHA-256 of everything the cell's solve reads: the cell, its parameters (not where
    the compiled TO is cached nor how much it logs), the upstream files, the code the solve
    imports and this module.

    Raises:
        ArtifactError: An upstream output is missing (run the pipeline up to ``retarget``).
    """
    missing = [e for e in UPSTREAM if not (upstream / e).exists()]
    if missing:
        raise ArtifactError(
            f"the grid's cells reuse {upstream}/{{{', '.join(missing)}}}, which do not exist: "
            f"run `dvc repro retarget@{cell.scenario}` first"
        )
    settings = {
        "cell": dataclasses.asdict(cell),
        "scenario": dataclasses.asdict(scenario),
        "solve": results_settings(dataclasses.asdict(solve)),
    }
    digest = _digest(settings)
    for path in _files(upstream, UPSTREAM):
        digest.update(str(path.relative_to(upstream)).encode())
        digest.update(path.read_bytes())
    _update_with_code(digest, _solve_sources())
    return digest.hexdigest()


def cell_inputs(
    cfg: RootCfg, cell: CellCfg, data_dir: Path
) -> tuple[Path, ScenarioCfg, SolveCfg, str]:
    """What ``cell``'s solve reads: its upstream folder, its scenario and solve settings
    (the run's, time-limited), and their :func:`solve_key`."""
    upstream = Path(data_dir) / cell.scenario
    scenario = cell_scenario(cfg.scenarios[cell.scenario], cell)
    run = find_run(cell.figure, cell.run)
    solve = with_time_limit(run.apply(cfg.solve, cell.scenario), cfg.figures.time_limit_s)
    return upstream, scenario, solve, solve_key(cell, scenario, solve, upstream)


def cell_key(solved: str, evaluate: EvaluateCfg) -> str:
    """SHA-256 of everything the cell reads: its ``solved`` key (:func:`solve_key`), the
    evaluation's parameters and the code the evaluation imports beyond the solve's."""
    digest = _digest({"solve_key": solved, "evaluate": dataclasses.asdict(evaluate)})
    solve_code = set(_solve_sources())
    _update_with_code(
        digest, [p for p in imported_sources(EVALUATE_MODULES) if p not in solve_code]
    )
    return digest.hexdigest()


def _digest(settings: dict[str, Any]) -> Any:
    return hashlib.sha256(json.dumps(settings, sort_keys=True, default=str).encode())


def _update_with_code(digest: Any, sources: list[Path]) -> None:
    for path in sources:
        digest.update(str(path.relative_to(PACKAGE)).encode())
        digest.update(path.read_bytes())


def check_same_world(cell_scene: Path, upstream_scene: Path) -> None:
    """The cell's objects and plan are the upstream's but for masses.

    Raises:
        ConfigError: They differ: the upstream keyframes would belong to another scene.
    """
    plans = [(folder / "plan.json").read_bytes() for folder in (cell_scene, upstream_scene)]
    ours = json.loads((cell_scene / "objects.json").read_text())["objects"]
    theirs = json.loads((upstream_scene / "objects.json").read_text())["objects"]

    def strip(objects: dict[str, Any]) -> dict[str, Any]:
        return {n: {k: v for k, v in s.items() if k != "mass_kg"} for n, s in objects.items()}

    if plans[0] != plans[1] or strip(ours) != strip(theirs):
        raise ConfigError(
            f"the cell's scene differs from {upstream_scene} in more than the box mass and the "
            "initial yaw, so its contacts and keyframes do not apply: rerun the pipeline with "
            "the new parameters (`dvc repro retarget`) before the grid"
        )


@contextlib.contextmanager
def output_to(path: Path, append: bool = False) -> Iterator[None]:
    """Send what this process prints to ``path``: Python's ``sys.stdout`` / ``sys.stderr``
    (whatever they are, a test's capture included) and file descriptors 1 and 2 (IPOPT's C
    output); after what it holds where ``append``."""
    sys.stdout.flush()
    sys.stderr.flush()
    saved = os.dup(1), os.dup(2)
    with open(path, "a" if append else "w", buffering=1) as log:
        os.dup2(log.fileno(), 1)
        os.dup2(log.fileno(), 2)
        try:
            with contextlib.redirect_stdout(log), contextlib.redirect_stderr(log):
                yield
        finally:
            log.flush()
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            os.close(saved[0])
            os.close(saved[1])


def _solve(
    name: str, scenario: ScenarioCfg, solve: SolveCfg, upstream: Path, out: Path
) -> dict[str, Any]:
    """The cell's scene and solve into ``out``; the record's numbers of the solve."""
    write_scene(out / "scene", build_scene(name, scenario, (64, 48)))
    check_same_world(out / "scene", upstream / "scene")
    traj = solve_scenario(
        out / "scene", upstream / "contacts", upstream / "retarget", out / "solve", solve
    )
    solved = json.loads((out / "solve" / "metrics.json").read_text())
    return {
        "status": "converged" if traj.success else "not_converged",
        "reason": "" if traj.success else traj.status,
        "solver_status": traj.status,
        "iterations": traj.iterations,
        "solve_time_s": traj.solve_time_s,
        # Rounds of found pairs that added any, and how many they added.
        "collision_rounds": sum(r["pairs_added"] > 0 for r in solved["collision_rounds"]),
        "pairs_found": solved["pairs_found"],
        # Solves started again from the guess with the pairs found (CollisionCfg.restarts).
        "restarts": solved["restarts"],
    }


def _evaluate(evaluate: EvaluateCfg, out: Path) -> dict[str, Any]:
    """The evaluation of the solve in ``out``; the record's numbers of it."""
    metrics = evaluate_scenario(out / "scene", out / "solve", out / "evaluate", evaluate, False)
    return {
        "avg_penetration_m": metrics["avg_penetration_m"],
        "max_penetration_m": metrics["max_penetration_m"],
        "max_penetration_pair": metrics["max_penetration_pair"],
        "penetration_by_class": metrics["penetration_by_class"],
        "dynamics_residual_max": metrics["dynamics_residual_max"],
        "object_goal_error_m": metrics["object_goal_error_m"],
        "success": metrics["success"],
        "failed_checks": metrics["failed_checks"],
    }


def _kept(previous: dict[str, Any] | None, folder: Path) -> bool:
    """The cell's last record holds a solve's numbers, and its trajectory is there."""
    return (
        previous is not None
        and all(k in previous for k in SOLVE_NUMBERS[:5])
        and (folder / "solve" / TRAJECTORY_FILE).is_file()
    )


def _solved(previous: dict[str, Any] | None, solved: str, folder: Path) -> bool:
    """The cell's last record holds a solve of today's ``solved`` key, and its trajectory."""
    return _kept(previous, folder) and previous.get("solve_key") == solved


def run_cell(
    cfg: RootCfg, cell: CellCfg, data_dir: Path = Path("data"), rescore: bool = False
) -> dict[str, Any]:
    """Run one cell unless its record is up to date (and not an error); return its record.
    A cell whose solve is up to date is only evaluated again (``"reevaluated": true``); its
    ``wall_time_s`` stays the solve's, ``evaluate_wall_time_s`` is the new evaluation's [s]. With
    ``rescore``, a cell with a kept trajectory is evaluated again even where the solve's
    code or parameters changed since (``"rescored": true``; it keeps its old ``solve_key``,
    so a plain run later solves it again).

    Whatever goes wrong inside (a solver failure, a time limit, an infeasible input, a bug)
    is recorded as the cell's status and reason, and the function returns: a grid goes on.
    Only a cell that cannot be named (bad configuration) or keyed (missing upstream) raises.

    Raises:
        ConfigError: The cell's settings are invalid or the scenario is unknown.
        ArtifactError: The upstream artifacts are missing; with ``rescore``, the cell has no
            kept solve.
    """
    errors = cell.check()
    if cell.scenario not in cfg.scenarios:
        errors.append(("scenario", f"unknown; known: {sorted(cfg.scenarios)}"))
    if errors:
        raise ConfigError("; ".join(f"cell.{k}: {msg}" for k, msg in errors))
    upstream, scenario, solve, solved = cell_inputs(cfg, cell, data_dir)
    key = cell_key(solved, cfg.evaluate)
    final = cell_dir(data_dir, cell)
    previous = read_record(final)
    rescored = rescore and _kept(previous, final) and not _solved(previous, solved, final)
    if rescored:
        solved = previous["solve_key"]
        key = cell_key(solved, cfg.evaluate)
    # An error (an exception, not a failed solve) may be the machine's (a full disk, a
    # cache it could not write): the next run tries the cell again.
    if previous is not None and previous.get("key") == key and previous.get("status") != "error":
        return {**previous, "skipped": True}
    if rescore and not _kept(previous, final):
        raise ArtifactError(f"{final} has no kept solve to score again: run the grid first")
    staging = staging_folder(final)
    reuse = _solved(previous, solved, final)
    if reuse:  # the scene, the solve and its log as they are; a new evaluation
        shutil.copytree(
            final,
            staging,
            ignore=shutil.ignore_patterns(RECORD_FILE, "evaluate"),
            dirs_exist_ok=True,
        )
    tic = time.perf_counter()
    with output_to(staging / LOG_FILE, append=reuse):
        try:
            if reuse:
                numbers = {k: previous[k] for k in SOLVE_NUMBERS if k in previous}
            else:
                numbers = _solve(cell.scenario, scenario, solve, upstream, staging)
            numbers |= _evaluate(cfg.evaluate, staging)
        except Exception as exc:  # a grid records every failure and goes on
            traceback.print_exc()
            numbers = {"status": "error", "reason": f"{type(exc).__name__}: {exc}"}
    seconds = time.perf_counter() - tic
    # JSON has no NaN: a non-finite number (a diverged solve) is recorded as null.
    nan = [k for k, v in numbers.items() if isinstance(v, float) and not math.isfinite(v)]
    finite = {**numbers, **dict.fromkeys(nan)}
    timing = (
        {"wall_time_s": previous["wall_time_s"], "evaluate_wall_time_s": seconds}
        if reuse
        else {"wall_time_s": seconds}
    )
    record = {
        **dataclasses.asdict(cell),
        "label": find_run(cell.figure, cell.run).label,
        **finite,
        **timing,
        "reevaluated": reuse,
        "rescored": rescored,
        "solve_key": solved,
        "key": key,
    }
    write_json_atomic(staging / RECORD_FILE, record)
    # The folder swapped in whole, as a stage's: a kill leaves the old cell, never a new
    # record beside old files.
    swap_in(staging, final)
    return {**record, "skipped": False}
