"""The TO written as term calls: the physics of the rows (Newton's third law between bodies,
independent equalities where an object starts to move) and which collision pairs exist,
under which treatment, for each contact mode."""

from __future__ import annotations

import dataclasses

import casadi as ca
import numpy as np
import pytest

from locoman.config.to import KINDS, CollisionCfg, ContactCfg, CostWeights
from locoman.errors import SolverBuildError
from locoman.scene import g1
from locoman.to.collisions.pairs import CollisionPair, node_collision_pairs
from locoman.to.collisions.spheres import FOREARM_LINKS, link_sphere_list
from locoman.to.problem.inputs import sole_points
from locoman.to.problem.layout import KINEMATICS, N_KIN, NodeLayout
from locoman.to.problem.modes import NodeMode, ObjectMode
from locoman.to.problem.numbers import Numbers
from locoman.to.problem.objects import ObjectModel, Obstacle
from locoman.to.terms.library import g1_terms
from locoman.to.terms.supports import Chassis, OnObject, Surface
from locoman.to.terms.term import Calls, Rows, term_kind
from locoman.to.transcription.transcribe import Transcription, transcribe

BOX = ObjectModel.box("box", np.array([0.25, 0.3, 0.2]), 2.0, 0.8)
NO_SELF = CollisionCfg(self_pairs=[])


