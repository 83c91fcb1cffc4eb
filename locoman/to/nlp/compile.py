"""The TO's derivative functions as generated C, compiled once per robot and cached.

A library is keyed by the hash of its C source, the compiler and the flags. The TO's terms
take every number as an input and are called over index lists that are data
(:mod:`locoman.to.nlp.ipopt`), so their source, and the key, change only with the robot model
and the kinds of terms: one set per robot. Each entry is ``to_<key>.so`` with
``to_<key>.json`` beside it (the library's size and SHA-256), written before the library
is renamed into place: a library that does not match its record (a truncated copy, which
would kill the process with SIGBUS on load) is rebuilt, never loaded.

Making the functions (differentiating them) and generating their C take most of a build
even when the library is cached: 80 % of S1's 164 s. So :func:`load_or_compile` also keeps
an index, ``index_<key>.json``, keyed by a :class:`Recipe`'s fingerprint (what the
functions are made from, cheap to compute): it names the library and holds what the caller
needs besides the functions (their sparsity patterns). A known fingerprint loads the
library directly; an unknown one makes the functions, finds or compiles their library as
above, and is indexed.

Several processes may share a cache (the cells of a grid, the end-to-end test and the
user's own runs, through ``LOCOMAN_CACHE_DIR``): every file is written under a name of its
own and renamed into place, so they never see each other's partial files.
"""

from __future__ import annotations

import dataclasses
import hashlib
import inspect
import json
import logging
import os
import shutil
import subprocess
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor, as_completed
from pathlib import Path

import casadi as ca

from locoman.errors import SolverBuildError

log = logging.getLogger(__name__)

CACHE_ENV = "LOCOMAN_CACHE_DIR"


def compiler(flags: Sequence[str]) -> str:
    """The C compiler: ``$CC`` if set; else, for a build without optimisation (``-O0`` or no
    ``-O``), Debian's ``tcc`` where it is installed (about 10x faster to compile than gcc,
    slower code); else ``gcc``."""
    if os.environ.get("CC"):
        return os.environ["CC"]
    optimised = any(f.startswith("-O") and f not in ("-O0", "-O") for f in flags)
    if not optimised and shutil.which("tcc"):
        return "tcc"
    return "gcc"


def cache_dir(configured: str | Path) -> Path:
    """Where compiled libraries live: ``$LOCOMAN_CACHE_DIR`` if set, else ``configured``
    (``solve.cache_dir``)."""
    return Path(os.environ.get(CACHE_ENV) or configured)


@dataclasses.dataclass(frozen=True)
class Unit:
    """One translation unit: functions compiled into one shared library."""

    functions: tuple[ca.Function, ...]
    source: str
    key: str

    @property
    def name(self) -> str:
        return self.functions[0].name().rsplit("_", 1)[0]


def _unit(functions: Sequence[ca.Function], compiler: str, flags: Sequence[str]) -> Unit:
    gen = ca.CodeGenerator("locoman_to.c", {"with_header": False})
    for fn in functions:
        gen.add(fn)
    source = gen.dump()
    digest = hashlib.sha256("\0".join([source, compiler, *flags]).encode()).hexdigest()[:16]
    return Unit(tuple(functions), source, digest)


def _record(library: Path, key: str) -> dict:
    # The key names the unit the library was built for: a library moved under another
    # unit's name, with its record, still matches its bytes but not the name.
    data = library.read_bytes()
    return {"key": key, "bytes": len(data), "sha256": hashlib.sha256(data).hexdigest()}


def _key(library: Path) -> str:
    return library.stem.removeprefix("to_")


def _valid(library: Path) -> bool:
    """The library exists, is the one built for its name, and matches the record written
    when it was built."""
    record = library.with_suffix(".json")
    try:
        return json.loads(record.read_text()) == _record(library, _key(library))
    except (OSError, ValueError):
        return False


def _make_cache(directory: Path) -> None:
    try:
        directory.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise SolverBuildError(
            f"the compile cache {directory} cannot be created ({exc.strerror}); set "
            f"{CACHE_ENV} (or solve.cache_dir) to a folder you can write"
        ) from None


def _build(unit: Unit, library: Path, compiler: str, flags: Sequence[str]) -> None:
    """Compile ``unit`` into ``library``; its record first, then the library, each renamed
    into place."""
    tag = f"{os.getpid()}.{time.monotonic_ns()}"
    c_file = library.with_name(f"{library.stem}.{tag}.c")
    partial = library.with_name(f"{library.stem}.{tag}.so.part")
    c_file.write_text(unit.source)
    cmd = [compiler, *flags, "-shared", "-fPIC", str(c_file), "-o", str(partial), "-lm"]
    try:
        subprocess.run(cmd, check=True, capture_output=True, text=True)
        record = library.with_name(f"{library.stem}.{tag}.json.part")
        record.write_text(json.dumps(_record(partial, _key(library))))
        record.rename(library.with_suffix(".json"))
        partial.rename(library)
    except subprocess.CalledProcessError as exc:
        raise SolverBuildError(
            f"compiling the TO's {unit.name} failed ({' '.join(cmd)}): {exc.stderr[:2000]}"
        ) from exc
    finally:
        c_file.unlink(missing_ok=True)
        partial.unlink(missing_ok=True)


