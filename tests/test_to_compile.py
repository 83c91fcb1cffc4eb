"""The TO's compiled terms: one set per robot, whatever the scenario, its numbers or its
structure; and the compile cache."""

from __future__ import annotations

import logging
import shutil

import casadi as ca
import numpy as np
import pytest

from locoman.artifacts.io import split_wall_clock
from locoman.errors import SolverBuildError
from locoman.to.nlp.compile import Recipe, compiler, load_or_compile


def test_wall_clock_figures_are_split_from_the_results_at_any_depth():
    metrics = {
        "status": "ok",
        "solve_time_s": 3.0,
        "per_subtask": [{"index": 0, "seconds": 1.5}, {"index": 1}],
        "cases": {"a": {"rmse": 0.1, "kmp_seconds": 0.2}},
    }
    science, timing = split_wall_clock(metrics)
    assert science == {
        "status": "ok",
        "per_subtask": [{"index": 0}, {"index": 1}],
        "cases": {"a": {"rmse": 0.1}},
    }
    assert timing == {
        "solve_time_s": 3.0,
        "per_subtask": [{"seconds": 1.5}, None],
        "cases": {"a": {"kmp_seconds": 0.2}},
    }
    assert split_wall_clock({"status": "ok"}) == ({"status": "ok"}, None)


def _tiny_function(name: str) -> ca.Function:
    x = ca.SX.sym("x", 2)
    return ca.Function(name, [x], [ca.sin(x[0]) * x[1]])


def compile_units(batches, directory) -> dict[str, ca.Function]:
    """name -> function, each batch of functions one recipe of :func:`load_or_compile` (one
    library), as the TO's terms are built."""
    recipes = [
        Recipe(" ".join(f.name() for f in fns), lambda fns=fns: (fns, {})) for fns in batches
    ]
    return {f.name(): f for fns, _ in load_or_compile(recipes, directory) for f in fns}


@pytest.mark.skipif(shutil.which("gcc") is None, reason="no C compiler")
def test_a_truncated_library_is_rebuilt_not_loaded(tmp_path, caplog):
    caplog.set_level(logging.INFO, logger="locoman.to.nlp.compile")
    compile_units([[_tiny_function("f_jac")]], tmp_path)
    (library,) = tmp_path.glob("to_*.so")
    library.write_bytes(library.read_bytes()[:100])  # an interrupted copy
    fn = compile_units([[_tiny_function("f_jac")]], tmp_path)["f_jac"]
    assert float(fn([0.5, 2.0])) == pytest.approx(2.0 * np.sin(0.5))
    assert library.stat().st_size > 100
    assert "1/1 f" in caplog.text  # progress: unit, how many of how many
    caplog.clear()
    compile_units([[_tiny_function("f_jac")]], tmp_path)
    assert "compiling" not in caplog.text  # valid: loaded, not rebuilt


@pytest.mark.skipif(shutil.which("gcc") is None, reason="no C compiler")
def test_two_libraries_swapped_with_their_records_are_rebuilt(tmp_path):
    """issue 53: each library matched its own record, so the swap loaded and CasADi failed
    in External::init; the record names the unit it was built for."""
    batches = [[_tiny_function("f_jac")], [_tiny_function("g_jac")]]
    compile_units(batches, tmp_path)
    a, b = sorted(tmp_path.glob("to_*.so"))
    for suffix in (".so", ".json"):
        first, second = a.with_suffix(suffix), b.with_suffix(suffix)
        first.rename(tmp_path / "swap")
        second.rename(first)
        (tmp_path / "swap").rename(second)
    fns = compile_units(batches, tmp_path)
    assert float(fns["g_jac"]([0.5, 2.0])) == pytest.approx(2.0 * np.sin(0.5))


def test_a_cache_folder_that_cannot_be_made_names_the_variable(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("")
    with pytest.raises(SolverBuildError, match="LOCOMAN_CACHE_DIR"):
        compile_units([[_tiny_function("f_jac")]], blocker / "cache")
    with pytest.raises(SolverBuildError, match="LOCOMAN_CACHE_DIR"):
        load_or_compile([Recipe("x", lambda: ([], {}))], blocker / "cache")


@pytest.mark.skipif(shutil.which("gcc") is None, reason="no C compiler")
def test_an_indexed_recipe_is_loaded_without_making_its_functions(tmp_path):
    made = []

    def make() -> tuple[list[ca.Function], dict]:
        made.append(1)
        return [_tiny_function("h_jac")], {"pattern": [1, 2]}

    recipe = Recipe("h v1", make)
    for calls in (1, 1):  # built and indexed, then loaded from the index
        ((fn,), data) = load_or_compile([recipe], tmp_path)[0]
        assert len(made) == calls and data == {"pattern": [1, 2]}
        assert float(fn([0.5, 2.0])) == pytest.approx(2.0 * np.sin(0.5))
    del fn  # unloads the library: truncating a loaded one is a SIGBUS
    (library,) = tmp_path.glob("to_*.so")
    library.write_bytes(library.read_bytes()[:100])  # the index's library is broken: remade
    ((fn,), _) = load_or_compile([recipe], tmp_path)[0]
    assert len(made) == 2 and float(fn([0.5, 2.0])) == pytest.approx(2.0 * np.sin(0.5))
    load_or_compile([Recipe("h v2", make)], tmp_path)  # another fingerprint: made
    assert len(made) == 3 and len(list(tmp_path.glob("index_*.json"))) == 2


def test_a_missing_compiler_says_how_to_install_it(tmp_path, monkeypatch):
    monkeypatch.setenv("CC", "no-such-compiler-locoman")
    with pytest.raises(SolverBuildError, match="apt-get install gcc"):
        compile_units([[_tiny_function("g_jac")]], tmp_path)


def test_the_compiler_is_cc_else_tcc_without_optimisation_else_gcc(monkeypatch):
    monkeypatch.setenv("CC", "clang")
    assert compiler(["-O2"]) == "clang"
    monkeypatch.delenv("CC")
    assert compiler(["-O1"]) == "gcc"
    tcc = shutil.which("tcc") is not None
    assert compiler(["-O0"]) == ("tcc" if tcc else "gcc")
    assert compiler([]) == ("tcc" if tcc else "gcc")