def rotation_x(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _transcription(
    modes: list[NodeMode],
    objects: tuple[ObjectModel, ...],
    collision: CollisionCfg = NO_SELF,
    obstacles: tuple[Obstacle, ...] = (),
    P: np.ndarray | None = None,
) -> Transcription:
    numbers = Numbers(CostWeights(), ContactCfg(), collision, objects, obstacles)
    if P is None:
        P = np.zeros((NodeLayout.of(len(objects)).n_params, len(modes)))
    return transcribe(modes, P, numbers, g1_terms())


def _point(tr: Transcription, nodes: list[dict[str, np.ndarray]]) -> np.ndarray:
    """x with each node's given variables (by layout name), the rest zero."""
    layout = tr.layout
    Z = np.zeros((len(nodes), layout.width))
    for k, values in enumerate(nodes):
        for name, value in values.items():
            Z[k, layout.variables[name]] = value
    return Z.ravel()


def _sole_centre_left() -> np.ndarray:
    """World position of the left sole's centre in the standing posture [m]."""
    K = g1_terms().kinematics.term.function  # rows kin - K(q, v) of x = (q, v, kin)
    rows = np.asarray(K(np.r_[g1.standing_q35(), np.zeros(35), np.zeros(N_KIN)], [])[0])
    return -rows.ravel()[KINEMATICS["left_foot_r"]]


SOLE_CENTRE_LEFT = _sole_centre_left()


def test_the_first_touch_step_has_independent_equalities():
    """At the step where the hands first touch the resting object, its state at k and the
    wrench on it are fixed; the dynamics then fix its state at k + 1, and a support contact
    there as well made the Jacobian rank-deficient (IPOPT regularised every iteration)."""
    at_rest = NodeMode((True, True), (None, None), (ObjectMode(False, Surface()),))
    touched = NodeMode((True, True), (0, 0), (ObjectMode(True, Surface()),))
    P = np.zeros((NodeLayout.of(1).n_params, 2))
    par = NodeLayout.of(1).parameters
    P[par["hand_points"], 1] = [0.0, 0.15, 0.1, 0.0, -0.15, 0.1]
    faces = [rotation_x(-np.pi / 2), rotation_x(np.pi / 2)]  # z: the side faces' normals
    P[par["hand_frames"], 1] = np.concatenate([f.ravel(order="F") for f in faces])
    tr = _transcription([at_rest, touched], (BOX,), P=P)
    z = {
        "q": g1.standing_q35(),
        "object0_q": [0.5, 0.0, 0.4, 0.0, 0.0, 0.0],
        "object0_support_wrench": [0.0, 0.0, BOX.mass * 9.81, 0.0, 0.0, 0.0],
        "dt": 0.05,
    }
    x0 = _point(tr, [z, z])
    lower, upper = tr.rows.bounds()
    rows = np.flatnonzero(lower == upper)
    x = ca.SX.sym("x", len(x0))
    g = _symbolic_rows(tr, _extended(tr, x))[rows.tolist()]
    J = np.asarray(ca.densify(ca.Function("j", [x], [ca.jacobian(g, x)])(x0)))
    layout = tr.layout
    fixed = ["object0_q", "object0_v", "object0_support_wrench", "hand_wrench", "hand_slack"]
    free_node0 = np.setdiff1d(
        np.arange(layout.width),
        np.concatenate([np.arange(layout.width)[layout.variables[n]] for n in fixed]),
    )
    node1 = layout.width + np.arange(layout.width)
    free = np.r_[free_node0, node1]
    singular = np.linalg.svd(J[:, free], compute_uv=False)
    assert singular[-1] > 1e-6 * singular[0]


def _extended(tr: Transcription, x: ca.SX) -> ca.SX:
    """z = (x, y): the virtual variables as expressions of x."""
    y = [ca.SX(0)] * tr.n_y
    for block in tr.blocks:
        if block.defines and block.calls:
            n_in = block.term.nx - block.term.ng
            for xs, ps in zip(block.x, block.p, strict=True):
                inputs = ca.vertcat(x[xs[:n_in].tolist()], ca.SX.zeros(block.term.ng))
                values = -block.term.function(inputs, ps)[0]
                for i, index in enumerate(xs[n_in:] - tr.n_x):
                    y[index] = values[i]
    return ca.vertcat(x, *y)


def _symbolic_rows(tr: Transcription, x: ca.SX) -> ca.SX:
    parts, rows = [], []
    for block in tr.blocks:
        if not block.calls or not block.term.ng or block.defines:
            continue
        X = ca.reshape(x[block.x.ravel().tolist()], block.term.nx, block.calls)
        g = block.term.function.map(block.calls)(X, ca.DM(block.p.T))[0]
        parts.append(ca.vec(g))
        rows.append(block.rows.ravel())
    r = np.concatenate(rows)
    S = np.zeros((tr.rows.size, len(r)))
    S[r, np.arange(len(r))] = 1.0
    return ca.mtimes(ca.DM(S), ca.vertcat(*parts))


def test_a_collision_kind_is_a_penalty_a_hard_constraint_or_a_homotopy():
    """Switching ``object_body`` from the penalty (12) to the constraint (11) moves its p
    from the cost's residuals into the inequalities p >= 0, one row per pair;
    ``legs_object`` as the homotopy (13) adds a row (13a) per pair and the node's alpha
    residual of (13b)."""
    carried = NodeMode((True, True), (0, 0), (ObjectMode(True, None),))
    only = dict.fromkeys(KINDS, "off")
    shapes = {}
    for kind, treatment in (
        ("object_body", "off"),
        ("object_body", "penalty"),
        ("object_body", "constraint"),
        ("legs_object", "homotopy"),
    ):
        cfg = CollisionCfg(self_pairs=[], **(only | {kind: treatment}))
        tr = _transcription([carried], (BOX,), cfg)
        _, upper = tr.rows.bounds()
        inequalities = int(np.count_nonzero(np.isinf(upper)))
        residuals = sum(b.calls * int(b.term.function.size1_out(2)) for b in tr.blocks)
        shapes[treatment] = (inequalities, residuals)
    trunk_spheres = 2  # pelvis, torso; both palms touch the object
    leg_spheres = 2 * (3 + 4 + 6)  # each hip's, thigh's and shin's capsule chain
    assert shapes["off"][1] == 0
    assert shapes["penalty"] == (shapes["off"][0], trunk_spheres)
    assert shapes["constraint"] == (shapes["off"][0] + trunk_spheres, 0)
    assert shapes["homotopy"] == (shapes["off"][0] + leg_spheres, 1)


def _object_rows(tr: Transcription, x: np.ndarray) -> np.ndarray:
    """(objects, 12) each object's (1a), (1b) rows over the first step, with every share."""
    g, _ = tr.values(x)
    return g[tr.rows_of("object_step")]


def test_an_object_resting_on_another_hands_it_its_weight():
    """Newton's third law (6) between two objects: a 5 kg box at rest on a 12 kg trolley at
    rest; the box's support carries 5 kg, the trolley's ground contact both (its centre of
    pressure under their joint CoM), and both bodies' (1) rows vanish. Had the trolley not
    received the box's wrench, its vertical momentum row would miss the box's weight
    impulse."""
    box = ObjectModel.box("box", np.array([0.3, 0.3, 0.2]), 5.0, 0.8)
    trolley = dataclasses.replace(
        ObjectModel.box("trolley", np.array([0.8, 0.5, 0.55]), 12.0, 0.5),
        half_extents=np.array([0.35, 0.2]),
        solid=False,
        rear_axle_x=-0.35,
    )
    mode = NodeMode(
        (True, True), (None, None), (ObjectMode(True, OnObject(1)), ObjectMode(True, Chassis()))
    )
    P = np.zeros((NodeLayout.of(2).n_params, 2))
    P[NodeLayout.of(2).object_parameters(0, "support_z")] = 0.55
    tr = _transcription([mode, mode], (box, trolley), P=P)
    z = {
        "q": g1.standing_q35(),
        "dt": 0.05,
        "object0_q": [0.3, -1.1, 0.55, 0.0, 0.0, 0.0],
        "object1_q": [0.2, -1.1, 0.0, 0.0, 0.0, 0.0],
        "object0_support_wrench": [0.0, 0.0, 5.0 * 9.81, 0.0, 0.0, 0.0],
        # The box presses 0.1 m ahead of the trolley's chassis frame: its CoP moves forward.
        "object1_support_wrench": [0.0, 0.0, 17.0 * 9.81, 0.0, -0.1 * 5.0 * 9.81, 0.0],
    }
    np.testing.assert_allclose(_object_rows(tr, _point(tr, [z, z])), 0.0, atol=1e-9)
    forgotten = z | {"object1_support_wrench": [0.0, 0.0, 12.0 * 9.81, 0.0, -0.49, 0.0]}
    rows = _object_rows(tr, _point(tr, [forgotten, forgotten]))
    assert rows[1, 2] == pytest.approx(5.0 * 9.81 * 0.05)  # h1 - h0 - (net force) dt


def test_a_robot_standing_on_a_box_hands_it_its_weight_and_the_floor_carries_both():
    """(6) between a foot and the object it stands on (S1's step onto the box): the robot
    standing still on a 0.3 m box at rest on the floor; the feet carry the robot, the box's
    floor contact the robot and the box, and the box's (1) rows vanish. Had the box not
    received the feet's wrenches, its vertical momentum row would miss the robot's weight."""
    box = ObjectModel.box("box", np.array([0.4, 0.4, 0.3]), 5.0, 0.8)
    mode = NodeMode((True, True), (None, None), (ObjectMode(True, Surface()),), (0, 0))
    P = np.zeros((NodeLayout.of(1).n_params, 2))
    P[NodeLayout.of(1).parameters["foot_surface_z"]] = 0.3
    tr = _transcription([mode, mode], (box,), P=P)
    q = g1.standing_q35()
    q[2] += 0.3
    robot = g1_terms().mass * 9.81
    feet = sole_points(q)
    # Each foot carries half the robot, at its sole centre; the box's floor wrench, at its
    # bottom centre, carries the robot's and its own weight, with the moment of the feet's
    # forces about that centre.
    box_q = np.r_[feet.mean(axis=0)[:2], 0.0, 0.0, 0.0, 0.0]
    moment = sum(np.cross(f - box_q[:3], [0.0, 0.0, 0.5 * robot]) for f in feet)
    z = {
        "q": q,
        "dt": 0.05,
        "object0_q": box_q,
        "foot_wrench": np.tile([0.0, 0.0, 0.5 * robot, 0.0, 0.0, 0.0], 2),
        "object0_support_wrench": np.r_[0.0, 0.0, robot + 5.0 * 9.81, moment],
    }
    np.testing.assert_allclose(_object_rows(tr, _point(tr, [z, z])), 0.0, atol=1e-6)
    alone = z | {"object0_support_wrench": np.r_[0.0, 0.0, 5.0 * 9.81, 0.0, 0.0, 0.0]}
    rows = _object_rows(tr, _point(tr, [alone, alone]))
    assert rows[0, 2] == pytest.approx(robot * 0.05)  # h1 - h0 - (net force) dt


def test_the_object_mass_enters_its_dynamics():
    """(1a) of a carried box at rest: a box 3 kg heavier, everything else equal, changes
    only its vertical momentum row, by the extra weight's impulse 3 kg * 9.81 m/s^2 * dt;
    the problem's structure is the same (numbers are data)."""
    carry = NodeMode((True, True), (0, 0), (ObjectMode(True, None),))
    light = _transcription([carry, carry], (BOX,))
    heavy = _transcription([carry, carry], (dataclasses.replace(BOX, mass=5.0),))
    from locoman.to.nlp.ipopt import structure_key

    n_x = 2 * light.layout.width
    assert structure_key(n_x, light.blocks) == structure_key(n_x, heavy.blocks)
    z = {"q": g1.standing_q35(), "dt": 0.05, "object0_q": [0.4, 0.0, 0.9, 0.0, 0.0, 0.0]}
    x = _point(light, [z, z])
    difference = _object_rows(heavy, x) - _object_rows(light, x)
    expected = np.zeros_like(difference)
    expected[0, 2] = 3.0 * 9.81 * 0.05
    np.testing.assert_allclose(difference, expected, atol=1e-9)


def _trolley_spec() -> dict:
    """A trolley as ``objects.json`` describes it (the scene's trolley, 0.8 x 0.5 x 0.55 m)."""
    wheels = [
        {"name": f"wheel_{i}", "pos": [x, y, 0.05], "shape": "sphere", "size": [0.05]}
        for i, (x, y) in enumerate([(0.35, 0.2), (0.35, -0.2), (-0.35, 0.2), (-0.35, -0.2)])
    ]
    frame = [
        {
            "name": "post_left",
            "pos": [-0.385, 0.235, 0.75],
            "shape": "box",
            "size": [0.015] * 2 + [0.2],
        },
        {
            "name": "handle",
            "pos": [-0.385, 0.0, 0.95],
            "shape": "box",
            "size": [0.015, 0.25, 0.015],
        },
    ]
    platform = {
        "name": "platform",
        "pos": [0.0, 0.0, 0.54],
        "shape": "box",
        "size": [0.4, 0.25, 0.01],
    }
    return {
        "kind": "trolley",
        "size_m": [0.8, 0.5, 0.55],
        "mass_kg": 12.0,
        "friction": 0.5,
        "primitives": [platform, *wheels, *frame],
    }


def _penalty(tr: Transcription, x: np.ndarray) -> float:
    """The collision penalties' (12) cost at ``x``."""
    _, costs = tr.values(x)
    return sum(cost for name, cost in costs.items() if name.endswith("_penalty"))


def test_the_robot_keeps_out_of_a_trolleys_chassis_and_handle_frame():
    """A trolley is not solid as a whole (the hands reach its platform and handle), but its
    chassis (up to the platform's top) and its handle frame are: the G1's body points pay
    (12) inside either, and nothing 1 m behind the handle."""
    trolley = ObjectModel.from_spec("trolley", _trolley_spec())
    (chassis_c, chassis_h), (frame_c, frame_h) = trolley.parts
    assert np.allclose(chassis_c, [0.0, 0.0, 0.275]) and np.allclose(chassis_h, [0.4, 0.25, 0.275])
    assert frame_c[0] == pytest.approx(-0.385) and frame_c[2] - frame_h[2] == pytest.approx(0.55)
    cfg = CollisionCfg(self_pairs=[], hands_environment="off", object_environment="off")
    mode = NodeMode((True, True), (None, None), (ObjectMode(True, None),))
    tr = _transcription([mode], (trolley,), cfg)

    def penalty(robot_x: float) -> float:
        q = g1.standing_q35()
        q[0] = robot_x
        return _penalty(tr, _point(tr, [{"q": q}]))

    assert penalty(-1.4) < 1e-3
    assert penalty(0.0) > 1e3  # standing in the chassis
    assert penalty(-0.45) > 1.0  # the torso in the handle frame


def test_a_foot_in_a_trolleys_wheel_pays_the_feet_object_penalty_while_it_is_underfoot():
    """S2's left foot went 2.4 cm into a trolley's rear wheel while pushing: a trolley on
    the floor (``NodeMode.underfoot``) keeps the feet out of its wheels under
    ``feet_object``, not out of the space under its platform; the same foot costs nothing
    once the trolley is not underfoot, or when the foot stands on it."""
    trolley = ObjectModel.from_spec("trolley", _trolley_spec())
    rear_left = np.array(trolley.wheels[2][0])
    assert rear_left[0] < 0.0 < rear_left[1] and len(trolley.wheels) == 4
    cfg = CollisionCfg(self_pairs=[], **(dict.fromkeys(KINDS, "off") | {"feet_object": "penalty"}))

    def penalty(xy: np.ndarray, underfoot: tuple[int, ...], feet_on=(None, None)) -> float:
        mode = NodeMode((True, True), (None, None), (ObjectMode(True, None),), feet_on, underfoot)
        tr = _transcription([mode], (trolley,), cfg)
        z = {"q": g1.standing_q35(), "object0_q": [*xy, 0.0, 0.0, 0.0, 0.0]}
        return _penalty(tr, _point(tr, [z]))

    wheel_on_sole = SOLE_CENTRE_LEFT[:2] - rear_left[:2]
    assert penalty(wheel_on_sole, (0,)) > 1.0
    assert penalty(SOLE_CENTRE_LEFT[:2], (0,)) < 1e-3  # under the platform, between wheels
    assert penalty(wheel_on_sole, ()) == 0.0
    assert penalty(wheel_on_sole, (0,), (0, 0)) == 0.0


def test_a_foot_in_a_fixed_obstacle_pays_the_feet_environment_penalty():
    """A table leg (a fixed box) 2 cm off the left foot's toe, then over it: only the latter
    costs (12) under ``feet_environment``; with the kind off, nothing."""
    mode = NodeMode((True, True), (None, None), (ObjectMode(False, Surface()),))

    def penalty(leg_x: float, treatment: str = "penalty") -> float:
        sole = SOLE_CENTRE_LEFT
        leg = Obstacle(
            "table/leg", np.array([leg_x, sole[1], 0.35]), 0.0, np.array([0.03, 0.03, 0.35])
        )
        only = dict.fromkeys(KINDS, "off") | {"feet_environment": treatment}
        tr = _transcription([mode], (BOX,), CollisionCfg(self_pairs=[], **only), (leg,))
        return _penalty(tr, _point(tr, [{"q": g1.standing_q35()}]))

    toe = SOLE_CENTRE_LEFT[0] + 0.09
    assert penalty(toe + 0.03 + 0.03) < 1e-2
    assert penalty(SOLE_CENTRE_LEFT[0]) > 10.0
    assert penalty(SOLE_CENTRE_LEFT[0], "off") == 0.0


def test_a_carried_box_dipped_over_a_tables_rim_pays_the_object_environment_penalty():
    """A box pitched over a table's rim, its corners all clear of the table (the low ones
    off its edge, the high ones over its top), while the rim cuts into its bottom face:
    the rim's points catch it under ``object_environment``; lifted 5 cm, nothing."""
    table = Obstacle("table", np.array([1.0, 0.0, 0.36]), 0.0, np.array([0.3, 0.4, 0.36]))
    cfg = CollisionCfg(
        self_pairs=[], **(dict.fromkeys(KINDS, "off") | {"object_environment": "penalty"})
    )
    carried = NodeMode((True, True), (0, 0), (ObjectMode(True, None),))
    tr = _transcription([carried], (BOX,), cfg, (table,))
    pitch = -0.35  # the +x side (over the table) up

    def penalty(height: float) -> float:
        z = {"q": g1.standing_q35(), "object0_q": [0.68, 0.0, height, 0.0, pitch, 0.0]}
        return _penalty(tr, _point(tr, [z]))

    c, s = np.cos(pitch), np.sin(pitch)
    R = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])
    half = np.r_[BOX.half_extents, BOX.com[2]]
    signs = np.array([(x, y, zz) for x in (-1, 1) for y in (-1, 1) for zz in (0, 2)])
    corners = np.array([0.68, 0.0, 0.695]) + (signs * half) @ R.T
    over_table = corners[:, 0] > 0.7
    assert np.all(corners[over_table, 2] > 0.72 + cfg.margin_m)  # clear of the top
    assert np.all(corners[~over_table, 0] < 0.7 - cfg.margin_m)  # off the edge
    assert penalty(0.695) > 10.0
    assert penalty(0.745) < 1e-3


