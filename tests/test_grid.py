"""Paper A's figure grids (issue 22): the runs, the cells, the launch command, the claims
and the figures, without solving (the end-to-end test runs real cells)."""

from __future__ import annotations

import dataclasses
import json
import multiprocessing
import shutil
import time
from pathlib import Path

import numpy as np
import pytest
from hydra._internal.core_plugins.basic_sweeper import BasicSweeper
from hydra.core.override_parser.overrides_parser import OverridesParser

from locoman.config.figures import FiguresCfg, GridCfg
from locoman.config.to import KINDS, EvaluateCfg, SolveCfg
from locoman.errors import ArtifactError, ConfigError
from locoman.grid import cell as cell_module
from locoman.grid.app import summary
from locoman.grid.cell import (
    EVALUATE_MODULES,
    RECORD_FILE,
    SOLVE_MODULES,
    CellCfg,
    cell_dir,
    cell_key,
    cell_scenario,
    check_same_world,
    read_record,
    run_cell,
    solve_key,
    with_time_limit,
)
from locoman.grid.claims import fig5_claims, fig6_claims, vb_claims
from locoman.grid.figures import (
    SUMMARY_COLUMNS,
    fig5,
    fig6,
    markdown_table,
    setting_table,
    summary_csv,
)
from locoman.grid.launch import cells, check_overrides, multirun_command
from locoman.grid.runs import FIGURE_RUNS, KEYFRAME_RUNS, PIPELINE_RUNS, find_run
from locoman.grid.slots import SLOTS_ENV, environment_slot, slot
from locoman.grid.sources import PACKAGE, imported_sources, imports_of
from locoman.scene.builder import build_scene
from locoman.scene.io import write_scene
from locoman.sim.penetration import CLASSES


def test_fig6_has_every_keyframe_combination_from_none_to_all():
    switches = [(r.keyframe_base, r.keyframe_foot, r.warm_start) for r in KEYFRAME_RUNS]
    assert len(set(switches)) == 8
    assert switches[0] == (False, False, False) and KEYFRAME_RUNS[0].label == "NoKeyframe"
    assert switches[-1] == (True, True, True) and KEYFRAME_RUNS[-1].label == "AllKeyframe"
    assert all(r.contacts == "registration" and r.collisions for r in KEYFRAME_RUNS)


def test_a_run_sets_only_its_switches():
    solve = SolveCfg()
    naive = find_run("fig5", "naive").apply(solve, "tiny")
    assert (naive.keyframe_base, naive.keyframe_foot, naive.solver.warm_start) == (False,) * 3
    assert naive.contacts == "naive" and naive.collision == solve.collision
    off = find_run("fig5", "geometry_unaware").apply(solve, "tiny")
    assert all(getattr(off.collision, k) == "off" for k in KINDS)
    assert off.keyframe_base and off.solver.warm_start
    assert solve.contacts == "registration" and solve.collision.object_body == "penalty"
    assert dataclasses.replace(off, contacts="registration", collision=solve.collision) == solve


def test_unknown_figures_and_runs_are_named():
    with pytest.raises(ConfigError, match="known"):
        find_run("fig7", "all")
    with pytest.raises(ConfigError, match="ours"):
        find_run("fig5", "all")


def test_a_cell_checks_its_knobs_and_names_its_folder():
    assert CellCfg("tiny", "fig6", "base_foot", 2.5, -0.6).name == "base_foot_m2.5_yaw-0.6"
    assert CellCfg().check() == []
    bad = CellCfg("../x", "fig5", "all", float("nan"), 4.0).check()
    assert {k for k, _ in bad} == {"scenario", "run", "box_mass", "initial_yaw"}


def test_the_cell_scenario_changes_the_box_mass_and_the_yaw_only(params):
    tiny = params.scenarios["tiny"]
    cell = cell_scenario(tiny, CellCfg(box_mass=2.5, initial_yaw=0.6))
    assert cell.objects["box"].mass == 2.5 and cell.start.yaw == 0.6
    assert cell.start.xy == tiny.start.xy and cell.plan == tiny.plan
    assert cell.objects["table"] == tiny.objects["table"]
    assert tiny.objects["box"].mass == params.scenario.box_mass  # not mutated


def test_upstream_keyframes_are_reused_only_for_the_same_world(params, tiny_scene, tmp_path):
    tiny = params.scenarios["tiny"]
    heavy = tmp_path / "heavy"
    write_scene(heavy, build_scene("tiny", cell_scenario(tiny, CellCfg(box_mass=9.0)), (64, 48)))
    check_same_world(heavy, tiny_scene)
    table = dataclasses.replace(tiny.objects["table"], pos=[0.6, 0.0, 0.0])
    moved = dataclasses.replace(tiny, objects={**tiny.objects, "table": table})
    write_scene(tmp_path / "moved", build_scene("tiny", moved, (64, 48)))
    with pytest.raises(ConfigError, match="dvc repro retarget"):
        check_same_world(tmp_path / "moved", tiny_scene)


