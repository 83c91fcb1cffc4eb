"""The stage functions' constraints: independent where the object starts to move."""

from __future__ import annotations

import casadi as ca
import numpy as np

from locoman.retarget.robot import contact_frames
from locoman.scene import g1
from locoman.to.collision import CollisionCfg
from locoman.to.costs import CostWeights
from locoman.to.kinematics import SymbolicKinematics
from locoman.to.layout import NodeLayout, ObjectModel, object_key
from locoman.to.problem import ContactCfg, NodeMode, ObjectMode, StageBuilder
from locoman.to.supports import Surface

BOX = ObjectModel.box("box", np.array([0.25, 0.3, 0.2]), 2.0, 0.8)
LAYOUT = NodeLayout.of(1)
VARIABLES, PARAMETERS = LAYOUT.variables, LAYOUT.parameters
WIDTH, N_PARAMS = LAYOUT.width, LAYOUT.n_params


def rotation_x(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


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


def test_a_collision_kind_is_a_penalty_or_a_hard_constraint():
    """Switching ``object_body`` from the penalty (12) to the constraint (11) moves its p
    from the cost's residuals into the stage's inequalities p >= 0, one row per residual."""
    kin = SymbolicKinematics(g1.g1_pinocchio_model())
    carried = NodeMode((True, True), (0, 0), (ObjectMode(True, None),))
    shapes = {}
    for treatment in ("off", "penalty", "constraint"):
        cfg = CollisionCfg(
            self_pairs=[], object_body=treatment, hands_environment="off", object_environment="off"
        )
        builder = StageBuilder(kin, (BOX,), contact_frames(), CostWeights(), ContactCfg(), cfg, ())
        group = builder.group(carried, carried, False, np.array([0]))
        inequalities = int(np.count_nonzero(np.isinf(group.upper)))
        shapes[treatment] = (inequalities, int(group.function.size1_out(2)))
    body_spheres = 6  # BODY_POINTS; both palms touch the object
    assert shapes["off"][1] == 0
    assert shapes["penalty"] == (shapes["off"][0], body_spheres)
    assert shapes["constraint"] == (shapes["off"][0] + body_spheres, 0)
