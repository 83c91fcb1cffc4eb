"""The whole TO on a small problem: it converges, its dynamics hold by Pinocchio's account,
the feet stay put, and a failed solve comes back with its status; plus the schedule."""

from __future__ import annotations

import dataclasses
import time

import numpy as np
import pytest

from locoman.config.to import KINDS, CollisionCfg, CostWeights, ScheduleCfg, SolveCfg, SolverCfg
from locoman.errors import ConfigError
from locoman.scene import g1
from locoman.sim.evaluate import cone_violation, dynamics_residuals, stance_slip
from locoman.to.problem.inputs import Keyframe, TOInputs
from locoman.to.problem.modes import node_modes
from locoman.to.problem.objects import ObjectModel
from locoman.to.problem.schedule import step_count, subtask_phases
from locoman.to.solve.optimizer import TrajectoryOptimizer
from locoman.to.terms.supports import Chassis, OnObject, Surface

BOX = ObjectModel.box("box", np.array([0.25, 0.3, 0.2]), 2.0, 0.8)
SOLE = g1.foot_sole_corners()["left_ankle_roll_link"].mean(axis=0)


BOX_ON_TABLE = np.array([[2.0, 0.0, 0.7, 0.0, 0.0, 0.0]])


def _inputs(keyframes: list[Keyframe]) -> TOInputs:
    """The G1 at rest, one box on a table 2 m ahead, and the given keyframes."""
    return TOInputs(
        g1.standing_q35(),
        (BOX,),
        BOX_ON_TABLE,
        (Surface(),),
        np.array([0.7]),
        keyframes,
        np.zeros((1, 2, 3)),
        np.tile(np.eye(3), (1, 2, 1, 1)),
    )


def _squat_inputs() -> TOInputs:
    keyframe = g1.standing_q35()
    keyframe[2] -= 0.12
    return _inputs([Keyframe("walk", keyframe, None, BOX_ON_TABLE)])


def _cfg(**solver) -> SolveCfg:
    schedule = ScheduleCfg(double_support_nodes=4)
    return SolveCfg(schedule=schedule, solver=SolverCfg(compile=False, print_level=0, **solver))


def _optimizer(tmp_path_factory, **solver) -> TrajectoryOptimizer:
    return TrajectoryOptimizer(_squat_inputs(), _cfg(**solver), None)


def _as_arrays(traj) -> dict[str, np.ndarray]:
    return {f.name: getattr(traj, f.name) for f in dataclasses.fields(traj)}


@pytest.fixture(scope="module")
def squat(tmp_path_factory):
    return _optimizer(tmp_path_factory, max_iterations=200).solve()


def test_the_squat_converges_towards_the_keyframe_height(squat):
    assert squat.success, squat.status
    assert squat.q.shape == (5, 35)
    assert squat.max_constraint_violation <= 1e-6
    # (9) pulls the base towards the keyframe's lower height.
    assert squat.q[-1, 2] < squat.q[0, 2] - 1e-4


def test_dynamics_hold_by_pinocchio_and_the_feet_do_not_slip(squat):
    arrays = _as_arrays(squat)
    assert dynamics_residuals(arrays, [BOX], SOLE).max <= 1e-6
    assert stance_slip(arrays, SOLE) <= 1e-6
    assert squat.foot_wrench[:-1, :, 2].sum(axis=1).min() > 0.0


def test_a_failed_solve_is_returned_with_its_status(tmp_path_factory):
    traj = _optimizer(tmp_path_factory, max_iterations=1).solve()
    assert not traj.success
    assert traj.status == "Maximum_Iterations_Exceeded"
    assert traj.iterations == 1


def test_the_first_solve_is_of_the_built_problem_and_the_build_counts_each_piece_once(
    tmp_path_factory,
):
    """Solving the problem the optimizer was built with transcribes and assembles nothing
    more; another transcription (a round's) adds its own time to ``build_time_s``, once."""
    optimizer = _optimizer(tmp_path_factory, max_iterations=1)
    built = optimizer.build_time_s
    assert optimizer.solve().build_time_s == built
    tic = time.perf_counter()
    optimizer.transcribe(pairs=list(optimizer.transcription.pairs))
    took = time.perf_counter() - tic
    assert built < optimizer.build_time_s <= built + took