@pytest.fixture
def upstream(tiny_scene, tmp_path) -> Path:
    """data/tiny/ with the scene and stand-in contact and keyframe files (not valid
    artifacts: a cell that reads them fails, which the recording test wants)."""
    root = tmp_path / "data" / "tiny"
    shutil.copytree(tiny_scene, root / "scene")
    for folder in ("contacts/subtasks", "retarget/keyframes"):
        (root / folder).mkdir(parents=True)
        (root / folder / "subtask_0.npz").write_bytes(b"not an npz")
    return root


def test_the_keys_change_with_every_input(params, upstream):
    tiny, solve, evaluate = params.scenarios["tiny"], params.solve, params.evaluate
    cell = CellCfg()
    solved = solve_key(cell, tiny, solve, upstream)
    assert solve_key(cell, tiny, solve, upstream) == solved
    assert cell_key(solved, evaluate) == cell_key(solved, evaluate) != solved
    heavier = CellCfg(box_mass=2.5)
    assert solve_key(heavier, cell_scenario(tiny, heavier), solve, upstream) != solved
    weights = dataclasses.replace(solve.weights, collision=10.0)
    heavy_weights = dataclasses.replace(solve, weights=weights)
    assert solve_key(cell, tiny, heavy_weights, upstream) != solved
    moved = dataclasses.replace(solve, cache_dir="/elsewhere")
    assert solve_key(cell, tiny, moved, upstream) == solved  # where the cache is: no
    stricter = dataclasses.replace(evaluate, nonholonomic_tol_mps=1e-6)
    assert cell_key(solved, stricter) != cell_key(solved, evaluate)  # the solve's stays
    (upstream / "retarget/keyframes/subtask_0.npz").write_bytes(b"another keyframe")
    assert solve_key(cell, tiny, solve, upstream) != solved


def test_the_keys_hash_the_code_each_part_imports():
    """The solve's code is what its modules import (the evaluation's is not in it), the
    evaluation's adds its own; both follow imports, lazy ones too."""
    solve = imported_sources(SOLVE_MODULES)
    names = {str(p.relative_to(PACKAGE)) for p in solve}
    assert {
        "to/solve/optimizer.py",
        "to/terms/supports.py",
        "scene/builder.py",
        "kernels.py",
    } <= names
    assert {"contact/io.py", "retarget/io.py", "grid/runs.py", "__init__.py"} <= names
    # The solve replays its solution in MuJoCo to find the collision pairs it needs.
    assert "sim/audit.py" in names and "grid/figures.py" not in names
    evaluate = {str(p.relative_to(PACKAGE)) for p in imported_sources(EVALUATE_MODULES)}
    assert {"sim/evaluate.py", "sim/pipeline.py", "to/terms/kinematics.py"} <= evaluate
    with pytest.raises(ModuleNotFoundError, match="no module of locoman"):
        imported_sources(["locoman.no_such_module"])


def test_imports_are_read_at_any_depth_and_relative_ones_resolved():
    source = (
        "import numpy as np\n"
        "from . import costs\n"
        "from ..scene.g1 import load\n"
        "def later():\n"
        "    import locoman.sim.camera\n"
    )
    assert imports_of(source, "locoman.to") == {
        "locoman.to",
        "locoman.to.costs",
        "locoman.scene.g1",
        "locoman.scene.g1.load",
        "locoman.sim.camera",
    }


def test_the_figures_time_limit_caps_the_solvers_and_keys_the_cell(params, upstream):
    solve = params.solve
    assert solve.solver.max_wall_time_s is None
    limited = with_time_limit(solve, 600.0)
    assert limited.solver.max_wall_time_s == 600.0  # IPOPT's max_wall_time [s]
    tighter = dataclasses.replace(solve.solver, max_wall_time_s=60.0)
    assert with_time_limit(dataclasses.replace(solve, solver=tighter), 600.0).solver == tighter
    assert dataclasses.replace(limited, solver=solve.solver) == solve  # nothing else changes
    cell, tiny = CellCfg(), params.scenarios["tiny"]
    keys = {solve_key(cell, tiny, s, upstream) for s in (limited, solve)}
    assert len(keys) == 2


def test_a_failing_cell_is_recorded_and_a_rerun_tries_it_again(params, upstream):
    data = upstream.parent
    cell = CellCfg("tiny", "fig6", "all", 5.0, 0.0)
    record = run_cell(params, cell, data)  # returns: the grid goes on
    assert record["status"] == "error" and "ArtifactError" in record["reason"]
    assert "subtask_" in record["reason"] and not record["skipped"]
    folder = cell_dir(data, cell)
    assert read_record(folder)["key"] == record["key"]
    assert "Traceback" in (folder / "log.txt").read_text()
    assert not list(folder.parent.glob(".*staging"))  # swapped in whole
    again = run_cell(params, cell, data)  # the error may have been the machine's
    assert not again["skipped"] and again["key"] == record["key"]
    assert again["status"] == "error" and "error (ArtifactError" in summary(again)


