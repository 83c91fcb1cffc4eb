"""The TO's runtime parameters: numbers are inputs of the compiled functions, never
constants in them, so one compiled problem serves every value; and the compile cache."""

from __future__ import annotations

import dataclasses
import shutil

import casadi as ca
import numpy as np
import pytest

from locoman.artifacts.io import split_wall_clock
from locoman.retarget.robot import contact_frames
from locoman.scene import g1
from locoman.to.collision import CollisionCfg, Obstacle
from locoman.to.compile import Recipe, SolverBuildError, compile_units, load_or_compile
from locoman.to.costs import CostWeights
from locoman.to.kinematics import SymbolicKinematics
from locoman.to.layout import NodeLayout, ObjectModel, object_key
from locoman.to.problem import ContactCfg, NodeMode, ObjectMode, StageBuilder

KIN = SymbolicKinematics(g1.g1_pinocchio_model())
TABLE = Obstacle("table", np.array([1.0, 0.0, 0.36]), 0.2, np.array([0.3, 0.4, 0.36]))
CARRY = NodeMode((True, True), (0, 0), (ObjectMode(True, None),))
LAYOUT = NodeLayout.of(1)
VARIABLES, WIDTH, N_PARAMS = LAYOUT.variables, LAYOUT.width, LAYOUT.n_params
OBJECT_Q, OBJECT_V = object_key(0, "q"), object_key(0, "v")


def _builder(mass: float, weights: CostWeights, friction: float = 0.8) -> StageBuilder:
    box = ObjectModel.box("box", np.array([0.25, 0.3, 0.2]), mass, friction)
    return StageBuilder(
        KIN,
        (box,),
        contact_frames(),
        weights,
        ContactCfg(floor_friction=friction),
        CollisionCfg(self_pairs=[]),
        (TABLE,),
    )


def _point(seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    z, z1 = 0.1 * rng.normal(size=WIDTH), 0.1 * rng.normal(size=WIDTH)
    for x in (z, z1):
        x[VARIABLES["q"]] = g1.standing_q35() + 0.05 * rng.normal(size=35)
        x[VARIABLES[OBJECT_Q]] = [0.6, 0.0, 0.8, 0.05, -0.03, 0.1]
        x[VARIABLES["dt"]] = 0.05
    return z, z1, rng.normal(size=N_PARAMS), rng.normal(size=N_PARAMS)


def test_a_stage_built_with_other_numbers_is_the_same_function_of_theta():
    """Built for a 2 kg box and Table I's weights, the carry stage evaluated with the
    parameters of a 7.5 kg box and other weights is the stage built for those: no number
    of the first build is a constant of its graph, and the generated C is the same."""
    heavy_weights = dataclasses.replace(
        CostWeights(), slack=3e5, com_over_feet=50.0, keyframe_base=[7.0, 3.0], collision=20.0
    )
    light = _builder(2.0, CostWeights())
    heavy = _builder(7.5, heavy_weights, friction=0.5)
    f_light = light.group(CARRY, CARRY, True, np.array([0])).function
    f_heavy = heavy.group(CARRY, CARRY, True, np.array([0])).function
    theta_light, theta_heavy = light.parameters.vector(), heavy.parameters.vector()
    assert light.parameters.layout == heavy.parameters.layout
    assert not np.allclose(theta_light, theta_heavy)
    for seed in range(3):
        args = _point(seed)
        for out_a, out_b in zip(
            f_light(*args, theta_heavy), f_heavy(*args, theta_heavy), strict=True
        ):
            np.testing.assert_allclose(np.asarray(out_a), np.asarray(out_b), rtol=1e-12)
        cost_light = float(f_light(*args, theta_light)[1])
        assert cost_light != pytest.approx(float(f_heavy(*args, theta_heavy)[1]))
    gen = [ca.CodeGenerator("x.c", {"with_header": False}) for _ in range(2)]
    gen[0].add(f_light)
    gen[1].add(f_heavy)
    assert gen[0].dump() == gen[1].dump()


def test_the_object_mass_enters_its_dynamics():
    """(1a) of the carried box at rest: a box 3 kg heavier, everything else equal, changes
    only its vertical momentum row, by the extra weight's impulse 3 kg * 9.81 m/s^2 * dt."""
    builder = _builder(2.0, CostWeights())
    f = builder.group(CARRY, CARRY, False, np.array([0])).function
    z, z1, p, p1 = _point(0)
    z[VARIABLES[OBJECT_V]] = z1[VARIABLES[OBJECT_V]] = 0.0
    params = builder.parameters
    heavier = dataclasses.replace(params, values=params.values | {"object0.mass": np.array([5.0])})
    g_light = np.asarray(f(z, z1, p, p1, params.vector())[0]).ravel()
    g_heavy = np.asarray(f(z, z1, p, p1, heavier.vector())[0]).ravel()
    expected = np.zeros_like(g_light)
    expected[6 + 35 + 2] = 3.0 * 9.81 * z[VARIABLES["dt"]][0]  # after the robot's (1a), (1b)
    np.testing.assert_allclose(g_heavy - g_light, expected, atol=1e-9)


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


@pytest.mark.skipif(shutil.which("gcc") is None, reason="no C compiler")
def test_a_truncated_library_is_rebuilt_not_loaded(tmp_path, capsys):
    compile_units([[_tiny_function("f_jac")]], tmp_path)
    (library,) = tmp_path.glob("to_*.so")
    library.write_bytes(library.read_bytes()[:100])  # an interrupted copy
    fn = compile_units([[_tiny_function("f_jac")]], tmp_path)["f_jac"]
    assert float(fn([0.5, 2.0])) == pytest.approx(2.0 * np.sin(0.5))
    assert library.stat().st_size > 100
    assert "1/1 f" in capsys.readouterr().out  # progress: unit, how many of how many
    compile_units([[_tiny_function("f_jac")]], tmp_path)
    assert "compiling" not in capsys.readouterr().out  # valid: loaded, not rebuilt


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
