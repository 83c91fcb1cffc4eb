"""Issue 48: the collision pairs a solution needs, found by replaying it in MuJoCo, and the
evaluation's check between nodes. On tiny's scene (a box on a table, a side table)."""

from __future__ import annotations

import dataclasses
from types import SimpleNamespace

import numpy as np
import pytest

from locoman.config.to import CollisionCfg
from locoman.retarget.robot import contact_frames
from locoman.scene import g1
from locoman.scene.io import load_objects, load_scene_model
from locoman.sim.audit import Body, ClosePair, close_pairs, unscheduled_penetrations
from locoman.to.collisions.boxes import box_edge_points, edge_point_counts, edge_points
from locoman.to.collisions.pairs import object_boxes
from locoman.to.problem.objects import ObjectModel, obstacles_from_objects
from locoman.to.rounds.found_pairs import (
    ARM_LINKS,
    FLOOR_BOX,
    PROMOTED,
    WRIST_LINKS,
    Check,
    SolutionScene,
    arm_nodes,
    arm_pairs,
    found_pairs,
    pairs_for,
    promoted_pairs,
    round_pairs,
    unmodelled,
)
from locoman.to.rounds.search import search
from locoman.to.solve.trajectory import Trajectory

NODES = 4
BOX_ON_TABLE = np.array([0.4, 0.0, 0.72, 0.0, 0.0, 0.0])


def _trajectory(
    box_q: np.ndarray,
    support: str = "none",
    q: np.ndarray | None = None,
    feet_contact: np.ndarray | None = None,
) -> dict:
    """The G1 standing still at the origin (both feet on the floor unless ``feet_contact``
    says otherwise), the box at ``box_q`` (N, 6), hands off it."""
    q = np.tile(g1.standing_q35(), (NODES, 1)) if q is None else q
    return {
        "q": q,
        "object_q": box_q[:, None, :],
        "object_names": np.array(["box"]),
        "feet_contact": np.ones((NODES, 2), bool) if feet_contact is None else feet_contact,
        "foot_object": np.full((NODES, 2), -1),
        "hand_object": np.full((NODES, 2), -1),
        "support_kind": np.full((NODES, 1), support),
        "support_base": np.full((NODES, 1), -1),
        "object_active": np.ones((NODES, 1), bool),
    }


@pytest.fixture(scope="module")
def scene(tiny_scene):
    return load_scene_model(tiny_scene), load_objects(tiny_scene)


def test_a_carried_box_through_the_table_is_found_a_resting_one_is_not(scene):
    model, _ = scene
    sunk = np.tile(BOX_ON_TABLE, (NODES, 1))
    sunk[2, 2] -= 0.05  # node 2: 5 cm into the table top
    carried = close_pairs(model, _trajectory(sunk), 0.005, 0)
    pairs = {(c.node, c.a.name, c.b.name) for c in carried} | {
        (c.node, c.b.name, c.a.name) for c in carried
    }
    assert (2, "box", "table") in pairs
    assert min(c.distance for c in carried if c.node == 2) < -0.04
    # Resting on the table (its support), the same pose is the schedule's contact.
    resting = close_pairs(model, _trajectory(sunk, "surface"), 0.005, 0)
    assert not [c for c in resting if "box" in (c.a.name, c.b.name)]


def test_a_foot_on_the_floor_is_allowed_only_while_it_stands(scene):
    """The robot sunk 10 mm into the floor: the soles of standing feet are the schedule's
    contact; the left foot in swing at node 2 is a robot-floor pair there, and only there
    (a pose between node 2 and a standing node is allowed what that node allows)."""
    model, _ = scene
    q = np.tile(g1.standing_q35(), (NODES, 1))
    q[:, 2] -= 0.01
    swing = np.ones((NODES, 2), bool)
    swing[2, 0] = False
    box = np.tile(BOX_ON_TABLE, (NODES, 1))
    standing = close_pairs(model, _trajectory(box, "surface", q), 0.005, 3)
    assert not [c for c in standing if "floor" in (c.a.name, c.b.name)]
    close = close_pairs(model, _trajectory(box, "surface", q, swing), 0.005, 3)
    floor = [c for c in close if "floor" in (c.a.name, c.b.name)]
    assert floor and {(c.node, c.fraction) for c in floor} == {(2, 0.0)}
    assert {c.a.name for c in floor} | {c.b.name for c in floor} == {
        "floor",
        g1.FOOT_LINKS[0],
    }
    assert min(c.distance for c in floor) < -0.005