def _stand_ins(monkeypatch, calls: dict[str, int]) -> None:
    """A solve and an evaluation that count their calls and write what a cell keeps."""

    def solve(name, scenario, solve, upstream, out):
        calls["solve"] += 1
        (out / "solve").mkdir(parents=True)
        (out / "solve" / "trajectory.npz").write_bytes(b"a trajectory")
        print("IPOPT's iterations")
        return {
            "status": "converged",
            "reason": "",
            "solver_status": "Solve_Succeeded",
            "iterations": 7,
            "solve_time_s": 1.5,
            "collision_rounds": 1,
            "pairs_found": 9,
        }

    def evaluate(cfg, out):
        calls["evaluate"] += 1
        (out / "evaluate").mkdir()
        print("evaluated")
        return {"avg_penetration_m": cfg.nonholonomic_tol_mps, "success": True}

    monkeypatch.setattr(cell_module, "_solve", solve)
    monkeypatch.setattr(cell_module, "_evaluate", evaluate)


def test_a_cell_whose_solve_is_up_to_date_is_only_evaluated_again(params, upstream, monkeypatch):
    """Stand-ins for the solve and the evaluation count their calls: a new evaluation
    parameter reruns the evaluation on the kept trajectory and log, a solve parameter both."""
    calls = {"solve": 0, "evaluate": 0}
    _stand_ins(monkeypatch, calls)
    data, cell = upstream.parent, CellCfg("tiny", "fig6", "all", 5.0, 0.0)
    first = run_cell(params, cell, data)
    assert calls == {"solve": 1, "evaluate": 1} and not first["reevaluated"]
    assert run_cell(params, cell, data)["skipped"] and calls["evaluate"] == 1
    stricter = dataclasses.replace(
        params, evaluate=dataclasses.replace(params.evaluate, nonholonomic_tol_mps=1e-6)
    )
    again = run_cell(stricter, cell, data)
    assert calls == {"solve": 1, "evaluate": 2} and again["reevaluated"]
    assert again["solve_key"] == first["solve_key"] and again["key"] != first["key"]
    assert again["iterations"] == 7 and again["avg_penetration_m"] == 1e-6
    assert again["wall_time_s"] == first["wall_time_s"] and "evaluate_wall_time_s" in again
    folder = cell_dir(data, cell)
    assert read_record(folder) == {k: v for k, v in again.items() if k != "skipped"}
    assert (folder / "log.txt").read_text() == "IPOPT's iterations\nevaluated\nevaluated\n"
    assert "evaluated again" in summary(again)
    weights = dataclasses.replace(stricter.solve.weights, collision=10.0)
    other = dataclasses.replace(
        stricter, solve=dataclasses.replace(stricter.solve, weights=weights)
    )
    assert not run_cell(other, cell, data)["reevaluated"]
    assert calls == {"solve": 2, "evaluate": 3}


def test_rescoring_evaluates_a_kept_solve_whose_code_changed_and_solves_nothing(
    params, upstream, monkeypatch, tmp_path
):
    """Issue 52: an old grid is read with a new metric without solving it again."""
    from locoman.errors import ArtifactError
    from locoman.grid.rescore import main, rescore

    calls = {"solve": 0, "evaluate": 0}
    _stand_ins(monkeypatch, calls)
    data = upstream.parent
    for cell in cells(params, "tiny", "vb"):
        run_cell(params, cell, data)
    assert calls == {"solve": 4, "evaluate": 4}
    # The solve (a weight) and the evaluation (a bound) change: a plain run would solve
    # again, a rescore evaluates the kept solve.
    weights = dataclasses.replace(params.solve.weights, collision=10.0)
    changed = dataclasses.replace(
        params,
        solve=dataclasses.replace(params.solve, weights=weights),
        evaluate=dataclasses.replace(params.evaluate, nonholonomic_tol_mps=1e-6),
    )
    cell = cells(changed, "tiny", "vb")[0]
    old = read_record(cell_dir(data, cell))
    again = run_cell(changed, cell, data, rescore=True)
    assert calls == {"solve": 4, "evaluate": 5}
    assert again["rescored"] and again["solve_key"] == old["solve_key"]
    assert again["pairs_found"] == 9 and again["avg_penetration_m"] == 1e-6
    assert run_cell(changed, cell, data, rescore=True)["skipped"]  # scored with today's
    assert not run_cell(changed, cell, data)["reevaluated"] and calls["solve"] == 5
    # The command scores every cell of the figure and draws it; none is solved.
    params_file = Path(__file__).parents[1] / "params.yaml"
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "timing.json").write_text('{"grid_wall_time_s": {"vb": 60.0}}')
    metrics = rescore("tiny", "vb", tmp_path / "out", params_file, data)
    assert "60.0" in (tmp_path / "out" / "timing.json").read_text()  # the run's, kept
    assert calls["solve"] == 5 and "claims" in metrics
    assert "rounds / pairs found" in (tmp_path / "out" / "summary.md").read_text()
    with pytest.raises(ArtifactError, match="no kept solve"):
        run_cell(params, CellCfg("tiny", "vb", "ours_no_collision", 9.0, 0.0), data, rescore=True)
    assert main(["tiny", "fig7", "out"]) == 2  # usage