def test_a_carried_box_pierced_by_the_trolleys_post_pays_the_object_object_penalty():
    """S2's box, carried past the trolley, went 88 mm through its post in the first solve,
    where no pair held it. ``object_object``: the handle frame's vertical edge (the post)
    inside the carried box pays (12); 30 cm further, nothing; a box at rest, and a box
    with the kind off, have no such pairs."""
    trolley = ObjectModel.from_spec("trolley", _trolley_spec())
    frame_c, frame_h = trolley.parts[1]
    post_y = frame_c[1] + frame_h[1]  # the frame's +y vertical edge: the left post
    cfg = CollisionCfg(
        self_pairs=[], **(dict.fromkeys(KINDS, "off") | {"object_object": "penalty"})
    )
    carried = NodeMode((True, True), (0, 0), (ObjectMode(True, None), ObjectMode(True, Surface())))
    tr = _transcription([carried], (BOX, trolley), cfg)
    assert {p.kind for p in tr.pairs} == {"object_object"}
    assert {(p.obj, p.box_obj) for p in tr.pairs} == {(0, 1), (1, 0)}

    def penalty(x: float) -> float:
        box_q = [x, post_y, frame_c[2] - 0.1, 0.0, 0.0, 0.0]  # the post through its middle
        z = {"q": g1.standing_q35(), "object0_q": box_q, "object1_q": np.zeros(6)}
        return _penalty(tr, _point(tr, [z]))

    assert penalty(frame_c[0]) > 10.0
    assert penalty(frame_c[0] + 0.3 + BOX.half_extents[0]) < 1e-3
    at_rest = NodeMode((True, True), (None, None), (ObjectMode(True, Surface()),) * 2)
    assert not _transcription([at_rest], (BOX, trolley), cfg).pairs
    off = dataclasses.replace(cfg, object_object="off")
    assert not _transcription([carried], (BOX, trolley), off).pairs