def test_a_pose_between_two_nodes_is_checked(scene):
    """The box passes through the table's top between nodes 1 and 2 (over it at 1, under
    it at 2): no node shows it, a pose between them does, and so does the evaluation."""
    model, _ = scene
    path = np.tile(BOX_ON_TABLE, (NODES, 1))
    path[:, 2] = [0.9, 0.9, 0.45, 0.45]  # the top is 0.72 m up, 3 cm thick
    path[:, 0] = [0.55, 0.55, 0.55, 0.55]
    nodes_only = close_pairs(model, _trajectory(path), 0.0, 0)
    assert not [c for c in nodes_only if "table" in (c.a.name, c.b.name)]
    between = close_pairs(model, _trajectory(path), 0.0, 3)
    assert {c.node for c in between if "table" in (c.a.name, c.b.name)} == {1}
    deepest, by_body = unscheduled_penetrations(model, _trajectory(path), 3)
    assert deepest > 0.01 and by_body["box"].node == 1 and 0.0 < by_body["box"].fraction < 1.0


def test_the_arm_in_the_torso_is_found_and_mapped_to_sphere_pairs(scene):
    model, _ = scene
    q = np.tile(g1.standing_q35(), (NODES, 1))
    q[1:, 6 + g1.G1_JOINT_NAMES.index("left_shoulder_roll_joint")] = -0.6
    close = close_pairs(
        model, _trajectory(np.tile(BOX_ON_TABLE, (NODES, 1)), "surface", q), 0.005, 0
    )
    self_pairs = [c for c in close if c.a.kind == c.b.kind == "robot"]
    assert self_pairs and all(c.node >= 1 for c in self_pairs)  # node 0 is given
    pair = pairs_for(self_pairs[0], 2, _box_by_the_table(scene))
    assert pair and {p.geometry for p in pair} == {"sphere_sphere"}
    assert all(p.kind == "found" and p.node == 2 for p in pair)


def _box_by_the_table(scene) -> SolutionScene:
    """The scene's box on its table, at every node, with the fixed objects."""
    _, objects = scene
    box = ObjectModel.from_spec("box", objects["box"])
    obstacles = {o.name: o for o in obstacles_from_objects(objects)}
    return SolutionScene((box,), np.tile(BOX_ON_TABLE, (NODES, 1, 1)), obstacles, contact_frames())


KNEE = Body("robot", "left_knee_link", "left_knee_link#7")


def _close(a: Body, b: Body, node: int = 2, fraction: float = 0.0) -> ClosePair:
    return ClosePair(node, fraction, a, b, -0.01, np.array([0.4, 0.0, 0.8]))


def test_a_holding_hands_wrist_against_its_object_may_touch_it(scene):
    """The left hand holds the box at node 2 only: there its wrist's found pairs against
    the box keep it out of the box (touching allowed), not a margin away, which would push
    the palm off the face; at node 1 and for a knee they keep the margin."""
    schedule = _trajectory(np.tile(BOX_ON_TABLE, (NODES, 1)))
    schedule["hand_object"][2, 0] = 0
    scene_ = dataclasses.replace(_box_by_the_table(scene), schedule=schedule)
    box = Body("object", "box", "box/body")
    wrist = Body("robot", "left_wrist_pitch_link", "left_wrist_pitch_link#44")
    held = pairs_for(_close(wrist, box), 2, scene_)
    assert held and all(p.touching for p in held)
    assert not any(p.touching for p in pairs_for(_close(wrist, box), 1, scene_))
    assert not any(p.touching for p in pairs_for(_close(KNEE, box), 2, scene_))
    right = Body("robot", "right_wrist_yaw_link", "right_wrist_yaw_link#62")
    assert not any(p.touching for p in pairs_for(_close(right, box), 2, scene_))