def test_a_cell_without_its_upstream_says_which_stage_to_run(params, tmp_path):
    from locoman.errors import ArtifactError

    with pytest.raises(ArtifactError, match="dvc repro retarget@tiny"):
        run_cell(params, CellCfg(), tmp_path)
    assert not (tmp_path / "tiny" / "grid").exists()


def test_a_killed_cell_leaves_no_record(tmp_path):
    folder = tmp_path / "cell"
    folder.mkdir()
    (folder / RECORD_FILE).write_text('{"status": ')  # cut short
    assert read_record(folder) is None


def test_the_multirun_sweeps_every_cell_of_the_figure(params):
    cfg = dataclasses.replace(
        params,
        figures=FiguresCfg(
            ["tiny"], "joblib", 3, 60.0, {"tiny": GridCfg([2.5, 5.0], [0.0, -0.6, 1.2])}
        ),
    )
    planned = cells(cfg, "tiny", "fig6")
    assert len(planned) == 2 * 3 * 8 and len({c.name for c in planned}) == len(planned)
    command = multirun_command(cfg, "tiny", "fig6", ["hydra/launcher=submitit_slurm"])
    assert command[1:4] == ["-m", "locoman.grid.app", "--multirun"]
    assert "cell.box_mass=2.5,5.0" in command and "cell.initial_yaw=0.0,-0.6,1.2" in command
    assert f"cell.run={','.join(r.name for r in KEYFRAME_RUNS)}" in command
    assert "hydra.launcher.n_jobs=3" in command
    jobs = BasicSweeper.split_arguments(
        OverridesParser.create().parse_overrides(command[4:-1]), None
    )[0]
    swept = [dict(o.split("=", 1) for o in job if o.startswith("cell.")) for job in jobs]
    assert [
        (float(j["cell.box_mass"]), float(j["cell.initial_yaw"]), j["cell.run"]) for j in swept
    ] == [
        (c.box_mass, c.initial_yaw, c.run) for c in planned
    ]  # Hydra launches them in cells()' order: whole (mass, yaw) panels first
    assert command[-1] == "hydra/launcher=submitit_slurm"  # the caller's overrides win
    fig5_cells = cells(cfg, "tiny", "fig5")
    assert [c.run for c in fig5_cells] == [r.name for r in PIPELINE_RUNS]
    assert {(c.box_mass, c.initial_yaw) for c in fig5_cells} == {
        (cfg.scenario.box_mass, cfg.scenario.initial_yaw)
    }
    with pytest.raises(ConfigError, match=r"figures\.grids"):
        cells(cfg, "s2_trolley", "fig6")


def test_figures_config_is_checked(params):
    from locoman.config.load import validate

    raw = json.loads(json.dumps(dataclasses.asdict(params), default=str))
    raw["solve"]["scenarios"] = ["tiny"]
    raw["figures"]["scenarios"] = ["s1_basket"]
    with pytest.raises(ConfigError, match=r"figures.scenarios.*not a solve scenario"):
        validate(raw)
    raw["figures"]["scenarios"] = ["tiny"]
    raw["figures"]["launcher"] = "ray_aws"
    with pytest.raises(ConfigError, match=r"figures\.launcher"):
        validate(raw)


def _record(run: str, status: str = "converged", pen: float | None = 0.001, **kw) -> dict:
    labels = {r.name: r.label for runs in FIGURE_RUNS.values() for r in runs}
    return {
        "scenario": "tiny",
        "figure": "fig5" if run in {r.name for r in PIPELINE_RUNS} else "fig6",
        "run": run,
        "label": labels[run],
        "box_mass": kw.get("mass", 5.0),
        "initial_yaw": kw.get("yaw", 0.0),
        "status": status,
        "reason": "" if status == "converged" else "Maximum_Iterations_Exceeded",
        "iterations": 80,
        "avg_penetration_m": pen,
        "max_penetration_m": None if pen is None else 2 * pen,
        "max_penetration_pair": ["floor", "left_foot"],
        "dynamics_residual_max": 1e-9,
        "object_goal_error_m": 0.01,
        "success": status == "converged",
    }


def test_fig5_claims_follow_the_evaluations_bounds():
    cfg = EvaluateCfg()
    runs = {
        "ours": _record("ours", pen=0.001),
        "naive": _record("naive", "not_converged", pen=0.05),
    }
    (minimal,) = fig5_claims(runs, cfg)
    assert minimal.holds is True and "naive: not_converged" in minimal.evidence
    # Converged and low on paper A's headline, but a hand 56 mm inside the box it holds.
    deep_hand = ["scheduled_contact_penetration"]
    runs["naive"] = {**_record("naive", pen=0.0001), "failed_checks": deep_hand}
    (minimal,) = fig5_claims(runs, cfg)
    assert minimal.holds is True and "failed scheduled_contact_penetration" in minimal.evidence
    runs["naive"] = {**runs["naive"], "failed_checks": []}
    assert fig5_claims(runs, cfg)[0].holds is False
    runs["naive"] = {**runs["naive"], "status": "error", "reason": "boom"}
    assert fig5_claims(runs, cfg)[0].holds is None


