"""Collision terms (paper A, Sec. IV-D): the scaled penetration (11), its penalty (12), the
G1's collision spheres and the scene's obstacles."""

from __future__ import annotations

import casadi as ca
import mujoco
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from locoman.config.to import KINDS, CollisionCfg, ContactCfg, CostWeights
from locoman.retarget.robot import contact_frames
from locoman.scene import g1
from locoman.scene.rotations import rpy_to_matrix
from locoman.to.collisions.boxes import box_corners, box_edge_points, edge_point_counts, edge_points
from locoman.to.collisions.spheres import link_spheres
from locoman.to.problem.layout import NodeLayout
from locoman.to.problem.modes import NodeMode
from locoman.to.problem.numbers import Numbers
from locoman.to.problem.objects import Obstacle, obstacles_from_objects
from locoman.to.terms.collisions import (
    box_clearance,
    collision_kind,
    homotopy_weight_kind,
    penetration_residual,
    sphere_box_penetration,
    sphere_sphere_penetration,
)
from locoman.to.terms.library import g1_terms
from locoman.to.transcription.transcribe import transcribe

HALF = np.array([0.3, 0.2, 0.05])
CFG = CollisionCfg()
_x, _c = ca.SX.sym("x", 3), ca.SX.sym("c", 3)
_R = ca.SX.sym("R", 3, 3)
CLEARANCE = ca.Function("c", [_x, _c, _R], [box_clearance(_x, _c, _R, HALF, CFG.smoothing_m)])
coordinate = st.floats(-1.0, 1.0)


def _yawed(yaw: float) -> np.ndarray:
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _signed_distance(local: np.ndarray) -> float:
    """Exact signed distance of a point from the box (frame-local coordinates) [m]."""
    excess = np.abs(local) - HALF
    outside = np.linalg.norm(np.maximum(excess, 0.0))
    return float(outside if outside > 0.0 else excess.max())


@settings(max_examples=80, deadline=None)
@given(st.tuples(coordinate, coordinate, coordinate), st.floats(-3.0, 3.0))
def test_box_clearance_is_the_face_distance_up_to_its_smoothing(local, yaw):
    R, centre = _yawed(yaw), np.array([0.5, -1.0, 0.7])
    local = np.array(local)
    c = float(CLEARANCE(centre + R @ local, centre, R))
    face = float(np.max(np.abs(local) - HALF))
    assert face - 1e-9 <= c <= face + CFG.smoothing_m * np.log(3.0) + 1e-3
    # Never more than the true distance plus the smoothing: p >= 0 keeps a sphere out.
    assert c <= _signed_distance(local) + CFG.smoothing_m * np.log(3.0) + 1e-3


@settings(max_examples=60, deadline=None)
@given(st.tuples(coordinate, coordinate, coordinate), st.floats(0.0, 0.1))
def test_a_sphere_with_nonnegative_penetration_is_outside_the_box(local, radius):
    local = np.array(local)
    p = ca.Function(
        "p", [_x], [sphere_box_penetration(_x, radius, ca.DM.zeros(3), ca.DM.eye(3), HALF, CFG)]
    )
    if float(p(local)) >= 0.0:
        assert _signed_distance(local) >= radius
    if _signed_distance(local) < radius - 1e-3:
        assert float(p(local)) < 0.0


@settings(max_examples=60, deadline=None)
@given(st.tuples(coordinate, coordinate, coordinate), st.floats(0.0, 0.1))
def test_a_touching_pair_keeps_the_sphere_out_with_the_least_margin(local, radius):
    """A holding forearm against its basket (``touching``): the margin is ln(3) times the
    smoothing, the least that still keeps the sphere out of the box (up to the 1 mm of
    |x|'s smoothing), and p is the full margin's shifted by the difference."""
    local = np.array(local)
    frame = (ca.DM.zeros(3), ca.DM.eye(3), ca.DM(HALF))
    least = np.log(3.0) * CFG.smoothing_m
    touching = sphere_box_penetration(ca.DM(local), radius, *frame, CFG, least)
    full = sphere_box_penetration(ca.DM(local), radius, *frame, CFG)
    assert float(touching - full) == pytest.approx((CFG.margin_m - least) / CFG.length_m)
    if float(touching) >= 0.0:
        assert _signed_distance(local) >= radius - 1e-3