def test_found_pairs_cover_the_nodes_around_once_and_never_the_first(scene):
    scene_ = _box_by_the_table(scene)
    table = Body("fixed", "table", "table/top")
    new = found_pairs(Check([_close(KNEE, table)], scene_), [])
    assert {p.node for p in new} == {1, 2, 3}
    assert {p.geometry for p in new} == {"sphere_fixed_box"}
    assert len(new) == 3 * 6  # six knee spheres at each node
    assert found_pairs(Check([_close(KNEE, table)], scene_), new) == []  # already there
    # Between nodes 0 and 1: at nodes 1 and 2 (node 0 is given), and where along the step.
    first = found_pairs(Check([_close(KNEE, table, node=0, fraction=0.25)], scene_), [])
    assert {p.node for p in first if p.fraction == 0.0} == {1, 2}
    assert {(p.node, p.fraction) for p in first if p.fraction} == {(0, 0.25)}
    assert len(first) == 3 * 6
    floor = found_pairs(Check([_close(KNEE, Body("floor", "floor", "floor"))], scene_), [])
    assert all(p.numbers["centre"][2] == FLOOR_BOX.centre[2] for p in floor)


def test_unmodelled_names_the_close_pairs_whose_pairs_are_missing(scene):
    """The last check's list of close pairs the problem lacks pairs for: those with any
    :func:`found_pairs` (it makes the existing pairs' keys once, not once per close pair)."""
    scene_ = _box_by_the_table(scene)
    table, floor = Body("fixed", "table", "table/top"), Body("floor", "floor", "floor")
    close = [_close(KNEE, table), _close(KNEE, floor), _close(KNEE, table, node=0, fraction=0.5)]
    modelled = found_pairs(Check(close[:1], scene_), [])
    assert unmodelled(Check(close, scene_), []) == close
    assert unmodelled(Check(close, scene_), modelled) == close[1:]
    assert unmodelled(Check(close, scene_), found_pairs(Check(close, scene_), [])) == []
    relabelled = [dataclasses.replace(p, label="elsewhere") for p in modelled]
    assert unmodelled(Check(close, scene_), relabelled) == close[1:]  # a pair is not its label


def test_an_object_against_another_keeps_its_edges_and_the_others_rim_out(scene):
    """A carried box into another object (S2's box into the trolley's platform): points
    along its edges (``spacing_m`` apart) against the other's box, and points along the
    other box's edges against it, so that neither the rim nor a post cuts it between two
    points; each pair once."""
    _, objects = scene
    box = ObjectModel.from_spec("box", objects["box"])
    other = ObjectModel.from_spec("crate", objects["box"] | {"kind": "box"})
    lifted = BOX_ON_TABLE + np.array([0.0, 0.0, 0.15, 0, 0, 0])
    poses = np.tile(np.stack([BOX_ON_TABLE, lifted]), (NODES, 1, 1))
    scene_ = SolutionScene((box, other), poses, {}, contact_frames())
    close = _close(Body("object", "box", "box/body"), Body("object", "crate", "crate/body"))
    pairs = pairs_for(close, 2, scene_)
    assert {p.geometry for p in pairs} == {"object_point_object_box"}
    own = [p for p in pairs if (p.obj, p.box_obj) == (0, 1)]
    rim = [p for p in pairs if (p.obj, p.box_obj) == (1, 0)]
    half = object_boxes(box)[0][1]
    assert len(own) == len(box_edge_points(np.zeros(3), half, scene_.spacing_m)) > 8
    assert len(rim) > 8
    assert len({p.label for p in pairs}) == len(pairs)
    assert len(found_pairs(Check([close], scene_), [])) == 3 * len(pairs)


def test_a_carried_box_against_the_table_or_the_floor_keeps_every_point(scene):
    """A carried box into a fixed table: every point along its edges against the table and
    every point along the table's edges against it, each its own pair (they shared one
    label, and the search kept one of each); against the floor, the box's points alone
    (the floor's edges lie 50 m away)."""
    scene_ = _box_by_the_table(scene)
    (box,), table = scene_.objects, next(iter(scene_.obstacles.values()))
    carried = Body("object", "box", "box/body")
    pairs = found_pairs(
        Check([_close(carried, Body("fixed", table.name, f"{table.name}/top"))], scene_), []
    )
    centre, half = object_boxes(box)[0]
    own = len(box_edge_points(centre, half, scene_.spacing_m))
    spacing = min(scene_.spacing_m, float(min(half)))
    rim = len(edge_points(table, edge_point_counts(table.half_extents, spacing)))
    assert len(pairs) == 3 * (own + rim)  # nodes 1, 2, 3
    floor = found_pairs(Check([_close(carried, Body("floor", "floor", "floor"))], scene_), [])
    assert len(floor) == 3 * own
    assert {p.geometry for p in floor} == {"object_point_fixed_box"}