def test_a_basket_is_open_and_a_hand_holding_it_keeps_its_forearm_out_of_it():
    """S1's right forearm went 5 cm into the held basket's floor: the TO saw a solid box,
    whose holding arm it does not check (the palm is on its face). A basket is its floor
    and walls (``parts``); an arm holding it keeps its forearm out of them, touching
    allowed (with the full margin, the forearm beside the wall its palm presses sat on the
    penalty's boundary); an arm holding a solid box or gripping a trolley's handle is not
    checked; a free one is, with the margin, and out of the basket's bounding box, not only
    its parts (a palm crossed a 20 mm wall between two nodes into its empty inside); a hand
    holding another object keeps out of the parts alone (it may put that object in)."""
    from locoman.retarget.robot import contact_frames
    from locoman.scene.objects import object_geometry

    size = [0.3, 0.4, 0.22]
    geometry = object_geometry("basket", size)
    spec = {
        "kind": "basket",
        "size_m": size,
        "mass_kg": 0.8,
        "friction": 0.8,
        "primitives": [dataclasses.asdict(p) for p in geometry.primitives],
    }
    basket = ObjectModel.from_spec("basket", spec)
    assert not basket.solid and len(basket.parts) == 5
    trolley = ObjectModel.from_spec("trolley", _trolley_spec())
    objects = (basket, BOX, trolley)
    cfg = dataclasses.replace(
        NO_SELF, **(dict.fromkeys(KINDS, "off") | {"hands_object": "penalty"})
    )
    left_arm = {s.name for s in link_sphere_list(FOREARM_LINKS[0])}
    left_arm |= {"left_hand/centre", "left_hand/back", "left_hand/front"}
    at_rest = (ObjectMode(True, Surface()),) * 3

    def pairs(j: int, holding: bool, held: int | None = None) -> list:
        mode = NodeMode((True, True), (j if holding else held, None), at_rest)
        out = node_collision_pairs(0, mode, objects, (), cfg, ContactCfg(), contact_frames())
        return [p for p in out if p.obj == j and p.sphere.name in left_arm]

    forearm = len(link_sphere_list(FOREARM_LINKS[0]))
    assert forearm > 0
    held = pairs(0, holding=True)  # the basket's floor and walls, touching allowed
    assert len(held) == 5 * forearm and all(pair.touching for pair in held)
    assert pairs(1, holding=True) == []  # a solid box: palm on its face
    assert pairs(2, holding=True) == []  # a gripped handle
    free_basket = pairs(0, holding=False)
    assert len(free_basket) == 3 + forearm and not any(p.touching for p in free_basket)
    for pair in free_basket:  # the bounding box, numbered after the parts
        assert pair.label.endswith("basket/5")
        np.testing.assert_allclose(pair.numbers["centre"], [0.0, 0.0, 0.11])
        np.testing.assert_allclose(pair.numbers["half"], [0.15, 0.2, 0.11])
    holding_box = pairs(0, holding=False, held=1)
    assert len(holding_box) == 5 * (3 + forearm) and not any(p.touching for p in holding_box)
    assert len(pairs(1, holding=False)) == 3  # a solid box: the palm, one box


