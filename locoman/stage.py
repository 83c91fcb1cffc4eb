"""Helpers shared by the thin entry points in ``stages/``."""

from __future__ import annotations

import contextlib
import fcntl
import inspect
import json
import os
import re
import shutil
import sys
from collections.abc import Callable, Iterator
from pathlib import Path

from threadpoolctl import threadpool_limits

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


# While :func:`run_stage` runs a stage: final output folder -> the staging folder the stage
# writes into instead (None outside run_stage: stage_dir is then the folder itself).
_staging: dict[Path, Path] | None = None


def stage_dir(scenario: str, stage: str) -> Path:
    """``data/<scenario>/<stage>/``, created if needed; inside :func:`run_stage`, its
    staging folder, which becomes the output folder only when the stage succeeds.

    Raises:
        ConfigError: If ``scenario`` is not a valid name (``../x`` would write outside
            data/); nothing is created then.
    """
    if not valid_scenario_name(scenario):
        raise ConfigError(f"scenario {scenario!r}: {SCENARIO_NAME_RULE}")
    path = DATA_DIR / scenario / stage
    if _staging is None:
        path.mkdir(parents=True, exist_ok=True)
        return path
    if path not in _staging:
        _remove_stale_staging(path.parent, stage)
        # A folder of this run's own: two runs of a stage at once cannot mix their files.
        staging = path.parent / f".{stage}.staging.{os.getpid()}"
        shutil.rmtree(staging, ignore_errors=True)
        staging.mkdir(parents=True)
        _staging[path] = staging
    return _staging[path]


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _remove_stale_staging(parent: Path, stage: str) -> None:
    """Remove the staging folders of ``stage`` whose run is gone (a killed run's)."""
    for folder in parent.glob(f".{stage}.staging*"):
        pid = folder.name.rsplit(".", 1)[-1]
        if not pid.isdigit() or not _alive(int(pid)):
            shutil.rmtree(folder, ignore_errors=True)


@contextlib.contextmanager
def _locked(final: Path) -> Iterator[None]:
    """Hold ``final``'s lock (a file beside it): a second run of the stage committing at
    the same time waits for this one to finish moving its files in."""
    final.parent.mkdir(parents=True, exist_ok=True)
    with open(final.parent / f".{final.name}.lock", "w") as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)


def _files(root: Path) -> set[Path]:
    """Files under ``root``, relative to it, but for dotfiles (DVC's .gitignore)."""
    return {
        p.relative_to(root)
        for p in root.rglob("*")
        if p.is_file() and not any(part.startswith(".") for part in p.relative_to(root).parts)
    }


def commit_staged(final: Path, staging: Path) -> None:
    """Make ``final`` hold exactly the files of ``staging``: move each in (a rename per
    file), remove the ones this run did not write, drop the staging folder."""
    final.mkdir(parents=True, exist_ok=True)
    new = _files(staging)
    for rel in sorted(new):
        (final / rel).parent.mkdir(parents=True, exist_ok=True)
        os.replace(staging / rel, final / rel)
    for rel in _files(final) - new:
        (final / rel).unlink()
    for folder in sorted((p for p in final.rglob("*") if p.is_dir()), reverse=True):
        if not any(folder.iterdir()):
            folder.rmdir()
    shutil.rmtree(staging, ignore_errors=True)


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


def run_stage(main: Callable[..., Path], argv: list[str]) -> None:
    """Run a stage: ``main`` writes into the folders :func:`stage_dir` gives and returns its
    output folder. The outputs appear whole or not at all: written into a staging folder,
    moved into place only when ``main`` returns; a failure leaves the previous outputs as
    they were. Each run stages into a folder of its own and commits under the output
    folder's lock, so two runs at once leave one's outputs whole. Bad arguments or a
    :class:`LocomanError` end it with a message and exit 2; success ends with
    :func:`summary_line`."""
    global _staging
    try:
        inspect.signature(main).bind(*argv)
    except TypeError as exc:
        doc = (sys.modules[main.__module__].__doc__ or "").strip()
        print(f"{doc}\n\nbad arguments {argv}: {exc}", file=sys.stderr)
        sys.exit(2)
    _staging = {}
    done = False
    # One BLAS / OpenMP thread: a threaded reduction sums in an order that depends on the
    # machine's core count, so outputs would differ between machines. The variable reaches
    # the libraries loaded later (CasADi's OpenBLAS, with MUMPS), the limit those loaded.
    os.environ["OPENBLAS_NUM_THREADS"] = os.environ["OMP_NUM_THREADS"] = "1"
    try:
        with threadpool_limits(limits=1):
            out = Path(main(*argv))
        done = True
    except LocomanError as exc:
        print(f"locoman: {type(exc).__name__}: {exc}", file=sys.stderr)
        print("locoman: the previous outputs are left as they were", file=sys.stderr)
    finally:
        staged, _staging = _staging, None
        if not done:  # a message above, or an exception on its way up with its traceback
            for staging in staged.values():
                shutil.rmtree(staging, ignore_errors=True)
    if not done:
        sys.exit(2)
    for final, staging in staged.items():
        with _locked(final):
            commit_staged(final, staging)
        if out == staging:
            out = final
    stage = Path(inspect.getsourcefile(main) or "stage").stem
    print(summary_line(stage, argv, out), flush=True)