def test_a_found_pair_still_penetrated_comes_back_hard(scene):
    """The pairs that keep coming back (issue 48): a penetration whose pairs the problem has
    already returns them as ``found_hard``, once; one within the margin only does not."""
    scene_ = _box_by_the_table(scene)
    close = _close(KNEE, Body("fixed", "table", "table/top"))
    assert promoted_pairs(Check([close], scene_), []) == []  # not modelled yet: found first
    found = found_pairs(Check([close], scene_), [])
    hard = promoted_pairs(Check([close], scene_), found)
    assert len(hard) == len(found) and {p.kind for p in hard} == {"found_hard"}
    assert promoted_pairs(Check([close], scene_), found + hard) == []
    near = ClosePair(2, 0.0, close.a, close.b, 0.003, close.point)  # within the margin
    assert promoted_pairs(Check([near], scene_), found) == []


def test_a_rounds_pairs_are_found_then_promoted_once(scene):
    """A check adds the found pairs under ``found``, and those still penetrated a round
    later under ``found_hard``, once; with the two the same, no pair comes twice."""
    scene_ = _box_by_the_table(scene)
    table = _close(KNEE, Body("fixed", "table", "table/top"))
    cfg = CollisionCfg()
    first = round_pairs(Check([table], scene_), [], cfg)
    assert first and {p.kind for p in first} == {"found"}
    again = round_pairs(Check([table], scene_), first, cfg)
    assert len(again) == len(first) and {p.kind for p in again} == {"found_hard"}
    assert round_pairs(Check([table], scene_), first + again, cfg) == []
    same = dataclasses.replace(cfg, found="constraint", found_hard="constraint")
    assert round_pairs(Check([table], scene_), first, same) == []


def test_pairs_with_the_same_label_against_another_box_are_not_the_same(scene):
    """A hand's pairs against a trolley's platform were labelled like those against its
    handle frame (the one box given was ``trolley/0`` either way), so the frame's never
    joined once the platform's had: a pair is its geometry and numbers, not its label."""
    _, objects = scene
    box = ObjectModel.from_spec("box", objects["box"])
    scene_ = SolutionScene((box,), np.tile(BOX_ON_TABLE, (NODES, 1, 1)), {}, contact_frames())
    hand = Body("robot", "right_rubber_hand", "right_rubber_hand#64")
    close = _close(hand, Body("object", "box", "box/body"))
    pairs = found_pairs(Check([close], scene_), [])
    assert pairs and all(p.label.endswith("box/0") for p in pairs)
    elsewhere = [
        dataclasses.replace(p, numbers=p.numbers | {"centre": p.numbers["centre"] + 0.3})
        for p in pairs
    ]
    assert [p.label for p in found_pairs(Check([close], scene_), elsewhere)] == [
        p.label for p in pairs
    ]
    assert found_pairs(Check([close], scene_), pairs) == []


class _Stuck:
    """An optimizer that moves nothing: each solve returns the trajectory it starts from, as
    a solve whose pairs cannot be met within its tolerance would leave it."""

    def __init__(self, guess: Trajectory | None = None) -> None:
        self.transcription = SimpleNamespace(pairs=[])
        self.pairs: list[int] = []
        self.guess = guess
        self.restarts: list[int] = []

    def solve(self, pairs, warm_start=None, hessian=None, label="first solve"):
        self.pairs.append(len(pairs))
        if warm_start is None:  # a restart from the guess
            self.restarts.append(len(pairs))
            return self.guess
        return warm_start