def test_new_weights_re_solve_the_same_built_problem(tmp_path_factory, squat):
    """A sweep's cell: the squat's optimizer, given the parameters of a lower base height
    reference and a heavier weight on it, re-solves without rebuilding, and the robot goes
    down further."""
    optimizer = _optimizer(tmp_path_factory, max_iterations=200)
    nlps = dict(optimizer._nlps)
    lower = dataclasses.replace(CostWeights(), base_height_m=0.6, base_height=1e4)
    deeper = optimizer.solve(numbers=dataclasses.replace(optimizer.numbers, weights=lower))
    # The same assembled NLP, other numbers (the exact Hessian's flavour of the same
    # structure joins it where the first phase stalls).
    assert {key for key, _ in optimizer._nlps} == {key for key, _ in nlps}
    assert all(optimizer._nlps[k] is nlp for k, nlp in nlps.items())
    assert deeper.success, deeper.status
    assert deeper.q[-1, 2] < squat.q[-1, 2] - 0.02


def test_a_warm_start_from_the_optimum_converges_in_a_few_iterations(tmp_path_factory, squat):
    optimizer = _optimizer(tmp_path_factory, max_iterations=200)
    cold = optimizer.solve()
    warm = optimizer.solve(warm_start=cold)
    assert warm.success, warm.status
    assert 2 * warm.iterations < cold.iterations, (warm.iterations, cold.iterations)
    assert warm.cost == pytest.approx(cold.cost, rel=1e-6)


@pytest.mark.parametrize("first", ["gauss_newton", "projected"])
def test_an_unconverged_solve_goes_on_with_the_exact_hessian(tmp_path_factory, squat, first):
    """Stopped after 5 iterations with the first Hessian, the squat goes on from that point
    with the exact one, within the same iteration budget, to the same optimum. (Switched
    from Gauss-Newton after 3 it ends at another KKT point, cost 6.22 against 5.97: the
    problem is not convex, and the exact Hessian from so early a point takes another
    path.)"""
    limits = {"hessian": first, "max_iterations": 200, "exact_after_iterations": 5}
    traj = _optimizer(tmp_path_factory, **limits).solve()
    assert traj.success, traj.status
    assert 0 < traj.exact_iterations == traj.iterations - 5
    assert traj.cost == pytest.approx(squat.cost, rel=1e-4)
    capped = {"hessian": first, "max_iterations": 5, "exact_after_iterations": 3}
    capped = _optimizer(tmp_path_factory, **capped).solve()
    assert not capped.success and capped.iterations == 5 and capped.exact_iterations == 2


def test_a_stalled_first_phase_goes_on_with_the_exact_hessian_early(tmp_path_factory, squat):
    """With the stall test loose (the objective changing by under 50 % per iteration for
    10 iterations), the projected phase stops as stalled long before its 150 iterations and
    the exact Hessian finishes, at the same optimum; without the test, the squat converges
    in the projected phase alone."""
    limits = {"hessian": "projected", "max_iterations": 200}
    loose = _optimizer(tmp_path_factory, **limits, exact_when_stalled=0.5).solve()
    assert loose.success, loose.status
    first = loose.iterations - loose.exact_iterations
    assert loose.exact_iterations > 0 and 10 <= first < 150, (first, loose.exact_iterations)
    assert loose.cost == pytest.approx(squat.cost, rel=1e-4)
    alone = _optimizer(tmp_path_factory, **limits, exact_when_stalled=None).solve()
    assert alone.success and alone.exact_iterations == 0, (alone.status, alone.exact_iterations)
    assert alone.cost == pytest.approx(squat.cost, rel=1e-4)


