"""The source files of locoman that a module runs: its imports, followed transitively.

A grid cell's key hashes the code it runs (:mod:`locoman.grid.cell`). Read from the
imports, not listed by hand, the set cannot miss a module a stage starts to use; parsed,
not imported, it costs no import time and runs no code.
"""

from __future__ import annotations

import ast
from collections.abc import Iterable
from pathlib import Path

import locoman

PACKAGE = Path(locoman.__file__).parent
ROOT = PACKAGE.name  # "locoman"
# The modules a grid cell's solve runs (their imports are followed) and its evaluation's;
# the cell's own file (not its imports, which reach the evaluation) decides its scenario and
# limits. The figures' drawing is in neither: redrawing reuses the cells.
CELL_FILE = "grid/cell.py"
SOLVE_MODULES = (
    "locoman.scene.builder",
    "locoman.scene.io",
    "locoman.to.pipeline",
    "locoman.grid.runs",
    # The CPU kernels the launcher pins in the cells' environment decide the last bits.
    "locoman.kernels",
)
EVALUATE_MODULES = ("locoman.sim.pipeline",)


def module_file(name: str, package: Path = PACKAGE) -> Path | None:
    """The source of module ``name`` (``locoman.a.b``): ``a/b.py`` or ``a/b/__init__.py``
    under ``package`` (this one's folder, or another checkout's); None for a name that is no
    module of it (a class, a function)."""
    parts = name.split(".")
    if parts[0] != ROOT:
        return None
    base = Path(package).joinpath(*parts[1:])
    for path in (base.with_suffix(".py"), base / "__init__.py"):
        if path.is_file():
            return path
    return None


def imports_of(source: str, package: str) -> set[str]:
    """Every locoman name an ``import`` in ``source`` (a module of ``package``, e.g.
    ``locoman.to``) names, at any depth (a function's lazy import too), relative ones
    resolved, with each ``from a import b`` also as ``a.b`` (b may be a module)."""
    parts = package.split(".")
    names = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = parts[: len(parts) - node.level + 1] if node.level else []
            module = ".".join([*base, *(node.module.split(".") if node.module else [])])
            names.add(module)
            names.update(f"{module}.{alias.name}" for alias in node.names)
    return {n for n in names if n.split(".")[0] == ROOT}


def _imported(path: Path, package: Path) -> set[str]:
    name = ".".join([ROOT, *path.relative_to(package).parent.parts])
    return imports_of(path.read_text(), name)


def _with_parents(name: str) -> list[str]:
    """``a.b.c`` -> ``a``, ``a.b``, ``a.b.c``: importing a module runs its packages first."""
    parts = name.split(".")
    return [".".join(parts[:i]) for i in range(1, len(parts) + 1)]


def imported_sources(modules: Iterable[str], package: Path = PACKAGE) -> list[Path]:
    """The sorted source files of ``modules`` and of every locoman module they import,
    transitively, their packages' ``__init__.py`` included, read from ``package`` (this
    package's folder, or another checkout's ``locoman/``).

    Raises:
        ModuleNotFoundError: A name in ``modules`` is no locoman module.
    """
    seen: set[Path] = set()
    stack = []
    for name in modules:
        if module_file(name, package) is None:
            raise ModuleNotFoundError(f"{name!r} is no module of {ROOT} (under {package})")
        stack.append(name)
    while stack:
        for parent in _with_parents(stack.pop()):
            path = module_file(parent, package)
            if path is None or path in seen:
                continue
            seen.add(path)
            stack.extend(_imported(path, package))
    return sorted(seen)
