"""``solve.mode: paper_a``: each scenario as paper A ran Sec. V-A and V-C (its minimal
collision set alone, (14a)'s averaging with (10) in the stage cost, its keyframes), and the
grid figure ``fig6_paper`` that runs the keyframe ablation in it."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from locoman.config import load_params
from locoman.config.to import KINDS, PaperSetCfg, ScheduleCfg, SolveCfg, SolverCfg, scenario_solve
from locoman.errors import ConfigError
from locoman.grid.figures import short_reason
from locoman.grid.report import default_figures
from locoman.grid.runs import find_run
from locoman.scene import g1
from locoman.to.problem.inputs import Keyframe, TOInputs, guided_by, guiding_keyframe
from locoman.to.problem.layout import NodeLayout
from locoman.to.problem.modes import node_modes
from locoman.to.problem.numbers import node_parameters
from locoman.to.problem.objects import ObjectModel
from locoman.to.problem.schedule import build_schedule
from locoman.to.solve.initial_guess import initial_guess
from locoman.to.terms.supports import Surface

S1_SET = PaperSetCfg(
    collision={"legs_object": "penalty", "object_environment": "penalty"}, keyframes=[0, 2]
)


def _paper(**sets: PaperSetCfg) -> SolveCfg:
    return SolveCfg(mode="paper_a", paper_a=sets)


def test_paper_mode_keeps_the_scenarios_set_alone_averages_and_takes_its_keyframes():
    solve = scenario_solve(_paper(s1_basket=S1_SET), "s1_basket")
    on = {k for k in KINDS if getattr(solve.collision, k) != "off"}
    assert on == {"legs_object", "object_environment"}  # no found pairs either
    assert solve.weights.average_over_nodes
    assert solve.keyframes == [0, 2]
    product = SolveCfg()
    assert scenario_solve(product, "s1_basket") is product


def test_paper_mode_for_a_scenario_without_a_set_says_what_to_add():
    with pytest.raises(ConfigError, match=r"no set for 'tiny'.*conf/solve"):
        scenario_solve(_paper(s1_basket=S1_SET), "tiny")


def test_a_paper_set_names_real_collision_kinds_and_treatments():
    bad = PaperSetCfg(collision={"elbows": "penalty", "legs_object": "hard"}, keyframes=[])
    messages = " ".join(m for _, m in bad.check())
    assert "'elbows' is not a collision kind" in messages
    assert "legs_object: must be one of" in messages
    assert "subtask indices" in messages


def test_the_configured_paper_sets_are_sec_v_as():
    solve = load_params().solve
    s1 = scenario_solve(dataclasses.replace(solve, mode="paper_a"), "s1_basket")
    s2 = scenario_solve(dataclasses.replace(solve, mode="paper_a"), "s2_trolley")
    assert s1.keyframes == [0, 1, 3]  # pick, place, grab: the step's keyframe is not used
    assert (s2.collision.legs_object, s2.collision.knee_collision) == ("homotopy", "constraint")
    assert s2.collision.hands_object == "penalty" and s2.collision.found == "off"


def test_the_fig6_paper_runs_are_fig6s_settings_in_paper_mode():
    solve = load_params().solve
    all_paper = find_run("fig6_paper", "all").apply(solve, "s1_basket")
    none_paper = find_run("fig6_paper", "none").apply(solve, "s1_basket")
    assert all_paper.mode == "paper_a" and all_paper.keyframes == [0, 1, 3]
    assert not (none_paper.keyframe_base or none_paper.keyframe_foot)
    assert not none_paper.solver.warm_start
    assert find_run("fig6", "all").apply(solve, "s1_basket").mode == "product"
    cfg = load_params()
    assert "fig6_paper" not in default_figures(cfg, "tiny")
    assert "fig6_paper" in default_figures(cfg, "s1_basket")


def _three_subtasks() -> TOInputs:
    """Walk, squat, walk: three keyframes of distinct base heights."""
    box = ObjectModel.box("box", np.array([0.4, 0.4, 0.3]), 5.0, 0.8)
    keyframes = []
    for i, (x, dz) in enumerate([(0.5, 0.0), (0.5, -0.1), (1.0, -0.05)]):
        q = g1.standing_q35()
        q[0], q[2] = x, q[2] + dz
        keyframes.append(Keyframe("walk", q, None, np.zeros((1, 6)) + i))
    return TOInputs(
        g1.standing_q35(),
        (box,),
        np.array([[3.0, 0.0, 0.15, 0.0, 0.0, 0.0]]),
        (Surface(),),
        np.zeros(1),
        keyframes,
        np.zeros((1, 2, 3)),
        np.tile(np.eye(3), (1, 2, 1, 1)),
    )


def test_a_keyframe_that_does_not_guide_has_no_keyframe_cost_and_starts_at_the_next():
    inputs = guided_by(_three_subtasks(), [0, 2])
    assert [kf.guides for kf in inputs.keyframes] == [True, False, True]
    assert guiding_keyframe(inputs, 1) is inputs.keyframes[2]
    schedule = build_schedule(inputs, ScheduleCfg())
    P = node_parameters(inputs, schedule, keyframe_base=True, keyframe_foot=True)
    par = NodeLayout.of(1).parameters
    on = np.flatnonzero(P[par["kf_base_on"]].ravel())
    assert list(on) == [schedule.keyframe_nodes()[0], schedule.keyframe_nodes()[2]]
    foot_on = P[par["kf_foot_on"]].ravel() > 0
    assert not any(foot_on[k] for k in range(schedule.nodes) if schedule.subtask_of(k) == 1)
    layout = NodeLayout.of(1)
    X = initial_guess(layout, inputs, schedule, node_modes(inputs, schedule), SolverCfg(), 35.0)
    q = layout.variables["q"]
    middle = [k for k in range(schedule.nodes) if schedule.subtask_of(k) == 1]
    assert middle
    for k in middle:
        np.testing.assert_allclose(X[q, k], inputs.keyframes[2].q35)
    with pytest.raises(ConfigError, match="names subtask 3, but the plan has 3"):
        guided_by(_three_subtasks(), [0, 3])


def test_a_hatched_bar_says_why_in_a_few_letters():
    assert short_reason("Maximum_Iterations_Exceeded") == "iter"
    assert short_reason("Restoration_Failed") == "restor"
    assert short_reason("Collision_Pairs_Missing") == "pairs"
    assert short_reason("Collision_Pairs_Unfreed") == "unfreed"
    assert short_reason("ArtifactError: something") == "Artifa"