def test_two_spheres_follow_the_papers_scaled_penetration():
    a, b = np.zeros(3), np.array([0.3, 0.0, 0.4])
    p = sphere_sphere_penetration(ca.DM(a), ca.DM(b), 0.25, 0.1)
    assert float(p) == pytest.approx((0.5 - 0.25) / 0.1, abs=1e-5)


def test_a_deep_sphere_pair_keeps_its_push():
    """(12)'s gradient keeps its size however deep two spheres are: the paper's d^2 - 1
    loses it as the centres meet (a wrist stayed 123 mm in the torso)."""
    a, b = ca.SX.sym("a", 3), ca.DM([0.0, 0.0, 0.0])
    grad = ca.Function("g", [a], [ca.gradient(sphere_sphere_penetration(a, b, 0.25, 0.1), a)])
    for depth in (0.2, 0.1, 0.02):
        norm = float(ca.norm_2(grad(ca.DM([0.25 - depth, 0.0, 0.0]))))
        assert norm == pytest.approx(1.0 / 0.1, rel=1e-3)


@given(st.floats(-2.0, 2.0))
def test_the_penalty_is_the_square_of_the_smoothed_penetration(value):
    """r = min(p, 0) within softness ln 2, and r' = sigmoid(-p / softness): continuous
    (smooth) across p = 0, where the paper's form jumps in curvature."""
    soft = 0.01
    p = ca.SX.sym("p")
    r = penetration_residual(p, soft)
    fn = ca.Function("r", [p], [r, ca.jacobian(r, p)])
    residual, slope = (float(x) for x in fn(value))
    assert min(value, 0.0) - soft * np.log(2.0) - 1e-12 <= residual <= min(value, 0.0)
    assert slope == pytest.approx(1.0 / (1.0 + np.exp(value / soft)), abs=1e-9)


def test_the_penalty_is_the_papers_away_from_contact():
    p = ca.SX.sym("p")
    penalty = ca.Function("l", [p], [penetration_residual(p, 0.01) ** 2])
    assert float(penalty(-0.3)) == pytest.approx(0.09, rel=1e-6)
    assert float(penalty(0.4)) < 1e-30


def test_box_corners_span_the_box_from_its_bottom_face():
    corners = np.array([np.asarray(c).ravel() for c in box_corners(HALF)])
    assert corners.shape == (8, 3)
    assert np.allclose(corners.min(axis=0), [-0.3, -0.2, 0.0])
    assert np.allclose(corners.max(axis=0), [0.3, 0.2, 0.1])


def test_link_spheres_cover_the_capsule_axis_ends():
    model = g1.g1_mjmodel()
    for link in ("torso_link", "left_knee_link", "right_rubber_hand"):
        spheres = link_spheres(link)
        geom = next(
            g
            for g in range(model.ngeom)
            if model.body(model.geom_bodyid[g]).name == link
            and model.geom_group[g] == g1.COLLISION_GROUP
        )
        rot = np.zeros(9)
        mujoco.mju_quat2Mat(rot, model.geom_quat[geom])
        ends = [
            model.geom_pos[geom] + s * model.geom_size[geom][1] * rot.reshape(3, 3)[:, 2]
            for s in (-1, 1)
        ]
        for end in ends:
            assert min(np.linalg.norm(s.centre - end) for s in spheres) < 1e-9
        gaps = np.linalg.norm(np.diff([s.centre for s in spheres], axis=0), axis=1)
        assert np.all(gaps <= spheres[0].radius + 1e-9)


