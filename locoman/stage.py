"""Helpers shared by the thin entry points in ``stages/``."""

from __future__ import annotations

import dataclasses
import inspect
import json
import logging
import os
import re
import shutil
import sys
from collections.abc import Callable
from pathlib import Path

from threadpoolctl import threadpool_limits

from locoman.artifacts.folder import locked, staging_folder, swap_in
from locoman.errors import ConfigError, LocomanError

DATA_DIR = Path("data")

# A scenario's name is a folder under data/: one path component, no way out of it.
_SCENARIO_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_-]{0,63}")
SCENARIO_NAME_RULE = (
    "a scenario name is a folder of data/: 1 to 64 letters, digits, '_' or '-', "
    "starting with a letter or digit"
)


def valid_scenario_name(name: str) -> bool:
    """Whether ``name`` may name a scenario (:data:`SCENARIO_NAME_RULE`)."""
    return _SCENARIO_NAME.fullmatch(name) is not None


def stage_path(scenario: str, stage: str) -> Path:
    """``data/<scenario>/<stage>/``, a stage's output folder (not created).

    Raises:
        ConfigError: If ``scenario`` is not a valid name (``../x`` would write outside
            data/).
    """
    if not valid_scenario_name(scenario):
        raise ConfigError(f"scenario {scenario!r}: {SCENARIO_NAME_RULE}")
    return DATA_DIR / scenario / stage


@dataclasses.dataclass
class StageOutputs:
    """Where one run of a stage writes: for each output folder it asks for, a staging folder
    of this run's own, swapped in whole when the stage succeeds
    (:mod:`locoman.artifacts.folder`).

    Attributes:
        staged: Output folder -> its staging folder, in the order they were asked for.
    """

    staged: dict[Path, Path] = dataclasses.field(default_factory=dict)

    def folder(self, scenario: str, stage: str) -> Path:
        """The folder to write ``data/<scenario>/<stage>/``'s new content into.

        Raises:
            ConfigError: If ``scenario`` is not a valid name; nothing is created then.
        """
        final = stage_path(scenario, stage)
        if final not in self.staged:
            self.staged[final] = staging_folder(final)
        return self.staged[final]

    def commit(self) -> None:
        """Swap every staging folder in."""
        for final, staging in self.staged.items():
            swap_in(staging, final)

    def discard(self) -> None:
        """Drop every staging folder; the outputs stay as they were."""
        for staging in self.staged.values():
            shutil.rmtree(staging, ignore_errors=True)

    def final(self, path: Path) -> Path:
        """``path`` where it will be once committed: a staging folder is named by its
        output folder."""
        return next((f for f, s in self.staged.items() if s == path), path)


def _files(root: Path) -> set[Path]:
    """Files under ``root``, relative to it, but for dotfiles (DVC's .gitignore)."""
    return {
        p.relative_to(root)
        for p in root.rglob("*")
        if p.is_file() and not any(part.startswith(".") for part in p.relative_to(root).parts)
    }


def verdict(metrics: dict) -> str:
    """Whether a stage passed its checks, from its metrics: every ``success`` flag (at any
    depth, with its ``failed_checks`` or ``status``) and the keyframes' contact checks. A
    stage without such flags passed: its checks raise when they fail."""
    checks, failures = 0, []

    def visit(node: object, path: str) -> None:
        nonlocal checks
        if not isinstance(node, dict):
            return
        if isinstance(node.get("success"), bool):
            checks += 1
            if not node["success"]:
                why = node.get("failed_checks") or node.get("status")
                why = ", ".join(map(str, why)) if isinstance(why, list) else why
                failures.append(f"{path or 'success'}{f' ({why})' if why else ''}")
        for key, child in node.items():
            visit(child, f"{path}.{key}" if path else key)

    visit(metrics, "")
    for key in ("unreachable_contacts", "self_collision_pairs"):
        if isinstance(metrics.get(key), int):
            checks += 1
            if metrics[key]:
                failures.append(f"{key} = {metrics[key]}")
    if not checks:  # the stage's checks stop it with a message when they fail
        return "checks passed"
    return "checks FAILED: " + "; ".join(failures) if failures else "checks passed"


def summary_line(stage: str, argv: list[str], out: Path) -> str:
    """The one line a stage ends with: what it wrote and whether it passed its checks."""
    files = _files(out)
    size = sum((out / f).stat().st_size for f in files)
    metrics = out / "metrics.json"
    result = verdict(json.loads(metrics.read_text())) if metrics.is_file() else "no metrics"
    name = " ".join([stage, *argv])
    return f"[{name}] wrote {out}/ ({len(files)} files, {size / 1e6:.1f} MB); {result}"


def configure_logging(name: str, level: int = logging.INFO) -> None:
    """The library's log lines (``locoman.*`` at ``level``) on standard output, each
    prefixed ``[name]`` as the stage's summary line is: a stage's progress beside other
    stages' in one log (``make run``'s two arms)."""
    handler = logging.StreamHandler(sys.stdout)
    handler.setFormatter(logging.Formatter(f"[{name}] %(message)s"))
    logger = logging.getLogger("locoman")
    logger.handlers[:] = [handler]
    logger.setLevel(level)
    logger.propagate = False


def run_stage(main: Callable[..., Path], argv: list[str]) -> None:
    """Run a stage: ``main(outputs, *argv)`` writes into the folders
    :meth:`StageOutputs.folder` gives and returns its output folder. The outputs appear
    whole or not at all: each output folder is swapped in whole only when ``main`` returns;
    a failure leaves the previous outputs as they were, and two runs at once leave one's
    outputs whole. Bad arguments or a :class:`LocomanError` end it with a message and exit
    2; success ends with :func:`summary_line`.

    A stage's entry point, it sets the process's BLAS / OpenMP threads to one: a threaded
    reduction sums in an order that depends on the machine's core count, so outputs would
    differ between machines. The variables reach the libraries loaded later (CasADi's
    OpenBLAS, with MUMPS), the limit those loaded.
    """
    outputs = StageOutputs()
    stage = Path(inspect.getsourcefile(main) or "stage").stem
    configure_logging(" ".join([stage, *argv]))
    try:
        inspect.signature(main).bind(outputs, *argv)
    except TypeError as exc:
        doc = (sys.modules[main.__module__].__doc__ or "").strip()
        print(f"{doc}\n\nbad arguments {argv}: {exc}", file=sys.stderr)
        sys.exit(2)
    os.environ["OPENBLAS_NUM_THREADS"] = os.environ["OMP_NUM_THREADS"] = "1"
    done = False
    try:
        with threadpool_limits(limits=1):
            out = Path(main(outputs, *argv))
        done = True
    except LocomanError as exc:
        print(f"locoman: {type(exc).__name__}: {exc}", file=sys.stderr)
        print("locoman: the previous outputs are left as they were", file=sys.stderr)
    finally:
        if not done:  # a message above, or an exception on its way up with its traceback
            outputs.discard()
    if not done:
        sys.exit(2)
    out = outputs.final(out)
    outputs.commit()
    # Under the folder's lock: a run of the same stage finishing now swaps the folder away.
    with locked(out):
        line = summary_line(stage, argv, out)
    print(line, flush=True)