def _solved(arrays: dict) -> Trajectory:
    """A converged trajectory of ``arrays`` (:func:`_trajectory`), every other field empty."""
    empty = {"str": "", "bool": False, "int": 0, "float": 0.0}
    fields = {f.name: empty.get(f.type, np.zeros(0)) for f in dataclasses.fields(Trajectory)}
    given = {k: v for k, v in arrays.items() if k in fields}
    return Trajectory(**fields | given | {"success": True, "status": "Solve_Succeeded"})


def test_a_pair_no_round_frees_ends_the_search_unfreed_naming_it(scene):
    """Issue 48: a carried box 5 cm in the table that no solve moves: the first check adds
    its pairs, the second promotes them, the third adds nothing and returns the pair as
    unfreed (the solve is then recorded as ``Collision_Pairs_Unfreed``)."""
    model, _ = scene
    sunk = np.tile(BOX_ON_TABLE, (NODES, 1))
    sunk[1:, 2] -= 0.05
    scene_ = dataclasses.replace(_box_by_the_table(scene), object_q=sunk[:, None, :])
    stuck = _Stuck()
    cfg = dataclasses.replace(CollisionCfg(), rounds=4, restarts=0)
    found = search(stuck, _solved(_trajectory(sunk)), model, scene_, cfg)
    rounds, missing, unfreed = found.rounds, found.missing, found.unfreed
    assert [r.pairs_added > 0 for r in rounds] == [True, True, False]
    assert len(stuck.pairs) == 2 and stuck.pairs[0] < stuck.pairs[1]
    assert missing == []  # every pair it needs is there
    assert unfreed and all(c.distance < -cfg.unfreed_m for c in unfreed)
    assert {frozenset(c.label.split(" | ")) for c in unfreed} == {
        frozenset({"box/body", "table/top"})
    }


def test_pairs_no_round_frees_are_solved_again_from_the_guess_with_every_pair(scene):
    """Issue 48 (S1's six unfreed grid cells): the rounds leave the box in the table; the
    restart solves from the guess with every pair found (the solve there frees it) and the
    rounds check its solution: no pair missing or unfreed."""
    model, scene_, first = _sunk_box(scene)
    freed = _solved(_trajectory(np.tile(BOX_ON_TABLE, (NODES, 1))))
    solver = _Stuck(guess=freed)
    cfg = dataclasses.replace(CollisionCfg(), rounds=4, restarts=1)
    found = search(solver, first, model, scene_, cfg)
    traj, rounds, missing, unfreed = found.trajectory, found.rounds, found.missing, found.unfreed
    assert solver.restarts == [max(solver.pairs[:-1])]  # once, with every pair found
    assert [r.restart for r in rounds] == [False, False, False, True, False]
    assert traj is not first and traj.success and missing == [] and unfreed == []


def test_restarts_are_bounded_and_a_pair_they_cannot_free_stays_named(scene):
    """A restart that lands in the table again: its rounds run, the search stops after
    ``restarts`` restarts and names the pair unfreed."""
    model, scene_, first = _sunk_box(scene)
    solver = _Stuck(guess=first)
    cfg = dataclasses.replace(CollisionCfg(), rounds=4, restarts=2)
    found = search(solver, first, model, scene_, cfg)
    rounds, unfreed = found.rounds, found.unfreed
    assert len(solver.restarts) == 2 and sum(r.restart for r in rounds) == 2
    assert {frozenset(c.label.split(" | ")) for c in unfreed} == {
        frozenset({"box/body", "table/top"})
    }


class _FailsWith(_Stuck):
    """Moves nothing, like :class:`_Stuck`, and fails each solve that ``fails`` says of its
    pairs, as IPOPT ends in a point of local infeasibility."""

    def __init__(self, fails, status: str = "Infeasible_Problem_Detected") -> None:
        super().__init__()
        self.fails = fails
        self.status = status
        self.kinds: list[set[str]] = []

    def solve(self, pairs, warm_start=None, hessian=None, label="first solve"):
        self.kinds.append({p.kind for p in pairs})
        moved = super().solve(pairs, warm_start, hessian)
        if not self.fails(len(self.pairs), pairs):
            return moved
        return dataclasses.replace(moved, success=False, status=self.status)


def _with_promotions(_calls: int, pairs) -> bool:
    return any(p.kind == PROMOTED for p in pairs)


