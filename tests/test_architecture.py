"""The library's shape: no import cycles, configuration below the TO, the TO's files small
and each named once."""

from __future__ import annotations

import ast
from collections import Counter
from pathlib import Path

import locoman

PACKAGE = Path(locoman.__file__).parent
TO = PACKAGE / "to"
MAX_TO_LINES = 450


def _module(path: Path) -> str:
    parts = ["locoman", *path.relative_to(PACKAGE).with_suffix("").parts]
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _modules() -> dict[str, Path]:
    return {_module(p): p for p in PACKAGE.rglob("*.py")}


def imports_of(path: Path, modules: dict[str, Path]) -> set[str]:
    """The library's modules ``path`` imports anywhere in it: at the top, inside a function
    (a lazy import) or under ``if TYPE_CHECKING:``; ``from a import b`` counts as ``a.b``
    where ``b`` is a module, else as ``a``."""
    me = _module(path)
    package = me if path.name == "__init__.py" else me.rpartition(".")[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.rsplit(".", node.level - 1)[0] if node.level > 1 else package
                base = f"{anchor}.{base}" if base else anchor
            for alias in node.names:
                full = f"{base}.{alias.name}"
                found.add(full if full in modules else base)
    return {m for m in found if m in modules and m != me}


def import_graph() -> dict[str, set[str]]:
    modules = _modules()
    return {name: imports_of(path, modules) for name, path in modules.items()}


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan's algorithm)."""
    index, low, stack, on_stack, out = {}, {}, [], set(), []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                out.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_the_cycle_finder_finds_a_cycle():
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def test_no_module_of_the_library_imports_itself_back():
    assert cycles(import_graph()) == []


def test_the_configuration_does_not_import_the_to():
    graph = import_graph()
    wrong = {
        m: sorted(i for i in imports if i.startswith("locoman.to")) for m, imports in graph.items()
    }
    assert {m: i for m, i in wrong.items() if m.startswith("locoman.config") and i} == {}


def test_the_to_files_are_small_and_each_named_once():
    files = [p for p in TO.rglob("*.py") if p.name != "__init__.py"]
    long = {
        str(p.relative_to(TO)): n
        for p in files
        if (n := len(p.read_text().splitlines())) > MAX_TO_LINES
    }
    assert long == {}
    twice = [name for name, n in Counter(p.name for p in files).items() if n > 1]
    assert twice == []