def test_a_pair_between_two_nodes_sees_the_spheres_at_the_configuration_there():
    """Issue 48: the replay between two nodes is linear in q; a pair there takes the link's
    spheres where that configuration puts them (virtual variables of their own), not the
    chord of their centres at the two nodes."""
    from locoman.to.collisions.spheres import link_sphere_list

    knee = link_sphere_list("left_knee_link")[2]
    table = {"centre": np.array([0.6, 0.0, 0.36]), "yaw": 0.0, "half": np.array([0.3, 0.4, 0.36])}
    pair = CollisionPair(0, "found", "sphere_fixed_box", sphere=knee, numbers=table, fraction=0.5)
    mode = NodeMode((True, True), (None, None), (ObjectMode(False, Surface()),))
    tr = transcribe(
        [mode, mode],
        np.zeros((NodeLayout.of(1).n_params, 2)),
        Numbers(CostWeights(), ContactCfg(), NO_SELF, (BOX,), ()),
        g1_terms(),
        [pair],
    )
    q0, q1 = g1.standing_q35(), g1.standing_q35()
    q1[6 + g1.G1_JOINT_NAMES.index("left_knee_joint")] += 1.2
    q1[0] += 0.3
    defined = np.concatenate([b.x[:, -b.term.ng :].ravel() for b in tr.blocks if b.defines])
    assert np.array_equal(np.sort(defined), tr.n_x + np.arange(tr.n_y))  # each once
    z = tr.extended(_point(tr, [{"q": q0}, {"q": q1}]))
    (between,) = [b for b in tr.blocks if b.defines and b.term.name.startswith("spheres_between")]
    centres = z[between.x[0, -between.term.ng :]].reshape(-1, 3)
    spheres = g1_terms().link_spheres["left_knee_link"].term.function
    n_c = between.term.ng
    expected = -np.asarray(spheres(np.r_[0.5 * (q0 + q1), np.zeros(n_c)], [])[0]).reshape(-1, 3)
    np.testing.assert_allclose(centres, expected, atol=1e-12)
    chord = 0.5 * (
        -np.asarray(spheres(np.r_[q0, np.zeros(n_c)], [])[0]).reshape(-1, 3)
        - np.asarray(spheres(np.r_[q1, np.zeros(n_c)], [])[0]).reshape(-1, 3)
    )
    assert np.abs(centres - chord).max() > 0.005  # the arc, not the chord