def _load(name: str, library: Path) -> ca.Function:
    # CasADi builds derivatives of the NLP's own f and g (the "_val" functions) when it sets
    # IPOPT up, though with every oracle given (and no lam_p asked for) it never evaluates
    # them; a compiled function has none, so those get finite differences on paper.
    return ca.external(name, str(library), {"enable_fd": name.endswith("_val")})


def _ensure_built(
    batches: Sequence[Sequence[ca.Function]],
    directory: Path,
    flags: Sequence[str],
    jobs: int | None,
) -> list[Path]:
    """Each batch's library in ``directory``, compiled where none valid is there."""
    cc = compiler(flags)
    units = [_unit(fns, cc, flags) for fns in batches]
    _make_cache(directory)
    library = {u.key: directory / f"to_{u.key}.so" for u in units}
    missing = list({u.key: u for u in units if not _valid(library[u.key])}.values())
    if missing:
        if shutil.which(cc) is None:
            raise SolverBuildError(
                f"the TO compiles its derivatives to C, and the compiler {cc!r} was not "
                "found. Install it (Debian/Ubuntu: `apt-get install gcc`; `make setup` does "
                "so as root), or set solve.solver.compile=false to interpret them, several "
                "times slower per iteration."
            )
        _compile_all(missing, library, cc, flags, jobs or os.cpu_count() or 1, directory)
    return [library[u.key] for u in units]


@dataclasses.dataclass(frozen=True)
class Recipe:
    """One library as :func:`load_or_compile` wants it.

    Attributes:
        fingerprint: Everything the functions are made from (a serialised function, the
            settings, the version of the code that makes them): equal fingerprints must
            give equal functions.
        make: Makes the functions, with JSON-able data the caller needs beside them; called
            only when the index does not know the fingerprint.
    """

    fingerprint: str
    make: Callable[[], tuple[Sequence[ca.Function], dict]]


# The index's entries point at libraries by the key of their generated C: a change to how
# the C is generated must not reuse them.
_CODEGEN = inspect.getsource(_unit)


def _index_path(directory: Path, recipe: Recipe, flags: Sequence[str]) -> Path:
    parts = [recipe.fingerprint, compiler(flags), *flags, ca.__version__, _CODEGEN]
    key = hashlib.sha256("\0".join(parts).encode()).hexdigest()[:16]
    return directory / f"index_{key}.json"


def _indexed(path: Path) -> tuple[list[str], Path, dict] | None:
    """An index entry whose library is valid: function names, library, data."""
    try:
        entry = json.loads(path.read_text())
        library = path.with_name(f"to_{entry['library']}.so")
        names, data = list(entry["functions"]), dict(entry["data"])
    except (OSError, ValueError, KeyError, TypeError):
        return None
    return (names, library, data) if _valid(library) else None


def load_or_compile(
    recipes: Sequence[Recipe],
    directory: Path,
    flags: Sequence[str] = ("-O0",),
    jobs: int | None = None,
) -> list[tuple[list[ca.Function], dict]]:
    """Each recipe's functions, compiled, and its data: from the index when it knows the
    recipe's fingerprint (and its library is valid), else made, compiled (``jobs`` libraries
    at a time, default one per core; logging which, how many of how many, and the time)
    and indexed.

    Raises:
        SolverBuildError: No C compiler, or one failed.
    """
    _make_cache(directory)
    paths = [_index_path(directory, r, flags) for r in recipes]
    found = [_indexed(path) for path in paths]
    todo = [i for i, entry in enumerate(found) if entry is None]
    made = {i: recipes[i].make() for i in todo}
    libraries = _ensure_built([made[i][0] for i in todo], directory, flags, jobs)
    for i, library in zip(todo, libraries, strict=True):
        functions, data = made[i]
        names = [fn.name() for fn in functions]
        entry = {"library": _key(library), "functions": names, "data": data}
        partial = paths[i].with_name(f"{paths[i].stem}.{os.getpid()}.{time.monotonic_ns()}")
        partial.write_text(json.dumps(entry))
        partial.rename(paths[i])
        found[i] = (names, library, data)
    return [([_load(n, library) for n in names], data) for names, library, data in found]


def _compile_all(
    units: list[Unit],
    library: dict[str, Path],
    compiler: str,
    flags: Sequence[str],
    jobs: int,
    directory: Path,
) -> None:
    """Build the biggest units first (they bound the wall time), logging as they end."""
    units = sorted(units, key=lambda u: -len(u.source))
    size = sum(len(u.source) for u in units) / 1e6
    log.info(
        f"compiling {len(units)} libraries ({size:.1f} MB of C, {compiler} "
        f"{' '.join(flags)}, {jobs} at a time) into {directory}; once per robot"
    )
    tic = time.perf_counter()

    def build(unit: Unit) -> float:
        start = time.perf_counter()
        _build(unit, library[unit.key], compiler, flags)
        return time.perf_counter() - start

    with ThreadPoolExecutor(max_workers=jobs) as pool:
        futures = {pool.submit(build, u): u for u in units}
        for done, future in enumerate(as_completed(futures), start=1):
            unit = futures[future]
            seconds = future.result()
            # Each library at DEBUG; a line per tenth of them (and the last) at INFO.
            level = logging.INFO if done % max(len(units) // 10, 1) == 0 else logging.DEBUG
            log.log(
                logging.INFO if done == len(units) else level,
                "%d/%d %s (%.1f MB) in %.0f s; %.0f s elapsed",
                done,
                len(units),
                unit.name,
                len(unit.source) / 1e6,
                seconds,
                time.perf_counter() - tic,
            )