def _mujoco_self_contacts(q35: np.ndarray) -> set[frozenset[str]]:
    model = g1.g1_mjmodel()
    data = mujoco.MjData(model)
    data.qpos[:] = g1.pin_to_mujoco_qpos(g1.q35_to_pin(q35), model, data.qpos)
    mujoco.mj_forward(model, data)
    name = lambda geom: model.body(model.geom_bodyid[geom]).name  # noqa: E731
    return {
        frozenset((name(c.geom1), name(c.geom2)))
        for c in data.contact[: data.ncon]
        if c.dist < 0.0 and "floor" not in (model.geom(c.geom1).name, model.geom(c.geom2).name)
    }


@pytest.mark.parametrize("roll", [-0.2, -0.6])
def test_self_collision_penalises_what_mujoco_finds_in_collision(roll):
    """Standing, neither MuJoCo nor the penalty finds a collision; with the left arm swung
    into the torso both do."""
    only_self = dict.fromkeys(KINDS, "off") | {"self_collision": "penalty"}
    numbers = Numbers(CostWeights(), ContactCfg(), CollisionCfg(**only_self), (), ())
    mode = NodeMode((True, True), (None, None), ())
    tr = transcribe([mode, mode], np.zeros((NodeLayout.of(0).n_params, 2)), numbers, g1_terms())

    def cost(q35: np.ndarray) -> float:
        x = np.zeros(tr.n_x)
        for k in range(2):
            x[k * tr.layout.width + np.arange(35)] = q35
        _, costs = tr.values(x)
        return costs["sphere_sphere_penalty"]

    standing = g1.standing_q35()
    pairs = len(tr.pairs)
    # (softness ln 2)^2 per pair at most, near contact, at the weight of the configuration
    assert cost(standing) < 1e-4 * CostWeights().collision * pairs
    assert not _mujoco_self_contacts(standing)
    hugging = standing.copy()
    hugging[6 + g1.G1_JOINT_NAMES.index("left_shoulder_roll_joint")] = roll
    assert frozenset(("left_shoulder_yaw_link", "torso_link")) in _mujoco_self_contacts(hugging)
    assert cost(hugging) > CostWeights().collision