@pytest.mark.parametrize("slack_max_m", [0.004, None])
def test_a_landing_sole_sinks_no_deeper_than_the_slack_bound(slack_max_m):
    """issue 48: with (2a)'s slack bounded, r_dot_z / k_z still let a sole sit 7 mm in the box
    it stepped on; a foot that lands at node k + 1 gets r_z - z_g + d_max >= 0, d_max the
    slack bound (none where the slack is free); a held one does not."""
    swing = NodeMode((False, True), (None, None), ())
    standing = NodeMode((True, True), (None, None), ())
    numbers = Numbers(CostWeights(), ContactCfg(slack_max_m=slack_max_m), NO_SELF, (), ())
    layout = NodeLayout.of(0)
    P = np.zeros((layout.n_params, 4))
    P[layout.parameters["foot_surface_z"], :] = 0.3  # on a step 30 cm high
    tr = transcribe([standing, swing, standing, standing], P, numbers, g1_terms())
    blocks = [b for b in tr.blocks if b.term.name == "sole_depth"]
    if slack_max_m is None:
        assert not blocks
        return
    (block,) = blocks
    assert block.calls == 1  # the left foot landing at node 2
    np.testing.assert_allclose(block.p, [[0.3, 0.004]])
    depth = block.term.function
    for z, inside in ((0.3 - 0.007, False), (0.3 - 0.003, True), (0.31, True)):
        value = float(depth([0.0, 0.0, z], [0.3, 0.004])[0])
        assert (value >= 0.0) == inside