def _vb_cells(ours: list[float], unaware: list[float]) -> list[dict]:
    return [
        {**_record(run, pen=pen, yaw=0.3 * k), "figure": "vb"}
        for k, pair in enumerate(zip(ours, unaware, strict=True))
        for run, pen in zip(("ours_no_collision", "geometry_unaware"), pair, strict=True)
    ]


def test_vb_is_decided_on_paired_cells_not_one():
    # One cell where ours penetrates more decides nothing; six where it does, that it does.
    (one,) = vb_claims(_vb_cells([0.16], [0.06]))
    assert one.holds is None and "decide nothing" in one.evidence
    (six,) = vb_claims(_vb_cells([0.16, 0.1, 0.2, 0.12, 0.15, 0.3], [0.06] * 6))
    assert six.holds is False and "geometry-unaware contacts, no collision terms lower in 6" in (
        six.evidence
    )
    (ours_lower,) = vb_claims(_vb_cells([0.01] * 6, [0.06, 0.05, 0.2, 0.1, 0.07, 0.3]))
    assert ours_lower.holds is True


def test_fig6_claims_compare_all_against_none_cell_by_cell():
    records = [
        _record("none", "not_converged", 0.05, yaw=0.0),
        _record("all", "converged", 0.001, yaw=0.0),
        _record("none", "converged", 0.002, yaw=0.6),
        _record("all", "converged", 0.004, yaw=0.6),
    ]
    convergence, penetration = fig6_claims(records)
    assert convergence.holds and "AllKeyframe 2/2, NoKeyframe 1/2" in convergence.evidence
    assert penetration.holds is None  # one pair (yaw 0.6): too few to decide
    assert fig6_claims([])[0].holds is None
    # Neither converging anywhere (S2 in paper A's settings) is no evidence either way.
    stuck = [{**r, "status": "not_converged"} for r in records]
    assert fig6_claims(stuck, "fig6_paper")[0].holds is None
    assert fig6_claims(stuck, "fig6_paper")[0].key == "fig6_paper_convergence"
    lower = [
        _record(run, "converged", pen, yaw=0.2 * k)
        for k in range(6)
        for run, pen in (("none", 0.01 + 0.001 * k), ("all", 0.001))
    ]
    assert fig6_claims(lower)[1].holds is True
    close = [{**r, "avg_penetration_m": 0.0004 + 0.0001 * (r["run"] == "none")} for r in lower]
    assert fig6_claims(close)[1].holds is None  # 0.1 mm apart in every cell: a tie
    # A draw without NoKeyframe (WarmStart and AllKeyframe only) decides neither claim.
    without_none = [r for r in lower if r["run"] == "all"]
    for claim in fig6_claims(without_none):
        assert claim.holds is None and "NoKeyframe not in this grid" in claim.evidence


def test_the_figures_and_the_summary_draw_from_records():
    records = [
        _record(run.name, "converged" if k % 3 else "not_converged", 0.02 * k, yaw=yaw)
        for yaw in (0.0, 0.6)
        for k, run in enumerate(KEYFRAME_RUNS)
    ]
    records[3] = {**records[3], "status": "error", "avg_penetration_m": None}
    figure = fig6(records, 0.075, "Fig. 6")
    bars = [p for ax in figure.axes[:2] for p in ax.patches]
    assert max(b.get_height() for b in bars) == pytest.approx(75.0)  # cut at the bound [mm]
    assert any(b.get_hatch() == "//" for b in bars)
    runs5 = {r.name: _record(r.name) for r in PIPELINE_RUNS}
    # time, the headline, then each class: robot-object 2 mm, object-environment 5 mm.
    curve = np.zeros((2, 2 + len(CLASSES)))
    curve[1, :2] = 0.1, 0.002
    curve[1, 2 + CLASSES.index("robot_object")] = 0.002
    curve[1, 2 + CLASSES.index("object_environment")] = 0.005
    figure = fig5(runs5, {r.name: curve for r in PIPELINE_RUNS}, "Fig. 5")
    assert len(figure.axes) == 4  # the headline above, the classes below
    by_class = figure.axes[2]
    assert {line.get_label().split(": ")[1] for line in by_class.lines} == {
        "robot_object",
        "object_environment",
    }
    table = summary_csv(records).splitlines()
    assert table[0].split(",") == list(SUMMARY_COLUMNS) and len(table) == 17
    assert "| AllKeyframe | 5 | 0.6 | converged |" in markdown_table(records)
    records[-1] = {**records[-1], "solver_status": "Solved_To_Acceptable_Level"}
    assert "| AllKeyframe | 5 | 0.6 | converged (settled) |" in markdown_table(records)
    settings = setting_table(records)
    assert "| Base | 2/2 | 20.00 (20.0-20.0) | 40.0-40.0 | 2/2 |" in settings
    # WarmStart: an error at yaw 0 (no penetration, not converged), not converged at 0.6.
    assert "| WarmStart | 0/2 | 60.00 (60.0-60.0) | 120.0-120.0 | 0/2 |" in settings
    assert len(settings.splitlines()) == 2 + len(KEYFRAME_RUNS)