def _sunk_box(scene):
    model, _ = scene
    sunk = np.tile(BOX_ON_TABLE, (NODES, 1))
    sunk[1:, 2] -= 0.05
    scene_ = dataclasses.replace(_box_by_the_table(scene), object_q=sunk[:, None, :])
    return model, scene_, _solved(_trajectory(sunk))


def test_a_round_that_fails_with_promoted_pairs_is_solved_again_without_them(scene):
    """Issue 48 (S1's two infeasible grid cells): the round that promotes the box's pairs to
    (11) fails; it is solved again without the promotions, which succeeds, and no later
    round promotes: the search ends with the pair unfreed, not from a failed point."""
    model, scene_, first = _sunk_box(scene)
    solver = _FailsWith(_with_promotions)
    cfg = dataclasses.replace(CollisionCfg(), rounds=4, restarts=0)
    found = search(solver, first, model, scene_, cfg)
    traj, rounds, missing, unfreed = found.trajectory, found.rounds, found.missing, found.unfreed
    assert [PROMOTED in kinds for kinds in solver.kinds] == [False, True, False]
    assert solver.pairs[0] == solver.pairs[2] < solver.pairs[1]
    assert [r.demoted > 0 for r in rounds] == [False, True, False]
    assert [r.status for r in rounds[:2]] == ["Solve_Succeeded"] * 2
    assert missing == [] and unfreed
    assert not traj.success and traj.status == "Collision_Pairs_Unfreed"


def test_a_round_out_of_iterations_with_promoted_pairs_is_not_solved_again(scene):
    """Only infeasibility drops the promotions: a round that ran out of iterations (S2's
    NoKeyframe: 1000 more without them) ends the search with its status."""
    model, scene_, first = _sunk_box(scene)
    solver = _FailsWith(_with_promotions, "Maximum_Iterations_Exceeded")
    cfg = dataclasses.replace(CollisionCfg(), rounds=4, restarts=0)
    found = search(solver, first, model, scene_, cfg)
    traj, rounds = found.trajectory, found.rounds
    assert [PROMOTED in kinds for kinds in solver.kinds] == [False, True]
    assert [r.status for r in rounds] == ["Solve_Succeeded", "Maximum_Iterations_Exceeded"]
    assert [r.demoted for r in rounds] == [0, 0]
    assert traj.status == "Maximum_Iterations_Exceeded"


def test_a_round_that_fails_ends_the_search_with_its_failure(scene):
    """With no restart left, a round whose solve fails without promotions to drop is the
    search's result: no check of a failed point, no more rounds."""
    model, scene_, first = _sunk_box(scene)
    solver = _FailsWith(lambda calls, _: calls == 1)
    cfg = dataclasses.replace(CollisionCfg(), rounds=4, restarts=0)
    found = search(solver, first, model, scene_, cfg)
    traj, rounds, missing, unfreed = found.trajectory, found.rounds, found.missing, found.unfreed
    assert len(solver.pairs) == 1 and len(rounds) == 1
    assert not traj.success and traj.status == "Infeasible_Problem_Detected"
    assert rounds[0].status == "Infeasible_Problem_Detected" and rounds[0].demoted == 0
    assert missing == [] and unfreed == []


def test_a_round_that_fails_restarts_from_the_guess_with_every_pair(scene):
    """S2's Fig. 6 Foot at 5 kg, 1.2 rad: the first round runs out of iterations; with a
    restart left, the search solves again from the guess with every pair found, the failed
    round's too, and checks that solution."""
    model, scene_, first = _sunk_box(scene)
    solver = _FailsWith(lambda calls, _: calls == 1, "Maximum_Iterations_Exceeded")
    solver.guess = _solved(_trajectory(np.tile(BOX_ON_TABLE, (NODES, 1))))
    cfg = dataclasses.replace(CollisionCfg(), rounds=4, restarts=1)
    found = search(solver, first, model, scene_, cfg)
    traj, rounds, missing, unfreed = found.trajectory, found.rounds, found.missing, found.unfreed
    assert solver.restarts == solver.pairs[:1]  # the failed round's pairs, all of them
    assert [r.restart for r in rounds] == [False, True, False, False]  # then promotes
    assert [r.status for r in rounds[:3]] == [
        "Maximum_Iterations_Exceeded",
        "Solve_Succeeded",
        "Solve_Succeeded",
    ]
    assert rounds[-1].pairs_added == 0
    assert traj.success and missing == [] and unfreed == []