def test_an_obstacle_is_the_bounding_box_of_a_fixed_object_in_the_world():
    top = {"name": "top", "shape": "box", "pos": [0.1, 0.0, 0.7], "size": [0.3, 0.2, 0.01]}
    leg = {"name": "leg", "shape": "box", "pos": [0.35, 0.15, 0.35], "size": [0.03, 0.03, 0.35]}
    objects = {
        "table": {
            "movable": False,
            "pos_m": [1.0, 2.0, 0.0],
            "yaw_rad": np.pi / 2,
            "primitives": [top, leg],
        },
        "box": {"movable": True, "pos_m": [0, 0, 0], "yaw_rad": 0.0, "primitives": []},
    }
    (table,) = obstacles_from_objects(objects)
    assert table.name == "table"
    assert np.allclose(table.half_extents, [0.3, 0.2, 0.355])
    # Centre (0.1, 0, 0.355) in the table frame, turned by 90 degrees.
    assert np.allclose(table.centre, [1.0, 2.1, 0.355])
    assert np.allclose(table.rotation @ [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    objects["table"]["primitives"][0]["shape"] = "cylinder"
    with pytest.raises(ValueError, match="knows boxes"):
        obstacles_from_objects(objects)


def test_config_check_names_what_is_wrong():
    assert CollisionCfg().check() == []
    errors = dict(CollisionCfg(self_pairs=[["pelvis", "nose"]], smoothing_m=0.02).check())
    assert "nose" in errors["self_pairs"]
    assert "ln(3)" in errors["margin_m"]
    errors = dict(CollisionCfg(knee_collision="homotopy", legs_object="homotopy").check())
    assert "use constraint" in errors["knee_collision"] and "legs_object" not in errors


def test_palm_frames_are_square_to_the_hand_capsule():
    frames = contact_frames()
    for name, axes in frames.palm_axes.items():
        assert np.allclose(axes.T @ axes, np.eye(3), atol=1e-12)
        assert np.linalg.det(axes) == pytest.approx(1.0)
        # The palm faces away from the body: -y of the left hand link, +y of the right.
        side = -1.0 if name.startswith("left") else 1.0
        assert side * axes[1, 2] > 0.9


def test_box_edge_points_cover_all_twelve_edges_once_at_most_the_spacing_apart():
    centre, half = np.array([0.1, -0.2, 0.1]), np.array([0.15, 0.15, 0.1])
    points = box_edge_points(centre, half, 0.04)
    local = points - centre
    on_face = np.isclose(np.abs(local), half)
    assert np.all(on_face.sum(axis=1) >= 2)  # on an edge
    assert len(np.unique(np.round(points, 9), axis=0)) == len(points)  # each once
    assert on_face.all(axis=1).sum() == 8  # the corners
    # 9 points along each x and y edge (0.3 m at <= 0.04 m), 6 along each z edge (0.2 m).
    assert len(points) == 8 + 4 * 7 + 4 * 7 + 4 * 4
    for axis in range(3):
        along = local[on_face.sum(axis=1) >= 2]
        edge = along[np.isclose(local[:, (axis + 1) % 3], half[(axis + 1) % 3])]
        edge = edge[np.isclose(edge[:, (axis + 2) % 3], half[(axis + 2) % 3])]
        assert np.diff(np.sort(edge[:, axis])).max() <= 0.04 + 1e-12


def _signed_box_distance(points: np.ndarray, centre: np.ndarray, half: np.ndarray) -> np.ndarray:
    """Exact signed distance of points from an axis-aligned box [m] (negative inside)."""
    gap = np.abs(points - centre) - half
    outside = np.linalg.norm(np.maximum(gap, 0.0), axis=1)
    return np.where(gap.max(axis=1) > 0.0, outside, gap.max(axis=1))


def test_a_tilted_box_cutting_a_post_between_its_corners_is_caught_by_its_edge_points():
    """S2, AllKeyframe at 7.5 kg and 1.2 rad, node 78 (issue 48): the carried box, tilted
    (roll 0.47, pitch 0.34 rad), cuts the trolley's 30-mm handle frame between its corners.
    Its corners and the frame's edge points (spaced by the box's smallest half size) all
    stay out, so the found pairs could not free it; points along the box's edges 40 mm
    apart go inside."""
    half = np.array([0.15, 0.15, 0.1])  # the box; its frame at its bottom face
    centre = np.array([0.0, 0.0, 0.1])
    frame_centre, frame_half = np.array([-0.385, 0.0, 0.758]), np.array([0.015, 0.25, 0.208])
    p, R = np.array([-0.2604, 0.0425, 0.6926]), rpy_to_matrix(np.array([0.4657, 0.3443, -2.2167]))

    def in_frame(local: np.ndarray) -> np.ndarray:  # box points -> the frame's clearance
        return _signed_box_distance(p + local @ R.T, frame_centre, frame_half)

    corners = centre + np.array(box_corners(half)) - np.array([0.0, 0.0, half[2]])
    assert in_frame(corners).min() > 0.005
    rim = Obstacle("frame", frame_centre, 0.0, frame_half)
    rim_points = edge_points(rim, edge_point_counts(frame_half, float(min(half))))
    assert _signed_box_distance((rim_points - p) @ R, centre, half).min() > 0.005
    assert in_frame(box_edge_points(centre, half, 0.04)).min() < -0.01


def test_edge_points_run_along_every_vertical_and_top_edge_at_most_the_spacing_apart():
    table = Obstacle("t", np.array([1.0, 0.0, 0.36]), 0.3, np.array([0.3, 0.4, 0.36]))
    counts = edge_point_counts(table.half_extents, 0.1)
    points = np.array([np.asarray(p).ravel() for p in edge_points(table, counts)])
    local = (points - table.centre) @ table.rotation
    # Every point is on an edge: on two of the box's faces.
    on_face = np.isclose(np.abs(local), table.half_extents)
    assert np.all(on_face.sum(axis=1) >= 2)
    for x in (-0.3, 0.3):
        for y in (-0.4, 0.4):
            z = np.sort(local[np.isclose(local[:, 0], x) & np.isclose(local[:, 1], y), 2])
            assert z[0] == pytest.approx(-0.36) and z[-1] == pytest.approx(0.36)
            assert np.diff(z).max() <= 0.1 + 1e-12
    top = np.isclose(local[:, 2], 0.36)
    for axis, other, half in ((0, 1, 0.4), (1, 0, 0.3)):
        for side in (-half, half):
            run = np.sort(local[top & np.isclose(local[:, other], side), axis])
            assert run[0] == pytest.approx(-table.half_extents[axis])
            assert run[-1] == pytest.approx(table.half_extents[axis])
            assert np.diff(run).max() <= 0.1 + 1e-12
    # No point twice (the top corners belong to the vertical edges), none on the floor
    # but the vertical edges' ends.
    assert len(np.unique(np.round(local, 9), axis=0)) == len(local)
    assert np.sum(np.isclose(local[:, 2], -0.36)) == 4


@pytest.mark.parametrize("treatment", ["penalty", "constraint", "homotopy"])
def test_the_hard_constraint_keeps_a_body_out_where_the_penalty_lets_it_in(treatment):
    """A single-body toy: a ball (radius 5 cm) crosses a box-shaped obstacle from one side
    to the other with least acceleration, its path started straight through the box. With
    (11) as a constraint every node keeps the margin (p >= 0); a weak penalty (12) trades
    penetration for acceleration and lets the ball in. The homotopy (13) starts at the
    box's inscribed ellipsoid (alpha = 1 at every node) and ends at the true box: alpha
    at zero, p >= 0 to 0.1 mm, and the ball as close to the box as (11) lets it."""
    nodes, radius = 21, 0.05
    x = ca.SX.sym("x", 3, nodes)
    alpha = ca.SX.sym("alpha", nodes)
    term = collision_kind("sphere_fixed_box", treatment).term.function
    box = {"radius": radius, "centre": [0.0, 0.0, 0.0], "yaw": 0.0, "half": [0.1] * 3}
    box |= {"margin": CFG.margin_m, "smoothing": CFG.smoothing_m, "length": CFG.length_m}
    if treatment == "penalty":
        box |= {"weight": 1e-2, "softness": CFG.softness}
    if treatment == "homotopy":
        box |= {"stand_in_margin": CFG.margin_m}
    p = np.concatenate([np.atleast_1d(v) for v in box.values()])
    rows, residuals = [], []
    for k in range(nodes):
        inputs = ca.vertcat(x[:, k], alpha[k]) if treatment == "homotopy" else x[:, k]
        g_k, _, r_k = term(inputs, p)
        rows.append(g_k)
        residuals.append(r_k)
        if treatment == "homotopy":
            residuals.append(homotopy_weight_kind().term.function(alpha[k], 2e2)[2])
    acceleration = x[:, 2:] - 2 * x[:, 1:-1] + x[:, :-2]
    cost = 1e3 * ca.sumsqr(acceleration) + ca.sumsqr(ca.vertcat(*residuals))
    ends = ca.vertcat(x[:, 0] - [-0.5, 0.0, 0.0], x[:, -1] - [0.5, 0.0, 0.0])
    g = ca.vertcat(ends, *rows)
    solver = ca.nlpsol(
        "toy",
        "ipopt",
        {"x": ca.vertcat(ca.vec(x), alpha), "f": cost, "g": g},
        {"print_time": False, "ipopt": {"print_level": 0, "sb": "yes"}},
    )
    start = np.c_[np.linspace(-0.5, 0.5, nodes), np.full(nodes, 0.01), np.zeros(nodes)].T
    homotopy = treatment == "homotopy"
    n_rows = g.numel()
    true_box = ca.Function(
        "p",
        [x],
        [
            ca.vertcat(
                *[
                    sphere_box_penetration(x[:, k], radius, ca.DM.zeros(3), ca.DM.eye(3), 0.1, CFG)
                    for k in range(nodes)
                ]
            )
        ],
    )

    def solve(alpha_low: float, alpha_high: float) -> tuple[np.ndarray, np.ndarray]:
        """Each node's alpha and p of the true box, alpha within bounds."""
        out = solver(
            x0=np.r_[start.ravel(order="F"), np.full(nodes, alpha_high)],
            lbx=np.r_[np.full(3 * nodes, -np.inf), np.full(nodes, alpha_low)],
            ubx=np.r_[np.full(3 * nodes, np.inf), np.full(nodes, alpha_high)],
            lbg=np.zeros(n_rows),
            ubg=np.r_[np.zeros(6), np.full(n_rows - 6, np.inf)],
        )
        assert solver.stats()["success"]
        solution = np.asarray(out["x"]).ravel()
        path = solution[: 3 * nodes].reshape(3, nodes, order="F")
        return solution[3 * nodes :], np.asarray(true_box(path)).ravel()

    alpha, p = solve(0.0, 1.0 if homotopy else 0.0)
    if treatment == "penalty":
        assert p.min() < -0.1  # more than a centimetre inside, with L = 0.1 m
        assert n_rows == 6
    else:
        # (13) ends near, not at, alpha = 0 (w_hom trades it against the path), so the
        # true box holds to alpha (p~ - p): here 0.03 mm.
        assert p.min() >= (-1e-3 if homotopy else -1e-6)
        assert p.min() < 0.05  # within 5 mm of the margin: the true box shapes the path
    if treatment == "constraint":
        assert ca.vertcat(*residuals).numel() == 0
    if homotopy:
        assert alpha.max() < 1e-3
        # The stand-in alone (alpha held at 1), an ellipsoid inscribed in the box, lets the
        # ball cut the box's edges: it guides, the box decides.
        _, p_stand_in = solve(1.0, 1.0)
        assert p_stand_in.min() < -0.05  # 5 mm into the box


def test_a_pair_between_two_nodes_is_the_pair_at_its_fraction_along_the_step():
    """Between two nodes a carried box's corner can pass through a thin post that both
    nodes keep it out of: a term between nodes takes an object's pose at (1 - t) x_k +
    t x_{k+1} (a robot sphere's centre comes at the configuration there, as given)."""
    post = {"point": [0.1, 0.0, 0.0], "centre": [0.0, 0.0, 0.5], "yaw": 0.3}
    post |= {"half": [0.02, 0.02, 0.5], "margin": 0.01, "smoothing": 0.004, "length": 0.1}
    p = np.concatenate([np.atleast_1d(v) for v in post.values()])
    at_node = collision_kind("object_point_fixed_box", "constraint").term.function
    between = collision_kind("object_point_fixed_box", "constraint", between=True).term.function
    before, after = np.array([-0.3, 0.01, 0.6, 0, 0, 0]), np.array([0.1, -0.01, 0.6, 0, 0, 0])
    assert float(at_node(before, p)[0]) > 0.0 and float(at_node(after, p)[0]) > 0.0
    for t in (0.25, 0.5):
        value = float(between(np.r_[before, after], np.r_[p, t])[0])
        assert value == pytest.approx(float(at_node((1 - t) * before + t * after, p)[0]))
    assert float(between(np.r_[before, after], np.r_[p, 0.5])[0]) < 0.0  # through the post
    sphere = collision_kind("sphere_fixed_box", "constraint", between=True)
    assert set(sphere.x_slots) == {"c"}  # the robot's sphere comes at the fraction