def _by_class(depth: float, node: int = 3) -> dict:
    """A cell's ``penetration_by_class``: ``depth`` [m] in robot_object, nothing elsewhere."""
    empty = {"max_m": 0.0, "avg_m": 0.0, "deepest_pair": None, "nodes_penetrating": 0}
    pair = {"geoms": ["box/body", "left_knee_link#12"], "node": node, "depth_m": depth}
    hit = {"max_m": depth, "avg_m": depth / 10, "deepest_pair": pair, "nodes_penetrating": 2}
    return {kind: hit if kind == "robot_object" else empty for kind in CLASSES}


def test_a_grids_metrics_give_each_runs_penetration_by_class_over_its_converged_cells():
    """Issue 52: every grid's ``metrics.json`` has ``penetration_by_class``, per run: the
    deepest pair over the cells names its cell; failed solves and unevaluated cells are
    left out."""
    from locoman.grid.report import penetration_by_class

    records = [
        _record("none", yaw=0.0) | {"penetration_by_class": _by_class(0.01)},
        _record("none", yaw=0.6) | {"penetration_by_class": _by_class(0.03, node=7)},
        _record("none", "not_converged", yaw=1.2) | {"penetration_by_class": _by_class(0.5)},
        _record("all", "error", yaw=0.0) | {"penetration_by_class": None},
    ]
    by_run = penetration_by_class(records)
    assert by_run["all"] == {}
    robot_object = by_run["none"]["robot_object"]
    assert robot_object["cells"] == 2 and robot_object["max_m"] == pytest.approx(0.03)
    assert robot_object["avg_m"] == pytest.approx(0.002)
    assert robot_object["nodes_penetrating"] == 4
    assert robot_object["deepest_pair"] == {
        "geoms": ["box/body", "left_knee_link#12"],
        "node": 7,
        "depth_m": 0.03,
        "box_mass": 5.0,
        "initial_yaw": 0.6,
    }
    assert by_run["none"]["self"]["deepest_pair"] is None
    assert set(by_run["none"]) == set(CLASSES)


def test_the_figures_stage_runs_its_grids_on_the_parameters_it_was_given(
    params, tmp_path, monkeypatch
):
    """``benchmarks/figures_subset.py`` hands a parameters file with a smaller grid: the
    cells must read that file, or they would run the full grid. The figures' grids run side
    by side, their jobs sharing ``figures.n_jobs`` slots."""
    import locoman.grid.launch as launch_module
    import locoman.grid.report as report

    launched = []
    monkeypatch.setattr(
        launch_module,
        "launch",
        lambda scenario, figure, params_file, runs, env: launched.append(
            (scenario, figure, params_file, tuple(sorted(env.items())))
        ),
    )
    subset = tmp_path / "params.yaml"
    with pytest.raises(ArtifactError, match="has no record"):
        report.figures_scenario(params, "tiny", tmp_path / "out", tmp_path, params_file=subset)
    assert sorted(f[:3] for f in launched) == [("tiny", f, subset) for f in ("fig5", "fig6", "vb")]
    assert len({f[3] for f in launched}) == 1
    assert dict(launched[0][3])[SLOTS_ENV] == str(params.figures.n_jobs)


def test_one_figure_alone_is_launched_drawn_and_summarised(params, tmp_path, monkeypatch):
    """``figures=["fig6"]`` (``figures_subset.py --figures fig6``) runs and reports Fig. 6 only;
    an unknown figure is refused before anything runs."""
    import locoman.grid.launch as launch_module
    import locoman.grid.report as report

    launched = []
    monkeypatch.setattr(
        launch_module,
        "launch",
        lambda scenario, figure, params_file, runs, env: launched.append((figure, env)),
    )
    records = [
        _record(run.name, "converged" if k else "not_converged", 0.002, yaw=yaw)
        for yaw in (0.0, 0.6)
        for k, run in enumerate(KEYFRAME_RUNS)
    ]
    monkeypatch.setattr(report, "collect", lambda *args: records)
    out = tmp_path / "out"
    metrics = report.figures_scenario(params, "tiny", out, tmp_path, figures=["fig6"])
    assert launched == [("fig6", None)]  # one grid: its own launcher's n_jobs, no slots
    assert (out / "fig6.png").is_file() and not (out / "fig5.png").exists()
    assert set(metrics) == {"fig6", "claims"} and metrics["fig6"]["cells"] == 2
    assert set(metrics["fig6"]["penetration_by_class"]) == {r.name for r in KEYFRAME_RUNS}
    summary = (out / "summary.md").read_text()
    assert summary.startswith("# tiny: paper A's Fig. 6\n") and "## Fig. 5" not in summary
    assert len((out / "summary.csv").read_text().splitlines()) == 1 + len(records)
    with pytest.raises(ConfigError, match="unknown figures"):
        report.figures_scenario(params, "tiny", out, tmp_path, figures=["fig7"])
    assert len(launched) == 1