def test_a_restart_that_fails_ends_the_search_with_its_failure(scene):
    """The restart after a failed round fails too: the search ends with it, no check."""
    model, scene_, first = _sunk_box(scene)
    solver = _FailsWith(lambda calls, _: True, "Maximum_Iterations_Exceeded")
    solver.guess = first
    cfg = dataclasses.replace(CollisionCfg(), rounds=4, restarts=2)
    found = search(solver, first, model, scene_, cfg)
    traj, rounds = found.trajectory, found.rounds
    assert len(solver.restarts) == 1 and [r.restart for r in rounds] == [False, True]
    assert not traj.success and traj.status == "Maximum_Iterations_Exceeded"


def test_no_pair_where_the_schedule_lets_the_bodies_touch(scene):
    """A carried box that grazed the crate it is set on a node later: no pair holds it off
    the crate where it rests on it."""
    _, objects = scene
    box = ObjectModel.from_spec("box", objects["box"])
    other = ObjectModel.from_spec("crate", objects["box"] | {"kind": "box"})
    poses = np.tile(np.stack([BOX_ON_TABLE, BOX_ON_TABLE]), (NODES, 1, 1))
    schedule = _trajectory(poses[:, 0]) | {
        "object_q": poses,
        "object_names": np.array(["box", "crate"]),
        "support_kind": np.array([["none", "surface"]] * 3 + [["on_object", "surface"]]),
        "support_base": np.array([[-1, -1]] * 3 + [[1, -1]]),
        "object_active": np.ones((NODES, 2), bool),
    }
    scene_ = SolutionScene((box, other), poses, {}, contact_frames(), schedule)
    close = _close(Body("object", "box", "box/body"), Body("object", "crate", "crate/body"))
    assert {p.node for p in found_pairs(Check([close], scene_), [])} == {1, 2}  # not 3


def _open_box(scene, hand_object: np.ndarray) -> SolutionScene:
    """tiny's box as an open one of two parts (a floor and a wall) on its table, the left
    hand's contact per node ``hand_object`` (N,), the right hand's none."""
    _, objects = scene
    parts = [
        {"name": "floor", "pos": [0.0, 0.0, 0.01], "shape": "box", "size": [0.1, 0.1, 0.01]},
        {"name": "wall", "pos": [0.09, 0.0, 0.1], "shape": "box", "size": [0.01, 0.1, 0.1]},
    ]
    spec = objects["box"] | {"kind": "basket", "primitives": parts}
    box = ObjectModel.from_spec("box", spec)
    schedule = _trajectory(np.tile(BOX_ON_TABLE, (NODES, 1)))
    schedule["hand_object"][:, 0] = hand_object
    return SolutionScene(
        (box,), np.tile(BOX_ON_TABLE, (NODES, 1, 1)), {}, contact_frames(), schedule
    )