def test_a_settled_exact_solve_ends_at_an_acceptable_level(tmp_path_factory, squat):
    """With a tolerance no solve reaches (1e-14), the exact Hessian's solve ends once its
    objective has settled at a feasible point with the barrier at its floor: as
    ``Solved_To_Acceptable_Level``, at the same optimum, sooner than without the stop
    (IPOPT's own acceptable test: 15 iterations at a scaled error under 1e-6)."""
    unreachable = {"hessian": "exact", "max_iterations": 300, "tolerance": 1e-14}
    settled = _optimizer(tmp_path_factory, **unreachable).solve()
    plain = _optimizer(tmp_path_factory, **unreachable, settled_change=None).solve()
    assert settled.status == "Solved_To_Acceptable_Level" and settled.success
    assert settled.iterations < plain.iterations < 300, (settled.iterations, plain.iterations)
    assert settled.cost == pytest.approx(plain.cost, rel=1e-8)
    assert settled.cost == pytest.approx(squat.cost, rel=1e-4)
    assert settled.max_constraint_violation <= 1e-8


def test_second_order_corrections_reach_ipopt_and_keep_the_optimum(tmp_path_factory, squat):
    """IPOPT's ``max_soc`` is the setting's: the squat at the default 0 (16 iterations)
    and at IPOPT's own 4 (27) take other paths to the same optimum."""
    corrected = _optimizer(tmp_path_factory, max_iterations=200, second_order_corrections=4)
    corrected = corrected.solve()
    assert squat.success and corrected.success, corrected.status
    assert squat.iterations != corrected.iterations, squat.iterations
    assert corrected.cost == pytest.approx(squat.cost, rel=1e-6)


def test_mumps_scaling_reaches_ipopt_and_keeps_the_optimum(tmp_path_factory, squat):
    """MUMPS's own scaling of the KKT matrix, off by default (17 iterations), on (16):
    other pivots, another path, the same optimum."""
    scaled = _optimizer(tmp_path_factory, max_iterations=200, mumps_scaling=True).solve()
    assert squat.success and scaled.success, scaled.status
    assert squat.iterations != scaled.iterations, squat.iterations
    assert scaled.cost == pytest.approx(squat.cost, rel=1e-6)


def test_step_count_is_even_and_bounded_by_length_and_turn():
    cfg = ScheduleCfg(step_length_m=0.25, step_yaw_rad=0.45, step_min_m=0.15)
    feet = np.array([[0.0, 0.1], [0.0, -0.1]])
    assert step_count(feet, feet + np.array([0.1, 0.0]), 0.0, 0.0, cfg) == 0
    assert step_count(feet, feet + np.array([0.3, 0.0]), 0.0, 0.0, cfg) == 2
    assert step_count(feet, feet + np.array([0.6, 0.0]), 0.0, 0.0, cfg) == 4
    assert step_count(feet, feet, 0.0, 1.7, cfg) == 4


def test_pick_and_place_phases_hold_the_object_from_grasp_to_set():
    cfg = ScheduleCfg()
    pick = subtask_phases("pick", 1, 0, True, cfg)
    assert [p.name for p in pick] == ["reach", "grasp", "lift"]
    assert [p.keyframe for p in pick] == [False, True, False]
    place = subtask_phases("place", 2, 2, True, cfg)
    assert [p.name for p in place] == [
        "swing_right",
        "stance",
        "swing_left",
        "stance",
        "lower",
        "set",
    ]
    assert all(all(p.hands) for p in place)
    assert [p.object_supported for p in place][-1] and not place[0].object_supported
    with pytest.raises(ConfigError, match="climb"):
        subtask_phases("climb", 0, 0, True, cfg)