def test_a_grid_of_chosen_runs_launches_and_draws_only_those(params, tmp_path, monkeypatch):
    """``figures_subset.py --runs none all``: Fig. 6's two compared settings alone (S2 in
    paper A's settings is 12 min a solve); ``--draw-only`` launches nothing."""
    import locoman.grid.launch as launch_module
    import locoman.grid.report as report

    planned = cells(params, "tiny", "fig6", ["all", "none"])
    assert [c.run for c in planned] == ["none", "all"] * (len(planned) // 2)
    assert "cell.run=none,all" in multirun_command(params, "tiny", "fig6", [], ["all", "none"])
    with pytest.raises(ConfigError, match=r"has no runs \['nokey'\]"):
        cells(params, "tiny", "fig6", ["nokey"])
    launched = []
    monkeypatch.setattr(
        launch_module,
        "launch",
        lambda scenario, figure, params_file, runs, env: launched.append(runs),
    )
    records = [
        _record(run, "converged", 0.002 * (run == "none"), yaw=yaw)
        for yaw in (0.0, 0.6)
        for run in ("none", "all")
    ]
    monkeypatch.setattr(report, "collect", lambda *args: records)
    out = tmp_path / "out"
    metrics = report.figures_scenario(
        params, "tiny", out, tmp_path, figures=["fig6"], runs=["none", "all"]
    )
    assert launched == [["none", "all"]]
    assert metrics["fig6"]["cells"] == 2
    assert set(metrics["fig6"]["converged_rate"]) == {"none", "all"}
    assert len(fig6(records, 0.075, "Fig. 6").axes[0].patches) == 2  # two bars a panel
    report.figures_scenario(params, "tiny", out, tmp_path, figures=["fig6"], solve=False)
    assert launched == [["none", "all"]]


@pytest.mark.parametrize(
    ("override", "message"),
    [
        ("cell.box_mass=abc", r"cell.box_mass='abc': must be a float"),
        ("cell.box_mass=2.5,abc", r"cell.box_mass='abc'"),
        ("cell.box_mas=3", r"cell.box_mas: a cell has no such key"),
        ("cell.initial_yaw=1,9", r"cell.initial_yaw='9': must be in \[-pi, pi\]"),
        ("cell.run=nokey", r"cell.run='nokey'"),
        ("cell.box_mass=[", r"grid overrides"),
    ],
)
def test_a_bad_grid_override_names_its_key_before_hydra_runs(override, message):
    """issue 53: ``cell.box_mass=abc`` was a Hydra traceback from inside the multirun."""
    with pytest.raises(ConfigError, match=message):
        check_overrides("tiny", "fig5", [override])


def test_good_grid_overrides_pass_the_check():
    check_overrides("tiny", "fig6", ["cell.box_mass=2.5,7.5", "hydra.launcher.n_jobs=1", "x=1"])


def test_a_grids_records_are_exported_and_restored_where_none_is(tmp_path):
    """``python -m locoman.grid.archive``: records out to a committed folder and back, a
    newer record never overwritten, another scenario's refused."""
    from locoman.grid.archive import RECORDS, export_records, main, restore_records

    data, kept = tmp_path / "data", tmp_path / "kept"
    ran = [_record(run, yaw=yaw) for yaw in (0.0, 0.6) for run in ("none", "all")]
    for record in ran:
        cell = CellCfg("tiny", "fig6", record["run"], 5.0, record["initial_yaw"])
        (cell_dir(data, cell)).mkdir(parents=True)
        (cell_dir(data, cell) / "cell.json").write_text(json.dumps(record))
    (data / "tiny" / "grid" / "fig6" / "killed_m5_yaw+0").mkdir()  # no record: left out
    files = export_records(data, "tiny", "fig6", kept)
    assert [f.name for f in files] == sorted(
        f"{r['run']}_m5_yaw{r['initial_yaw']:+g}.json" for r in ran
    )
    assert json.loads(files[0].read_text()) in ran
    alone = export_records(data, "tiny", "fig6", tmp_path / "one", only={"all_m5_yaw+0.6"})
    assert [f.name for f in alone] == ["all_m5_yaw+0.6.json"]

    fresh = tmp_path / "fresh"
    newer = {**ran[0], "iterations": 99}
    newer_dir = cell_dir(fresh, CellCfg("tiny", "fig6", ran[0]["run"], 5.0, 0.0))
    newer_dir.mkdir(parents=True)
    (newer_dir / "cell.json").write_text(json.dumps(newer))
    restored, kept_own = restore_records(fresh, "tiny", kept)
    assert len(restored) == 3 and kept_own == ["fig6/none_m5_yaw+0"]
    assert read_record(newer_dir)["iterations"] == 99
    for record in ran[1:]:
        cell = CellCfg("tiny", "fig6", record["run"], 5.0, record["initial_yaw"])
        assert read_record(cell_dir(fresh, cell)) == record

    with pytest.raises(ArtifactError, match="a record of 'tiny', not 's1_basket'"):
        restore_records(fresh, "s1_basket", kept)
    with pytest.raises(ArtifactError, match="holds no cell record"):
        export_records(data, "tiny", "vb", kept)
    (kept / RECORDS / "fig6" / "bad.json").write_text(json.dumps({"run": "all"}))
    assert main(["--data-dir", str(fresh), "restore", "tiny", str(kept)]) == 2


def test_only_up_to_date_records_are_exported_unless_asked(params, upstream):
    """A grid restarted after a change holds its older cells' records until they are solved
    again: ``export`` keeps to the records whose key matches the checkout's (the same key a
    grid skips on), ``--stale`` takes every one."""
    from locoman.grid.archive import current_key, export_records, main

    data = upstream.parent
    fresh, old = CellCfg(run="all"), CellCfg(run="none")
    for cell, key in ((fresh, current_key(params, fresh, data)), (old, "a key of before")):
        cell_dir(data, cell).mkdir(parents=True)
        record = {**_record(cell.run, yaw=0.0), "key": key}
        (cell_dir(data, cell) / "cell.json").write_text(json.dumps(record))
    files = export_records(data, "tiny", "fig6", data / "out", current=params)
    assert [f.name for f in files] == [f"{fresh.name}.json"]
    everything = export_records(data, "tiny", "fig6", data / "all")
    assert sorted(f.name for f in everything) == sorted(f"{c.name}.json" for c in (fresh, old))
    (upstream / "retarget" / "keyframes" / "subtask_0.npz").write_bytes(b"other keyframes")
    with pytest.raises(ArtifactError, match="holds no up to date cell record"):
        export_records(data, "tiny", "fig6", data / "none", current=params)
    assert (
        main(["--data-dir", str(data), "export", "tiny", "fig6", str(data / "s"), "--stale"]) == 0
    )
    assert len(list((data / "s").rglob("*.json"))) == 2


def _hold_a_slot(folder: str, log: str) -> None:
    with slot(Path(folder), 2, poll_s=0.01) as i:
        with open(log, "a") as out:
            out.write(f"{time.monotonic()} +1 {i}\n")
        time.sleep(0.3)
        with open(log, "a") as out:
            out.write(f"{time.monotonic()} -1 {i}\n")


def test_jobs_of_grids_side_by_side_hold_at_most_their_slots_by_wall_clock_overlap(tmp_path):
    """Five processes, two slots: never more than two cells at once, every one runs, and a
    job without the slots in its environment runs at once."""
    log = tmp_path / "log.txt"
    context = multiprocessing.get_context("fork")
    jobs = [
        context.Process(target=_hold_a_slot, args=(str(tmp_path / "slots"), str(log)))
        for _ in range(5)
    ]
    for job in jobs:
        job.start()
    for job in jobs:
        job.join(timeout=60)
    assert all(job.exitcode == 0 for job in jobs)
    events = sorted(tuple(line.split()) for line in log.read_text().splitlines())
    running = np.cumsum([int(change) for _, change, _ in events])
    assert len(events) == 10 and running.max() == 2 and running[-1] == 0
    assert {index for _, _, index in events} == {"0", "1"}
    with environment_slot({}):
        pass  # no slots asked for: nothing to wait for


def test_a_figures_first_cells_take_their_slots_before_the_next_figure_is_launched(
    params, monkeypatch
):
    """Fig. 5's naive run, the longest cell, must not wait behind Fig. 6's and V-B's first
    cells: each figure is launched once the previous one's first cells hold their slots (or
    it has ended)."""
    import threading

    import locoman.grid.launch as launch_module

    events: list[tuple[float, str]] = []
    held = threading.Event()

    def fake_launch(scenario, figure, params_file, runs, env):
        events.append((time.monotonic(), f"launch {figure}"))
        if figure != "fig5":
            return
        folder, n = Path(env["LOCOMAN_GRID_SLOT_DIR"]), int(env[SLOTS_ENV])
        time.sleep(0.5)  # Hydra and the workers starting

        def hold(i):
            with slot(folder, n, poll_s=0.01):
                if i == 0:
                    events.append((time.monotonic(), "fig5 holds its slots"))
                held.wait(2.0)

        workers = [threading.Thread(target=hold, args=(i,)) for i in range(n)]
        for worker in workers:
            worker.start()
        time.sleep(0.5)
        held.set()
        for worker in workers:
            worker.join()

    monkeypatch.setattr(launch_module, "launch", fake_launch)
    launch_module.launch_figures(params, "tiny", ["fig5", "fig6", "vb"])
    order = [name for _, name in sorted(events)]
    assert order[:2] == ["launch fig5", "fig5 holds its slots"], order
    assert set(order[2:]) == {"launch fig6", "launch vb"}