def test_a_restart_keeps_both_arms_out_of_the_object_whole(scene):
    """Issue 48 (S1's AllKeyframe, 2.5 kg, 1.2 rad: the rounds moved a palm from one basket
    wall to the next, then to the shoulder, then to the other arm): at a restart the palm
    found in one part brings every link of both arms against every part, each arm over the
    nodes its hand keeps its contact."""
    scene_ = _open_box(scene, np.array([-1, -1, -1, 0]))  # the left hand holds from node 3
    box = Body("object", "box", "box/wall")
    palm = Body("robot", "right_rubber_hand", "right_rubber_hand#70")
    pairs = arm_pairs([_close(palm, box, node=1)], [], scene_, around=10)
    assert {p.label.split(" | ")[1] for p in pairs} == {"box/0", "box/1"}  # every part
    right = [p for p in pairs if p.sphere.link in ARM_LINKS[1]]
    spheres = {p.sphere.name for p in right}
    assert {s.split("/")[0] for s in spheres} == set(ARM_LINKS[1])  # shoulder to palm
    assert {p.node for p in right} == {1, 2, 3}  # the right hand never holds; never node 0
    assert len(right) == len(spheres) * 2 * 3
    # The left arm up to where its hand takes hold (node 3).
    left = [p for p in pairs if p.sphere.link in ARM_LINKS[0]]
    assert {p.sphere.link for p in left} == set(ARM_LINKS[0]) and {p.node for p in left} == {1, 2}
    assert len(pairs) == len(right) + len(left)
    assert arm_pairs([_close(palm, box, node=1)], pairs, scene_, around=10) == []  # there
    assert {p.node for p in arm_pairs([_close(palm, box, node=1)], [], scene_, 0)} == {1}
    # Over the hold: the left palm may touch the box, its wrist is kept out touching allowed.
    elbow = Body("robot", "left_elbow_link", "left_elbow_link#40")
    held = [
        p
        for p in arm_pairs([_close(elbow, box, node=3)], [], scene_, around=10)
        if p.sphere.link in ARM_LINKS[0]
    ]
    assert {p.node for p in held} == {3}
    assert not any(p.sphere.link == "left_rubber_hand" for p in held)
    assert {p.sphere.link for p in held if p.touching} == set(WRIST_LINKS[0])
    # Not an arm, or not against a body other than the robot: none.
    assert arm_pairs([_close(KNEE, box)], [], scene_, around=10) == []
    assert arm_pairs([_close(palm, KNEE)], [], scene_, around=10) == []


def test_the_arm_nodes_are_the_run_of_the_hands_contact_never_node_0(scene):
    scene_ = _open_box(scene, np.array([-1, 0, 0, -1]))
    assert list(arm_nodes(scene_, 0, 0, 10)) == [1, 2]  # between nodes 0 and 1
    assert list(arm_nodes(scene_, 2, 0, 10)) == [1, 2]
    assert list(arm_nodes(scene_, 2, 0, 0)) == [2]
    assert list(arm_nodes(scene_, 3, 0, 10)) == [3]
    assert list(arm_nodes(scene_, 3, 1, 1)) == [2, 3]  # the right hand: +-1
    free = dataclasses.replace(scene_, schedule=None)
    assert list(arm_nodes(free, 2, 0, 10)) == [1, 2, 3]


class _Kept(_Stuck):
    """Moves nothing (:class:`_Stuck`) and keeps the pairs of each restart."""

    def __init__(self, guess: Trajectory | None = None) -> None:
        super().__init__(guess)
        self.restart_pairs: list[list] = []

    def solve(self, pairs, warm_start=None, hessian=None, label="first solve"):
        if warm_start is None:
            self.restart_pairs.append(list(pairs))
        return super().solve(pairs, warm_start, hessian)


@pytest.mark.parametrize("around", [0, 10])
def test_a_restart_solves_with_the_found_arm_whole(scene, around):
    """The right palm 5 cm in the table, which no solve moves: the restart adds both arms
    whole against the table at every node (``restart_arm_nodes``; 0: none added)."""
    model, _ = scene
    q = np.tile(g1.standing_q35(), (NODES, 1))
    q[1:, 6 + g1.G1_JOINT_NAMES.index("right_shoulder_pitch_joint")] = -0.3
    q[1:, 6 + g1.G1_JOINT_NAMES.index("right_elbow_joint")] = 1.2
    first = _solved(_trajectory(np.tile(BOX_ON_TABLE, (NODES, 1)), "surface", q))
    solver = _Kept(guess=first)
    cfg = dataclasses.replace(CollisionCfg(), rounds=2, restarts=1, restart_arm_nodes=around)
    found = search(solver, first, model, _box_by_the_table(scene), cfg)
    rounds, unfreed = found.rounds, found.unfreed
    restart = next(r for r in rounds if r.restart)
    links = {p.sphere.link for p in solver.restart_pairs[0] if "table" in p.label}
    assert "right_rubber_hand" in links and unfreed
    if around == 0:
        assert restart.pairs_added == 0 and "right_shoulder_pitch_link" not in links
    else:
        assert restart.pairs_added > 0 and links == set(ARM_LINKS[0] + ARM_LINKS[1])
        found = [p for p in solver.restart_pairs[0] if p.sphere.link == "right_shoulder_roll_link"]
        assert {p.node for p in found} == {1, 2, 3}
