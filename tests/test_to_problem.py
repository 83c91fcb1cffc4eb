"""The stage functions' constraints: independent where the object starts to move."""

from __future__ import annotations

import dataclasses

import casadi as ca
import numpy as np
import pytest

from locoman.retarget.robot import contact_frames
from locoman.scene import g1
from locoman.to.collision import KINDS, CollisionCfg
from locoman.to.costs import CostWeights
from locoman.to.kinematics import SymbolicKinematics
from locoman.to.layout import NodeLayout, ObjectModel, object_key
from locoman.to.problem import ContactCfg, NodeMode, ObjectMode, StageBuilder
from locoman.to.supports import Surface
from locoman.to.trajopt import sole_points

BOX = ObjectModel.box("box", np.array([0.25, 0.3, 0.2]), 2.0, 0.8)
LAYOUT = NodeLayout.of(1)
VARIABLES, PARAMETERS = LAYOUT.variables, LAYOUT.parameters
WIDTH, N_PARAMS = LAYOUT.width, LAYOUT.n_params


def rotation_x(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _left_sole_centre() -> np.ndarray:
    """World position of the left sole's centre in the standing posture [m]."""
    kin = SymbolicKinematics(g1.g1_pinocchio_model())
    builder = StageBuilder(
        kin, (BOX,), contact_frames(), CostWeights(), ContactCfg(), CollisionCfg(self_pairs=[]), ()
    )
    values = np.asarray(builder.kinematics(g1.standing_q35(), np.zeros(35))).ravel()
    from locoman.to.layout import KINEMATICS

    return values[KINEMATICS["left_foot_r"]]


SOLE_CENTRE_LEFT = _left_sole_centre()


FIXED_WHILE_AT_REST = (
    object_key(0, "q"),
    object_key(0, "v"),
    object_key(0, "support_wrench"),
    "hand_wrench",
    "hand_slack",
)


def test_the_first_touch_stage_has_independent_equalities():
    """At the stage where the hands first touch the resting object, its state at k and the
    wrench on it are fixed; the dynamics then fix its state at k + 1, and a support contact
    there as well made the Jacobian rank-deficient (IPOPT regularised every iteration)."""
    kin = SymbolicKinematics(g1.g1_pinocchio_model())
    builder = StageBuilder(
        kin, (BOX,), contact_frames(), CostWeights(), ContactCfg(), CollisionCfg(self_pairs=[]), ()
    )
    at_rest = NodeMode((True, True), (None, None), (ObjectMode(False, Surface()),))
    touched = NodeMode((True, True), (0, 0), (ObjectMode(True, Surface()),))
    fn = builder.group(at_rest, touched, False, np.array([0])).function
    rows = int(np.count_nonzero(builder.group(at_rest, touched, False, [0]).upper == 0.0))

    z = np.zeros(WIDTH)
    q = g1.standing_q35()
    z[VARIABLES["q"]] = q
    z[VARIABLES["kin"]] = np.asarray(builder.kinematics(q, np.zeros(35))).ravel()
    z[VARIABLES[object_key(0, "q")]] = [0.5, 0.0, 0.4, 0.0, 0.0, 0.0]
    z[VARIABLES[object_key(0, "support_wrench")]][2] = BOX.mass * 9.81
    z[VARIABLES["dt"]] = 0.05
    zs, z1s = ca.SX.sym("z", WIDTH), ca.SX.sym("z1", WIDTH)
    p = np.zeros(N_PARAMS)
    p[PARAMETERS["hand_points"]] = [0.0, 0.15, 0.1, 0.0, -0.15, 0.1]
    faces = [rotation_x(-np.pi / 2), rotation_x(np.pi / 2)]  # z: the side faces' normals
    p[PARAMETERS["hand_frames"]] = np.concatenate([f.ravel(order="F") for f in faces])
    g = fn(zs, z1s, p, p, builder.parameters.vector())[0][:rows]
    jac = ca.Function("j", [zs, z1s], [ca.jacobian(g, ca.vertcat(zs, z1s))])
    J = np.asarray(ca.densify(jac(z, z)))
    fixed = np.concatenate([np.arange(WIDTH)[VARIABLES[name]] for name in FIXED_WHILE_AT_REST])
    free = np.setdiff1d(np.arange(2 * WIDTH), fixed)
    singular = np.linalg.svd(J[:, free], compute_uv=False)
    assert singular[-1] > 1e-6 * singular[0]


def test_a_collision_kind_is_a_penalty_a_hard_constraint_or_a_homotopy():
    """Switching ``object_body`` from the penalty (12) to the constraint (11) moves its p
    from the cost's residuals into the stage's inequalities p >= 0, one row per residual;
    ``legs_object`` as the homotopy (13) adds a row (13a) per pair and one residual, the
    node's alpha of (13b)."""
    kin = SymbolicKinematics(g1.g1_pinocchio_model())
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
        builder = StageBuilder(kin, (BOX,), contact_frames(), CostWeights(), ContactCfg(), cfg, ())
        group = builder.group(carried, carried, False, np.array([0]))
        inequalities = int(np.count_nonzero(np.isinf(group.upper)))
        shapes[treatment] = (inequalities, int(group.function.size1_out(2)))
    trunk_spheres = 2  # pelvis, torso; both palms touch the object
    leg_spheres = 2 * (3 + 4 + 6)  # each hip's, thigh's and shin's capsule chain
    assert shapes["off"][1] == 0
    assert shapes["penalty"] == (shapes["off"][0], trunk_spheres)
    assert shapes["constraint"] == (shapes["off"][0] + trunk_spheres, 0)
    assert shapes["homotopy"] == (shapes["off"][0] + leg_spheres, 1)


def test_an_object_resting_on_another_hands_it_its_weight():
    """Newton's third law (6) between two objects in the stage functions: a 5 kg box at
    rest on a 12 kg trolley at rest; the box's support carries 5 kg, the trolley's ground
    contact both (its centre of pressure under their joint CoM), and both bodies' (1) rows
    vanish. Had the trolley not received the box's
    wrench, its vertical momentum row would miss the box's weight impulse."""
    from locoman.to.supports import Chassis, OnObject

    box = ObjectModel.box("box", np.array([0.3, 0.3, 0.2]), 5.0, 0.8)
    trolley = dataclasses.replace(
        ObjectModel.box("trolley", np.array([0.8, 0.5, 0.55]), 12.0, 0.5),
        half_extents=np.array([0.35, 0.2]),
        solid=False,
        rear_axle_x=-0.35,
    )
    kin = SymbolicKinematics(g1.g1_pinocchio_model())
    cfg = CollisionCfg(self_pairs=[])
    builder = StageBuilder(
        kin, (box, trolley), contact_frames(), CostWeights(), ContactCfg(), cfg, ()
    )
    layout = NodeLayout.of(2)
    mode = NodeMode(
        (True, True), (None, None), (ObjectMode(True, OnObject(1)), ObjectMode(True, Chassis()))
    )
    fn = builder.group(mode, mode, False, np.array([0])).function
    z = np.zeros(layout.width)
    q = g1.standing_q35()
    z[layout.variables["q"]] = q
    z[layout.variables["kin"]] = np.asarray(builder.kinematics(q, np.zeros(35))).ravel()
    z[layout.variables["dt"]] = 0.05
    z[layout.object_variables(0, "q")] = [0.3, -1.1, 0.55, 0.0, 0.0, 0.0]
    z[layout.object_variables(1, "q")] = [0.2, -1.1, 0.0, 0.0, 0.0, 0.0]
    z[layout.object_variables(0, "support_wrench")][2] = 5.0 * 9.81
    # The box presses 0.1 m ahead of the trolley's chassis frame: its CoP moves forward.
    z[layout.object_variables(1, "support_wrench")][[2, 4]] = [17.0 * 9.81, -0.1 * 5.0 * 9.81]
    p = np.zeros(layout.n_params)
    p[layout.object_parameters(0, "support_z")] = 0.55
    theta = builder.parameters.vector()

    def object_rows(z_k):
        g = np.asarray(fn(z_k, z_k, p, p, theta)[0]).ravel()
        return g[6 + 35 : 6 + 35 + 24]  # after the robot's (1a), (1b): box, then trolley

    np.testing.assert_allclose(object_rows(z), 0.0, atol=1e-9)
    forgotten = z.copy()
    forgotten[layout.object_variables(1, "support_wrench")][2] = 12.0 * 9.81
    rows = object_rows(forgotten)
    assert rows[12 + 2] == pytest.approx(5.0 * 9.81 * 0.05)  # h1 - h0 - (net force) dt


def test_a_robot_standing_on_a_box_hands_it_its_weight_and_the_floor_carries_both():
    """(6) between a foot and the object it stands on (S1's step onto the box): the robot
    standing still on a 0.3 m box at rest on the floor; the feet carry the robot, the box's
    floor contact the robot and the box, and the box's (1) rows vanish. Had the box not
    received the feet's wrenches, its vertical momentum row would miss the robot's weight."""
    box = ObjectModel.box("box", np.array([0.4, 0.4, 0.3]), 5.0, 0.8)
    kin = SymbolicKinematics(g1.g1_pinocchio_model())
    builder = StageBuilder(
        kin, (box,), contact_frames(), CostWeights(), ContactCfg(), CollisionCfg(self_pairs=[]), ()
    )
    layout = NodeLayout.of(1)
    mode = NodeMode((True, True), (None, None), (ObjectMode(True, Surface()),), (0, 0))
    fn = builder.group(mode, mode, False, np.array([0])).function
    z = np.zeros(layout.width)
    q = g1.standing_q35()
    q[2] += 0.3
    z[layout.variables["q"]] = q
    z[layout.variables["kin"]] = np.asarray(builder.kinematics(q, np.zeros(35))).ravel()
    z[layout.variables["dt"]] = 0.05
    robot = float(kin.mass) * 9.81
    feet = sole_points(q)
    # Each foot carries half the robot, at its sole centre; the box's floor wrench, at its
    # bottom centre, carries the robot's and its own weight, with the moment of the feet's
    # forces about that centre.
    box_q = np.r_[feet.mean(axis=0)[:2], 0.0, 0.0, 0.0, 0.0]
    z[layout.object_variables(0, "q")] = box_q
    wrench = z[layout.variables["foot_wrench"]].reshape(2, 6)
    wrench[:, 2] = 0.5 * robot
    z[layout.variables["foot_wrench"]] = wrench.ravel()
    moment = sum(np.cross(f - box_q[:3], [0.0, 0.0, 0.5 * robot]) for f in feet)
    z[layout.object_variables(0, "support_wrench")] = np.r_[0.0, 0.0, robot + 5.0 * 9.81, moment]
    p = np.zeros(layout.n_params)
    p[layout.parameters["foot_surface_z"]] = 0.3
    theta = builder.parameters.vector()

    def box_rows(z_k):
        g = np.asarray(fn(z_k, z_k, p, p, theta)[0]).ravel()
        return g[6 + 35 : 6 + 35 + 12]  # after the robot's (1a), (1b)

    np.testing.assert_allclose(box_rows(z), 0.0, atol=1e-6)
    alone = z.copy()
    alone[layout.object_variables(0, "support_wrench")] = np.r_[0.0, 0.0, 5.0 * 9.81, 0, 0, 0]
    assert box_rows(alone)[2] == pytest.approx(robot * 0.05)  # h1 - h0 - (net force) dt


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


def test_the_robot_keeps_out_of_a_trolleys_chassis_and_handle_frame():
    """A trolley is not solid as a whole (the hands reach its platform and handle), but its
    chassis (up to the platform's top) and its handle frame are: the G1's body points pay
    (12) inside either, and nothing 1 m behind the handle."""
    trolley = ObjectModel.from_spec("trolley", _trolley_spec())
    (chassis_c, chassis_h), (frame_c, frame_h) = trolley.parts
    assert np.allclose(chassis_c, [0.0, 0.0, 0.275]) and np.allclose(chassis_h, [0.4, 0.25, 0.275])
    assert frame_c[0] == pytest.approx(-0.385) and frame_c[2] - frame_h[2] == pytest.approx(0.55)
    kin = SymbolicKinematics(g1.g1_pinocchio_model())
    cfg = CollisionCfg(self_pairs=[], hands_environment="off", object_environment="off")
    builder = StageBuilder(kin, (trolley,), contact_frames(), CostWeights(), ContactCfg(), cfg, ())
    mode = NodeMode((True, True), (None, None), (ObjectMode(True, None),))
    z = ca.SX.sym("z", WIDTH)
    residuals = ca.Function(
        "r",
        [z, builder.theta],
        [
            builder.collision_terms(z, mode).residuals(
                builder.collision.softness, builder.w.collision
            )
        ],
    )

    def penalty(robot_x: float) -> float:
        q = g1.standing_q35()
        q[0] = robot_x
        zn = np.zeros(WIDTH)
        zn[VARIABLES["q"]] = q
        zn[VARIABLES["kin"]] = np.asarray(builder.kinematics(q, np.zeros(35))).ravel()
        zn[VARIABLES[object_key(0, "q")]] = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
        return float(ca.sumsqr(residuals(zn, builder.parameters.vector())))

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
    kin = SymbolicKinematics(g1.g1_pinocchio_model())
    only = dict.fromkeys(KINDS, "off") | {"feet_object": "penalty"}
    builder = StageBuilder(
        kin,
        (trolley,),
        contact_frames(),
        CostWeights(),
        ContactCfg(),
        CollisionCfg(self_pairs=[], **only),
        (),
    )
    q = g1.standing_q35()
    zn = np.zeros(WIDTH)
    zn[VARIABLES["q"]] = q
    zn[VARIABLES["kin"]] = np.asarray(builder.kinematics(q, np.zeros(35))).ravel()

    def penalty(xy: np.ndarray, underfoot: tuple[int, ...], feet_on=(None, None)) -> float:
        mode = NodeMode((True, True), (None, None), (ObjectMode(True, None),), feet_on, underfoot)
        z = ca.SX.sym("z", WIDTH)
        r = builder.collision_terms(z, mode).residuals(
            builder.collision.softness, builder.w.collision
        )
        fn = ca.Function("r", [z, builder.theta], [ca.sumsqr(r)])
        z_k = zn.copy()
        z_k[VARIABLES[object_key(0, "q")]] = [*xy, 0.0, 0.0, 0.0, 0.0]
        return float(fn(z_k, builder.parameters.vector()))

    wheel_on_sole = SOLE_CENTRE_LEFT[:2] - rear_left[:2]
    assert penalty(wheel_on_sole, (0,)) > 1.0
    assert penalty(SOLE_CENTRE_LEFT[:2], (0,)) < 1e-3  # under the platform, between wheels
    assert penalty(wheel_on_sole, ()) == 0.0
    assert penalty(wheel_on_sole, (0,), (0, 0)) == 0.0


def test_a_foot_in_a_fixed_obstacle_pays_the_feet_environment_penalty():
    """A table leg (a fixed box) 2 cm off the left foot's toe, then over it: only the latter
    costs (12) under ``feet_environment``; with the kind off, nothing."""
    from locoman.to.collision import Obstacle

    kin = SymbolicKinematics(g1.g1_pinocchio_model())
    q = g1.standing_q35()
    mode = NodeMode((True, True), (None, None), (ObjectMode(False, Surface()),))

    def penalty(leg_x: float, treatment: str = "penalty") -> float:
        sole = SOLE_CENTRE_LEFT
        leg = Obstacle(
            "table/leg", np.array([leg_x, sole[1], 0.35]), 0.0, np.array([0.03, 0.03, 0.35])
        )
        only = dict.fromkeys(KINDS, "off") | {"feet_environment": treatment}
        cfg = CollisionCfg(self_pairs=[], **only)
        builder = StageBuilder(
            kin, (BOX,), contact_frames(), CostWeights(), ContactCfg(), cfg, (leg,)
        )
        z = ca.SX.sym("z", WIDTH)
        r = builder.collision_terms(z, mode).residuals(
            builder.collision.softness, builder.w.collision
        )
        zn = np.zeros(WIDTH)
        zn[VARIABLES["q"]] = q
        zn[VARIABLES["kin"]] = np.asarray(builder.kinematics(q, np.zeros(35))).ravel()
        fn = ca.Function("r", [z, builder.theta], [ca.sumsqr(r)])
        return float(fn(zn, builder.parameters.vector()))

    toe = SOLE_CENTRE_LEFT[0] + 0.09
    assert penalty(toe + 0.03 + 0.03) < 1e-2
    assert penalty(SOLE_CENTRE_LEFT[0]) > 10.0
    assert penalty(SOLE_CENTRE_LEFT[0], "off") == 0.0


def test_a_carried_box_dipped_over_a_tables_rim_pays_the_object_environment_penalty():
    """A box pitched over a table's rim, its corners all clear of the table (the low ones
    off its edge, the high ones over its top), while the rim cuts into its bottom face:
    the rim's points catch it under ``object_environment``; lifted 5 cm, nothing."""
    from locoman.to.collision import Obstacle

    table = Obstacle("table", np.array([1.0, 0.0, 0.36]), 0.0, np.array([0.3, 0.4, 0.36]))
    cfg = CollisionCfg(
        self_pairs=[], **(dict.fromkeys(KINDS, "off") | {"object_environment": "penalty"})
    )
    kin = SymbolicKinematics(g1.g1_pinocchio_model())
    builder = StageBuilder(
        kin, (BOX,), contact_frames(), CostWeights(), ContactCfg(), cfg, (table,)
    )
    carried = NodeMode((True, True), (0, 0), (ObjectMode(True, None),))
    z = ca.SX.sym("z", WIDTH)
    r = builder.collision_terms(z, carried).residuals(
        builder.collision.softness, builder.w.collision
    )
    fn = ca.Function("r", [z, builder.theta], [ca.sumsqr(r)])
    pitch = -0.35  # the +x side (over the table) up

    def penalty(height: float) -> float:
        zn = np.zeros(WIDTH)
        zn[VARIABLES["q"]] = g1.standing_q35()
        zn[VARIABLES[object_key(0, "q")]] = [0.68, 0.0, height, 0.0, pitch, 0.0]
        return float(fn(zn, builder.parameters.vector()))

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


def test_a_basket_is_open_and_a_hand_holding_it_keeps_its_forearm_out_of_it():
    """S1's right forearm went 5 cm into the held basket's floor: the TO saw a solid box,
    whose holding arm it does not check (the palm is on its face). A basket is its floor
    and walls (``parts``); an arm holding it keeps its forearm out of them, touching
    allowed (with the full margin, the forearm beside the wall its palm presses sat on the
    penalty's boundary); an arm holding a solid box or gripping a trolley's handle is not
    checked; a free one is, with the margin."""
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
    kin = SymbolicKinematics(g1.g1_pinocchio_model())
    builder = StageBuilder(
        kin,
        (basket, BOX, trolley),
        contact_frames(),
        CostWeights(),
        ContactCfg(),
        CollisionCfg(self_pairs=[]),
        (),
    )
    z = ca.SX.sym("z", NodeLayout.of(3).width)
    forearm = len(builder._forearm(z, 0))
    palm = [ca.SX.zeros(3)] * 3
    at_rest = (ObjectMode(True, Surface()),) * 3

    def mode(j: int, holding: bool) -> NodeMode:
        return NodeMode((True, True), (j if holding else None, None), at_rest)

    def checked(j: int, holding: bool) -> int:
        return len(builder._arm_spheres(z, mode(j, holding), 0, j, palm))

    def held_pairs(j: int) -> list:
        parts = builder._object_parts(z, j, builder.objects[j].parts)
        return builder._holding_forearms(z, mode(j, holding=True), j, parts)

    assert forearm > 0
    basket_pairs = held_pairs(0)  # the basket's floor and walls, touching allowed
    assert len(basket_pairs) == 5 * forearm and all(pair.touching for pair in basket_pairs)
    assert checked(0, holding=True) == 0
    assert checked(1, holding=True) == 0 and held_pairs(1) == []  # a solid box: palm on its face
    assert checked(2, holding=True) == 0 and held_pairs(2) == []  # a gripped handle
    assert checked(0, holding=False) == 3 + forearm and checked(1, holding=False) == 3