def _same_problem(a: Transcription, b: Transcription) -> None:
    assert [(x.term.name, x.defines) for x in a.blocks] == [
        (y.term.name, y.defines) for y in b.blocks
    ]
    for x, y in zip(a.blocks, b.blocks, strict=True):
        for field in ("x", "p", "rows"):
            np.testing.assert_array_equal(getattr(x, field), getattr(y, field))
    assert (a.n_y, a.rows.size) == (b.n_y, b.rows.size)
    for u, v in zip(a.rows.bounds(), b.rows.bounds(), strict=True):
        np.testing.assert_array_equal(u, v)


def test_a_round_of_found_pairs_reuses_the_earlier_pairs_calls_and_builds_the_same_problem():
    """Pairs that extend an earlier transcription's (a round's found pairs) reuse its pair
    calls; the problem is the one a transcription from scratch builds, new kinds (a pair
    promoted to (11), one between two nodes) and the rows included. Other pairs (one left
    out) or other numbers are transcribed from scratch."""
    table = {"centre": np.array([0.6, 0.0, 0.36]), "yaw": 0.0, "half": np.array([0.3, 0.4, 0.36])}
    knee, elbow = link_sphere_list("left_knee_link")[2], link_sphere_list("right_elbow_link")[0]
    carried = NodeMode((True, True), (0, 0), (ObjectMode(True, None),))
    modes = [carried] * 3
    numbers = Numbers(CostWeights(), ContactCfg(), CollisionCfg(), (BOX,), ())
    P = np.zeros((NodeLayout.of(1).n_params, len(modes)))
    first = transcribe(modes, P, numbers, g1_terms())
    found = [
        dataclasses.replace(first.pairs[-1], node=0),  # a kind the first pairs have
        CollisionPair(1, "found", "sphere_fixed_box", sphere=knee, numbers=table),
        CollisionPair(0, "found", "sphere_fixed_box", sphere=knee, numbers=table, fraction=0.5),
        CollisionPair(2, "found_hard", "sphere_fixed_box", sphere=elbow, numbers=table),
    ]
    for pairs in ([*first.pairs, *found], [*first.pairs[1:], *found]):
        again = transcribe(modes, P, numbers, g1_terms(), pairs, previous=first)
        _same_problem(again, transcribe(modes, P, numbers, g1_terms(), pairs))
    assert first.pair_calls.starts([*first.pairs, *found], first.pair_calls.context)
    assert not first.pair_calls.starts([*first.pairs[1:], *found], first.pair_calls.context)
    heavier = dataclasses.replace(numbers, weights=CostWeights(collision=2.0))
    pairs = [*first.pairs, *found]
    again = transcribe(modes, P, heavier, g1_terms(), pairs, previous=first)
    _same_problem(again, transcribe(modes, P, heavier, g1_terms(), pairs))