def test_a_step_lands_one_foot_then_the_other_on_the_object_and_the_feet_stay_there():
    cfg = ScheduleCfg()
    step = subtask_phases("step", 2, 2, False, cfg)
    assert [p.name for p in step] == [
        "swing_left",
        "stance",
        "swing_right",
        "stance",
        "step_up_left",
        "stance",
        "step_up_right",
        "stance",
    ]
    assert [p.feet_raised for p in step[3:]] == [
        (False, False),
        (True, False),
        (True, False),
        (True, True),
        (True, True),
    ]
    assert step[-1].keyframe and step[-1].stance and not any(p.keyframe for p in step[:-1])
    grab = subtask_phases("grab", 3, 0, True, cfg, raised=True)
    assert [p.name for p in grab] == ["reach", "grasp", "lift"]
    assert all(p.feet_raised == (True, True) for p in grab)
    with pytest.raises(ConfigError, match="no step down"):
        subtask_phases("walk", 4, 2, True, cfg, raised=True)


def test_the_object_is_simulated_from_the_first_touch():
    from locoman.to.problem.schedule import Schedule

    cfg = ScheduleCfg()
    schedule = Schedule.from_phases(subtask_phases("pick", 0, 0, True, cfg))
    inputs = _inputs([Keyframe("pick", g1.standing_q35(), 0, BOX_ON_TABLE)])
    modes = node_modes(inputs, schedule)
    touch = 1 + cfg.reach_nodes
    assert not any(m.objects[0].active for m in modes[:touch])
    assert all(m.objects[0].active for m in modes[touch:])
    assert modes[-1].carried(0) and not modes[touch].carried(0)


def test_a_picked_object_stays_simulated_when_set_on_one_that_joins_later():
    """S2's box: simulated from its pick on; the trolley it is set on (touched by no hand
    yet) joins the simulation when the box lands on it, not the other way round."""
    from locoman.to.problem.schedule import Schedule

    cfg = ScheduleCfg()
    trolley = ObjectModel.box("trolley", np.array([0.8, 0.5, 0.55]), 12.0, 0.5)
    poses = np.array([[2.0, 0.0, 0.7, 0.0, 0.0, 0.0], [2.0, -1.0, 0.0, 0.0, 0.0, 0.0]])
    stand = g1.standing_q35()
    keyframes = [
        Keyframe("pick", stand, 0, poses),
        Keyframe("place", stand, 0, poses, np.array([2.0, -1.0, 0.0]), OnObject(1), 0.55),
    ]
    inputs = TOInputs(
        stand,
        (BOX, trolley),
        poses,
        (Surface(), Chassis()),
        np.array([0.7, 0.0]),
        keyframes,
        np.zeros((2, 2, 3)),
        np.tile(np.eye(3), (2, 2, 1, 1)),
    )
    phases = subtask_phases("pick", 0, 0, True, cfg) + subtask_phases("place", 1, 2, True, cfg)
    modes = node_modes(inputs, Schedule.from_phases(phases))
    touch, landed = 1 + cfg.reach_nodes, len(modes) - cfg.set_nodes
    assert [m.objects[0].active for m in modes] == [k >= touch for k in range(len(modes))]
    assert [m.objects[1].active for m in modes] == [k >= landed for k in range(len(modes))]
    assert modes[landed].objects[0].support == OnObject(1)
    # The trolley on the floor is in the feet's way throughout; the box (on the table,
    # carried, on the trolley) never.
    assert all(m.underfoot == (1,) for m in modes)


def test_cone_violation_is_zero_inside_and_the_excess_outside():
    R, half = np.eye(3), np.array([0.1, 0.05])
    assert cone_violation(np.array([1.0, 2.0, 10.0]), np.zeros(3), R, 0.5, half) == 0.0
    assert cone_violation(np.array([6.0, 0.0, 10.0]), np.zeros(3), R, 0.5, half) == pytest.approx(
        1.0
    )
    assert cone_violation(np.zeros(3), np.array([0.0, 1.5, 0.0]), R, 0.5, half) == pytest.approx(
        1.5
    )


