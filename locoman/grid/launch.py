"""Launch a figure's grid as a Hydra multirun, built from ``params.yaml``.

Usage: ``python -m locoman.grid <scenario> <figure> [hydra overrides ...]``

The sweep comes from the ``figures`` section: Fig. 6 runs every keyframe setting at every
(box mass, initial yaw) of ``figures.grids.<scenario>``; Fig. 5 runs its four pipeline
variants at the scenario's configured mass and yaw (``scenario.box_mass``,
``scenario.initial_yaw``). ``figures.launcher`` picks the launcher; trailing arguments go to
Hydra as they are, e.g. ``hydra/launcher=submitit_slurm hydra.launcher.partition=cpu``.
Cells whose inputs have not changed are skipped, so a grid that was stopped, or that ran on
a cluster, finishes where it left off.
"""

from __future__ import annotations

import concurrent.futures
import dataclasses
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Mapping, Sequence
from pathlib import Path

from hydra.core.override_parser.overrides_parser import OverridesParser
from hydra.errors import OverrideParseException

from locoman.config import load_params
from locoman.config.schema import RootCfg
from locoman.errors import ConfigError, LocomanError
from locoman.grid.cell import CellCfg
from locoman.grid.runs import FIGURE_RUNS
from locoman.grid.slots import POLL_S, slot_environment, slots_taken
from locoman.kernels import pin_kernels


def cells(
    cfg: RootCfg, scenario: str, figure: str, runs: Sequence[str] | None = None
) -> list[CellCfg]:
    """The cells of ``figure`` for ``scenario``, in the figure's order (mass, yaw, run);
    ``runs``: only these of the figure's runs (None: all).

    Raises:
        ConfigError: An unknown figure or run, or a scenario without a grid.
    """
    if figure not in FIGURE_RUNS:
        raise ConfigError(f"unknown figure {figure!r}; known: {sorted(FIGURE_RUNS)}")
    names = [run.name for run in FIGURE_RUNS[figure]]
    unknown = sorted(set(runs or ()) - set(names))
    if unknown:
        raise ConfigError(f"figure {figure!r} has no runs {unknown}; its runs: {names}")
    if scenario not in cfg.figures.grids:
        raise ConfigError(f"figures.grids has no {scenario!r}; add its grid in conf/figures/")
    if figure == "fig5":
        masses, yaws = [cfg.scenario.box_mass], [cfg.scenario.initial_yaw]
    else:
        grid = cfg.figures.grids[scenario]
        masses, yaws = grid.box_mass, grid.initial_yaw
    return [
        CellCfg(scenario, figure, name, float(m), float(y))
        for m in masses
        for y in yaws
        for name in names
        if runs is None or name in runs
    ]


def _values(values: list) -> str:
    return ",".join(dict.fromkeys(str(v) for v in values))


def check_overrides(scenario: str, figure: str, extra: list[str]) -> None:
    """Every ``cell.<key>=...`` override names a cell field and each of its values is one a
    cell accepts, checked here: inside the multirun a bad value is a Hydra traceback per job.

    Raises:
        ConfigError: Naming the override, the key and what it must be.
    """
    try:
        overrides = OverridesParser.create().parse_overrides(list(extra))
    except OverrideParseException as exc:
        raise ConfigError(f"grid overrides {list(extra)}: {exc}") from None
    fields = {f.name: f for f in dataclasses.fields(CellCfg)}
    base = CellCfg(scenario, figure)
    for override in overrides:
        key = override.key_or_group.removeprefix("+")
        if not key.startswith("cell."):
            continue
        name = key.removeprefix("cell.")
        if name not in fields:
            raise ConfigError(
                f"grid override {key}: a cell has no such key; it has {sorted(fields)}"
            )
        values = (
            list(override.sweep_string_iterator())
            if override.is_sweep_override()
            else [override.get_value_element_as_str()]
        )
        default = fields[name].default
        for text in values:
            try:
                value = type(default)(text)
            except ValueError:
                raise ConfigError(
                    f"grid override {key}={text!r}: must be a {type(default).__name__} "
                    f"(e.g. {key}={default})"
                ) from None
            for field, message in dataclasses.replace(base, **{name: value}).check():
                if field == name:
                    raise ConfigError(f"grid override {key}={text!r}: {message}")