def test_calls_added_as_columns_stack_after_those_added_one_by_one():
    kind = term_kind(
        "scaled", {"a": 2, "b": 1}, {"w": 1, "m": 4}, lambda x, p: Rows(cost=p["w"] * x["b"])
    )
    matrix = np.arange(4.0).reshape(2, 2)
    one_by_one, columns = Calls(kind), Calls(kind)
    for i in range(3):
        one_by_one.add({"a": [i, i + 1], "b": 7}, {"w": 0.5 * i, "m": matrix + i})
    one_by_one.add({"a": [9, 8], "b": 1}, {"w": 2.0, "m": matrix})
    columns.add({"a": [0, 1], "b": 7}, {"w": 0.0, "m": matrix})
    columns.add_columns(
        2,
        {"a": np.array([[1, 2], [2, 3]]), "b": [7, 7]},
        {"w": [0.5, 1.0], "m": np.stack([matrix + 1, matrix + 2])},
    )
    columns.add({"a": [9, 8], "b": 1}, {"w": 2.0, "m": matrix})
    for got, want in zip(columns.arrays(), one_by_one.arrays(), strict=True):
        assert got.dtype == want.dtype
        np.testing.assert_array_equal(got, want)
    with pytest.raises(SolverBuildError, match="slot 'b' has values for 1 calls, not 2"):
        columns.add_columns(2, {"a": [[1, 2], [3, 4]], "b": [7]}, {"w": [1, 2], "m": [matrix] * 2})
    with pytest.raises(SolverBuildError, match=r"p slots missing \['m'\]"):
        columns.add_columns(1, {"a": [[1, 2]], "b": [7]}, {"w": [1]})