def test_problems_of_another_structure_load_the_same_compiled_terms(tmp_path):
    """Issue 47: the terms are compiled once per robot. The squat, then the squat with
    another contact schedule and collision set (longer stances, no self pairs, the legs'
    pairs as hard constraints), and its keyframe costs switched off: every problem loads
    the libraries the first one built, and compiles nothing."""
    cache = tmp_path / "casadi"
    solver = {"compile": True, "compile_flags": ["-O0"], "print_level": 0}
    first = TrajectoryOptimizer(_squat_inputs(), SolveCfg(solver=SolverCfg(**solver)), cache)
    libraries = sorted(cache.glob("to_*.so"))
    assert len(libraries) == len(first.derivatives)
    other = SolveCfg(
        schedule=ScheduleCfg(double_support_nodes=6),
        collision=CollisionCfg(self_pairs=[], legs_object="constraint"),
        keyframe_base=False,
        solver=SolverCfg(**solver),
    )
    second = TrajectoryOptimizer(_squat_inputs(), other, cache)
    assert sorted(cache.glob("to_*.so")) == libraries
    assert second.nlp.key != first.nlp.key
    assert second.schedule.nodes != first.schedule.nodes
    assert {p.kind for p in second.transcription.pairs} == set(KINDS) - {
        "self_collision",
        "feet_environment",
        "hands_environment",
        "object_environment",
        "object_object",  # off by default
        "feet_object",
        "found",  # pairs found along a solution, none before
        "found_hard",
    }


def test_a_schedule_too_large_is_refused_before_anything_is_built():
    """Issue 53: solve.schedule.swing_nodes=100000 ran 2 min and died with std::bad_alloc."""
    from locoman.config.to import MAX_PHASE_NODES
    from locoman.to.problem.schedule import build_schedule

    errors = dict(ScheduleCfg(swing_nodes=100000).check())
    assert "swing_nodes" in errors and str(MAX_PHASE_NODES) in errors["swing_nodes"]
    far = _squat_inputs()
    far = dataclasses.replace(
        far, keyframes=[Keyframe("walk", np.r_[60.0, g1.standing_q35()[1:]], None, BOX_ON_TABLE)]
    )
    with pytest.raises(ConfigError, match="nodes, more than the TO's"):
        build_schedule(far, ScheduleCfg(step_length_m=0.05, swing_nodes=50))


def test_slack_max_bounds_every_free_slack_and_keeps_the_inactive_ones_at_zero():
    """``contact.slack_max_m``: |s| of (2a), (4) and the hands' contacts within the bound
    where the contact is on; where it is off the slack stays fixed at 0; None: free."""
    from locoman.to.problem.layout import NodeLayout
    from locoman.to.problem.schedule import Schedule
    from locoman.to.solve.bounds import bounds

    cfg = ScheduleCfg()
    schedule = Schedule.from_phases(subtask_phases("pick", 0, 0, True, cfg))
    inputs = _inputs([Keyframe("pick", g1.standing_q35(), 0, BOX_ON_TABLE)])
    modes = node_modes(inputs, schedule)
    layout = NodeLayout.of(1)
    var = layout.variables
    slacks = [var["foot_slack"], var["hand_slack"], layout.object_variables(0, "support_slack")]
    rows = np.concatenate([np.arange(s.start, s.stop) for s in slacks])
    free_lo, free_hi = bounds(layout, inputs, schedule, modes, SolverCfg())
    lo, hi = bounds(layout, inputs, schedule, modes, SolverCfg(), slack_max_m=0.004)
    fixed = free_lo[rows] == free_hi[rows]
    assert fixed.any() and (~fixed).any()
    assert np.all(np.isinf(free_hi[rows][~fixed]))
    assert np.all(hi[rows][~fixed] == 0.004) and np.all(lo[rows][~fixed] == -0.004)
    assert np.all(lo[rows][fixed] == 0.0) and np.all(hi[rows][fixed] == 0.0)
    others = np.setdiff1d(np.arange(layout.width), rows)
    np.testing.assert_array_equal(lo[others], free_lo[others])
    np.testing.assert_array_equal(hi[others], free_hi[others])