def multirun_command(
    cfg: RootCfg,
    scenario: str,
    figure: str,
    extra: list[str],
    runs: Sequence[str] | None = None,
) -> list[str]:
    """The Hydra multirun that runs every cell of :func:`cells`, with ``extra`` overrides
    last (they win)."""
    swept = cells(cfg, scenario, figure, runs)
    launcher = [f"hydra/launcher={cfg.figures.launcher}"]
    if cfg.figures.launcher == "joblib":
        launcher.append(f"hydra.launcher.n_jobs={cfg.figures.n_jobs}")
    return [
        sys.executable,
        "-m",
        "locoman.grid.app",
        "--multirun",
        f"cell.scenario={scenario}",
        f"cell.figure={figure}",
        # Hydra's sweep varies the last key fastest: the runs of one (mass, yaw) go together,
        # so a grid stopped half-way has whole panels of Fig. 6.
        f"cell.box_mass={_values([c.box_mass for c in swept])}",
        f"cell.initial_yaw={_values([c.initial_yaw for c in swept])}",
        f"cell.run={_values([c.run for c in swept])}",
        *launcher,
        *extra,
    ]


def launch(
    scenario: str,
    figure: str,
    extra: list[str] = (),
    params_file: str | Path = "params.yaml",
    runs: Sequence[str] | None = None,
    env: Mapping[str, str] | None = None,
) -> None:
    """Run the grid (a subprocess: Hydra owns its process's logging and working state);
    ``runs``: only these of the figure's runs; ``env``: more variables for its jobs (the
    slots of grids launched side by side, :mod:`locoman.grid.slots`).

    Raises:
        ConfigError: Bad arguments.
        LocomanError: The multirun itself failed (a cell's failure does not fail it).
    """
    cfg = load_params(params_file)
    check_overrides(scenario, figure, list(extra))
    command = multirun_command(cfg, scenario, figure, list(extra), runs)
    if Path(params_file) != Path("params.yaml"):
        command.append(f"params_file={params_file}")
    print("[grid] " + " ".join(command[1:]), flush=True)
    # The cells' processes load NumPy first thing: the kernels are pinned in their
    # environment, as a stage pins its own (locoman/kernels.py).
    jobs_env = dict(os.environ) | dict(env or {})
    pin_kernels(jobs_env)
    if subprocess.run(command, env=jobs_env).returncode != 0:
        raise LocomanError(
            f"the {figure} grid of {scenario} stopped (the Hydra multirun above failed; a "
            "cell's own failure is recorded and does not stop it)"
        )


def launch_figures(
    cfg: RootCfg,
    scenario: str,
    figures: Sequence[str],
    params_file: str | Path = "params.yaml",
    runs: Sequence[str] | None = None,
) -> dict[str, float]:
    """Run the grids of ``figures`` side by side; return each one's wall time [s], from its
    launch to its last cell. With the ``joblib`` launcher their jobs share
    ``figures.n_jobs`` slots (:mod:`locoman.grid.slots`), so the cores stay busy until the
    last cell of any figure instead of each figure's; elsewhere (a cluster) each grid's
    launcher places its own jobs.

    Raises:
        LocomanError: A grid's multirun failed (the others still run to their end).
    """

    def timed(figure: str, env: Mapping[str, str] | None) -> float:
        tic = time.perf_counter()
        launch(scenario, figure, params_file=params_file, runs=runs, env=env)
        return time.perf_counter() - tic

    with tempfile.TemporaryDirectory(prefix="locoman-slots-") as folder:
        n = cfg.figures.n_jobs
        shared = cfg.figures.launcher == "joblib" and len(figures) > 1
        env = slot_environment(Path(folder), n) if shared else None
        with concurrent.futures.ThreadPoolExecutor(max(len(figures), 1)) as pool:
            futures = {}
            for figure in figures:
                futures[figure] = pool.submit(timed, figure, env)
                if shared:
                    cells_now = min(n, len(cells(cfg, scenario, figure, runs)))
                    _until_started(futures[figure], Path(folder), n, cells_now)
        return {f: future.result() for f, future in futures.items()}


def _until_started(
    launched: concurrent.futures.Future, folder: Path, n: int, k: int, timeout_s: float = 30.0
) -> None:
    """Wait until ``k`` of the ``n`` slots in ``folder`` are taken, the launch has ended,
    or ``timeout_s`` [s] has passed: a figure's first cells take their slots before the next
    figure's cells ask. Fig. 5 comes first and holds the longest cell, its naive run
    (`tiny`'s: 13 min of `make run`), which otherwise waited about 2 min behind the other
    figures' first cells."""
    end = time.monotonic() + timeout_s
    while not launched.done() and slots_taken(folder, n) < k and time.monotonic() < end:
        time.sleep(POLL_S)


def main(argv: list[str]) -> int:
    if len(argv) < 2 or argv[0].startswith("-"):
        print(__doc__, file=sys.stderr)
        return 2
    try:
        launch(argv[0], argv[1], argv[2:])
    except LocomanError as exc:
        print(f"locoman: {type(exc).__name__}: {exc}", file=sys.stderr)
        return 2
    return 0
