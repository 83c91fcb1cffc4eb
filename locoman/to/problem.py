"""The stage functions of paper A's whole-body TO (Sec. IV): one per pair of contact modes.

The robot's kinematics (momentum, CoM, sole and palm frames) are lifted into variables
tied to q, v by one node function (:func:`kinematics_function`), the same at every node; the
stage functions then only combine them. A stage k couples nodes k and k + 1
(:mod:`locoman.to.nlp`). Its constraints are

- the centroidal dynamics (1a), (1b) of the robot, with the wrenches of node k's contacts;
- the same dynamics for the object once a hand has touched it (before, it rests where the
  scene put it and its variables are fixed);
- the contact constraints of node k + 1: patch contact (2a)-(2c) of each foot on the ground,
  the interactive contact (4), (5a), (5b) of each hand on the object, patch contact of the
  object on its support; (2d) only where the contact starts at k + 1 (elsewhere (2c) at
  both nodes with (1b) already fixes those rates, and imposing both makes the constraint
  Jacobian singular); after the first node of a hand contact, (5b) keeps only the rate about
  the contact normal, for the same reason;
- the friction cone and CoP (3) of node k's non-prehensile contacts.

Newton's third law (6) holds by construction: the object receives minus each hand's wrench,
at the same point. The cost is node k's (8): L_st or L_wk by the mode, L_reg, L_slack, the
keyframe costs (9), (10) where the parameters switch them on, and the object goal, with the
collision penalties (12) as residuals (:mod:`locoman.to.nlp` takes their Hessian as
Gauss-Newton); the last stage adds node N - 1's.
"""

from __future__ import annotations

import dataclasses

import casadi as ca
import numpy as np

from locoman.retarget.robot import ContactFrames
from locoman.scene import g1
from locoman.to.collision import (
    CollisionCfg,
    CollisionTerms,
    Obstacle,
    box_corners,
    edge_point_count,
    self_collision_penetrations,
    sphere_box_penetration,
    vertical_edge_points,
)
from locoman.to.contacts import (
    friction_cone_cop,
    interactive_contact,
    no_rolling,
    patch_contact,
)
from locoman.to.costs import (
    CostWeights,
    keyframe_base_cost,
    keyframe_foot_cost,
    object_goal_cost,
    regularization_cost,
    stance_cost,
    walking_cost,
)
from locoman.to.dynamics import rigid_body_momentum, wrench_sum
from locoman.to.kinematics import SymbolicKinematics, euler_rates_to_world, rpy_matrix
from locoman.to.layout import (
    BODY_POINTS,
    FEET,
    HANDS,
    KINEMATICS,
    N_PARAMS,
    PARAMETERS,
    VARIABLES,
    WIDTH,
    ObjectModel,
)
from locoman.to.nlp import StageGroup
from locoman.to.parameters import GlobalParameters, SymbolicGlobals


@dataclasses.dataclass(frozen=True)
class NodeMode:
    """Which contacts hold at one node.

    Attributes:
        feet: (left, right) foot on the ground.
        hands: (left, right) hand on the object.
        object_active: The object is simulated (a hand has touched it).
        object_supported: The object rests on a support.
    """

    feet: tuple[bool, bool]
    hands: tuple[bool, bool]
    object_active: bool
    object_supported: bool

    @property
    def stance(self) -> bool:
        return all(self.feet)

    @property
    def carried(self) -> bool:
        return any(self.hands) and not self.object_supported


@dataclasses.dataclass
class ContactCfg:
    """Contact parameters of the TO.

    Attributes:
        floor_friction: mu of the feet on the ground [-].
        stiffness: k_z of (2a) [1/s].
        prehensile: Hands grasp the object: (3) is dropped for them (paper A, Sec. IV-A.2).
        palm_half_extents_m: Half sizes of a palm's patch for the CoP of (3b) [m].
    """

    floor_friction: float = 0.8
    stiffness: float = 50.0
    prehensile: bool = False
    palm_half_extents_m: list[float] = dataclasses.field(default_factory=lambda: [0.04, 0.03])

    def check(self) -> list[tuple[str, str]]:
        errors = []
        if self.floor_friction <= 0.0 or self.stiffness <= 0.0:
            errors.append(("stiffness", "friction and stiffness must be > 0"))
        if len(self.palm_half_extents_m) != 2 or min(self.palm_half_extents_m) <= 0.0:
            errors.append(("palm_half_extents_m", "needs two half sizes > 0 m"))
        return errors


def _var(z: ca.SX, name: str) -> ca.SX:
    return z[VARIABLES[name]]


def _kin(z: ca.SX, name: str) -> ca.SX:
    """A lifted kinematic quantity; rotations come back as (3, 3)."""
    value = _var(z, "kin")[KINEMATICS[name]]
    return ca.reshape(value, 3, 3) if name.endswith("_R") else value


def kinematics_function(kin: SymbolicKinematics, frames: ContactFrames) -> ca.Function:
    """K(q, v): the lifted kinematic quantities in :data:`KINEMATICS` order. A palm's
    contact frame is ``frames.palm_axes``: (5a) lays the palm's capsule flat on the face."""
    q, v = kin.q, kin.v
    parts = {"h": kin.centroidal_momentum(), "com": kin.com()}
    palms = [frames.palm[f"{side}_palm"] for side in ("left", "right")]
    palm_axes = [frames.palm_axes[f"{side}_palm"] for side in ("left", "right")]
    for foot, link in zip(FEET, g1.FOOT_LINKS, strict=True):
        R, p = kin.frame_pose(link)
        w, v_origin = kin.frame_velocity(link)
        offset = R @ ca.DM(frames.sole["left_sole"])
        parts |= {
            f"{foot}_r": p + offset,
            f"{foot}_r_dot": v_origin + ca.cross(w, offset),
            f"{foot}_R": ca.vec(R),
            f"{foot}_w": w,
        }
    for hand, link, palm, axes in zip(HANDS, g1.HAND_LINKS, palms, palm_axes, strict=True):
        R, p = kin.frame_pose(link)
        w, _ = kin.frame_velocity(link)
        parts |= {
            f"{hand}_r": p + R @ ca.DM(palm),
            f"{hand}_R": ca.vec(R @ ca.DM(axes)),
            f"{hand}_w": w,
        }
    points = []
    for link, offset, _ in BODY_POINTS:
        R, p = kin.frame_pose(link)
        points.append(p + R @ ca.DM(offset))
    parts["body_points"] = ca.vertcat(*points)
    return ca.Function("kinematics", [q, v], [ca.vertcat(*[parts[name] for name in KINEMATICS])])


def _par(p: ca.SX, name: str) -> ca.SX:
    return p[PARAMETERS[name]]


class StageBuilder:
    """Builds and caches one stage function per (mode at k, mode at k + 1, last) triple.

    Every function takes the global parameters theta (:mod:`locoman.to.parameters`) as its
    last input: the numbers below only set the problem's structure (which terms exist, how
    many edge points an obstacle has), and :attr:`parameters` holds their values.

    Args:
        kin: Symbolic kinematics of the G1.
        obj: The manipulated object.
        frames: The G1's sole and palm frames.
        weights: Cost weights.
        contact: Contact parameters.
        collision: Which collision terms (Sec. IV-D) to add.
        obstacles: The scene's fixed boxes.
    """

    def __init__(
        self,
        kin: SymbolicKinematics,
        obj: ObjectModel,
        frames: ContactFrames,
        weights: CostWeights,
        contact: ContactCfg,
        collision: CollisionCfg,
        obstacles: tuple[Obstacle, ...],
    ) -> None:
        self.parameters = GlobalParameters.of(weights, contact, collision, obj, obstacles)
        symbols = SymbolicGlobals(self.parameters.layout)
        self.theta = symbols.theta
        self.kin, self.obj = kin, symbols.object(obj)
        self.w, self.contact = symbols.weights(weights), symbols.contact(contact)
        self.collision, self.obstacles = symbols.collision(collision), symbols.obstacles(obstacles)
        # Points per vertical edge of each obstacle, spaced by the object's half height.
        self.edge_counts = [edge_point_count(o.half_extents[2], obj.com[2]) for o in obstacles]
        self.sole_half = np.asarray(frames.sole_half_extents)
        self.palm_radius = float(frames.palm_radius)
        self.palm_half_length = float(frames.palm_half_length)
        self.kinematics = kinematics_function(kin, frames)
        q, v = kin.q, kin.v
        self._base_omega = ca.Function(
            "base_omega", [q, v], [euler_rates_to_world(q[3:6]) @ v[3:6]]
        )
        self._cache: dict[tuple, tuple[ca.Function, np.ndarray, np.ndarray]] = {}

    def group(
        self,
        mode: NodeMode,
        mode_next: NodeMode,
        last: bool,
        stages: np.ndarray,
        curvature: bool = True,
    ) -> StageGroup:
        """The stage group of the given stages, which share ``(mode, mode_next, last)``;
        without ``curvature`` the constraints' second derivatives stay out of the Hessian."""
        key = (mode, mode_next, last)
        if key not in self._cache:
            self._cache[key] = self._stage(mode, mode_next, last, f"stage_{len(self._cache)}")
        fn, lower, upper = self._cache[key]
        return StageGroup(fn, np.asarray(stages, dtype=int), lower, upper, curvature)

    def kinematics_group(self, nodes: np.ndarray, curvature: bool = True) -> StageGroup:
        """The node constraint tying the lifted kinematics to q, v at ``nodes``; without
        ``curvature`` its second derivatives stay out of the Hessian (Gauss-Newton)."""
        z, p = ca.SX.sym("z", WIDTH), ca.SX.sym("p", N_PARAMS)
        residual = _var(z, "kin") - self.kinematics(_var(z, "q"), _var(z, "v"))
        fn = ca.Function("kinematics_node", [z, p, self.theta], [residual, ca.SX(0), ca.SX(0, 1)])
        rows = residual.numel()
        return StageGroup(
            fn, np.asarray(nodes, dtype=int), np.zeros(rows), np.zeros(rows), curvature
        )

    def self_collision_group(self, nodes: np.ndarray) -> StageGroup | None:
        """(12), or (11), between the spheres of each of ``collision.self_pairs``, from q;
        None when there are no pairs or the kind is off."""
        cfg = self.collision
        if not cfg.self_pairs or cfg.self_collision == "off":
            return None
        z, p = ca.SX.sym("z", WIDTH), ca.SX.sym("p", N_PARAMS)
        terms = CollisionTerms()
        terms.add(
            cfg.self_collision,
            self_collision_penetrations(self.kin.frame_pose, cfg.self_pairs, cfg.margin_m),
        )
        of_q = ca.Function(
            "self_collision",
            [self.kin.q, self.theta],
            [terms.inequalities(), terms.residuals(cfg.softness, self.w.collision)],
        )
        rows, residuals = of_q(_var(z, "q"), self.theta)
        fn = ca.Function("self_collision_node", [z, p, self.theta], [rows, ca.SX(0), residuals])
        n = rows.numel()
        return StageGroup(fn, np.asarray(nodes, dtype=int), np.zeros(n), np.full(n, np.inf))

    def _foot(self, z: ca.SX, i: int) -> tuple[ca.SX, ca.SX, ca.SX, ca.SX]:
        """Sole centre [m], its velocity [m/s], rotation and angular velocity [rad/s]."""
        f = FEET[i]
        return _kin(z, f"{f}_r"), _kin(z, f"{f}_r_dot"), _kin(z, f"{f}_R"), _kin(z, f"{f}_w")

    def _palm(self, z: ca.SX, i: int) -> tuple[ca.SX, ca.SX, ca.SX]:
        """Palm centre [m], contact frame and angular velocity [rad/s]."""
        h = HANDS[i]
        return _kin(z, f"{h}_r"), _kin(z, f"{h}_R"), _kin(z, f"{h}_w")

    def _palm_spheres(self, z: ca.SX, i: int) -> list[tuple[ca.SX, float]]:
        """(centre [m], radius [m]) of spheres covering the hand's collision capsule: its
        centre and both ends of its axis (the contact frame's x), which reach 3 cm further."""
        r, R, _ = self._palm(z, i)
        ends = [r + sign * self.palm_half_length * R[:, 0] for sign in (-1.0, 1.0)]
        return [(point, self.palm_radius) for point in (r, *ends)]

    def _object_frame(self, z: ca.SX) -> tuple[ca.SX, ca.SX, ca.SX]:
        qo, vo = _var(z, "object_q"), _var(z, "object_v")
        return rpy_matrix(qo[3:6]), qo[0:3], euler_rates_to_world(qo[3:6]) @ vo[3:6]

    def _hand_contact(self, z: ca.SX, p: ca.SX, i: int) -> tuple[ca.SX, ca.SX]:
        """Contact point on the object's surface [m] and the face's frame, world."""
        R_o, p_o, _ = self._object_frame(z)
        point = _par(p, "hand_points")[3 * i : 3 * i + 3]
        face = ca.reshape(_par(p, "hand_frames")[9 * i : 9 * i + 9], 3, 3)
        return p_o + R_o @ point, R_o @ face

    def _robot_contacts(self, z: ca.SX, p: ca.SX, mode: NodeMode) -> list[tuple]:
        """(point, force, moment) of each of the robot's contacts at a node."""
        out = []
        for i in range(2):
            if mode.feet[i]:
                r = self._foot(z, i)[0]
                w = _var(z, "foot_wrench")[6 * i : 6 * i + 6]
                out.append((r, w[0:3], w[3:6]))
            if mode.hands[i]:
                r, _ = self._hand_contact(z, p, i)
                w = _var(z, "hand_wrench")[6 * i : 6 * i + 6]
                out.append((r, w[0:3], w[3:6]))
        return out

    def _object_contacts(self, z: ca.SX, p: ca.SX, mode: NodeMode) -> list[tuple]:
        """(point, force, moment) on the object at a node: its support and minus each
        hand's wrench (6)."""
        out = []
        if mode.object_supported:
            w = _var(z, "support_wrench")
            out.append((_var(z, "object_q")[0:3], w[0:3], w[3:6]))
        for i in range(2):
            if mode.hands[i]:
                r, _ = self._hand_contact(z, p, i)
                w = _var(z, "hand_wrench")[6 * i : 6 * i + 6]
                out.append((r, -w[0:3], -w[3:6]))
        return out

    def _dynamics(self, z, z1, p, mode: NodeMode, mode_next: NodeMode) -> list[ca.SX]:
        q, q1, v1, dt = _var(z, "q"), _var(z1, "q"), _var(z1, "v"), _var(z, "dt")
        h, com, h1 = _kin(z, "h"), _kin(z, "com"), _kin(z1, "h")
        wrench = wrench_sum(com, self._robot_contacts(z, p, mode), self.kin.mass)
        rows = [h1 - h - wrench * dt, q1 - q - v1 * dt]  # (1a), (1b)
        if mode_next.object_active:
            obj = self.obj
            qo, vo = _var(z, "object_q"), _var(z, "object_v")
            qo1, vo1 = _var(z1, "object_q"), _var(z1, "object_v")
            ho, co = rigid_body_momentum(qo, vo, obj.mass, obj.inertia, obj.com)
            ho1, _ = rigid_body_momentum(qo1, vo1, obj.mass, obj.inertia, obj.com)
            wrench_o = wrench_sum(co, self._object_contacts(z, p, mode), obj.mass)
            rows += [ho1 - ho - wrench_o * dt, qo1 - qo - vo1 * dt]
        return rows

    def _contacts(self, z, z1, p1, mode: NodeMode, mode_next: NodeMode) -> list[ca.SX]:
        """Equalities of node k + 1's contacts."""
        k_z = self.contact.stiffness
        rows = []
        for i in range(2):
            if mode_next.feet[i]:
                r, r_dot, R, w = self._foot(z1, i)
                surface = _par(p1, "foot_surface_z")[i]
                slack = _var(z1, "foot_slack")[i]
                before = self._foot(z, i)[0] if mode.feet[i] else None
                rows.append(patch_contact(r, r_dot, R, surface, k_z, slack, before))
                if not mode.feet[i]:
                    rows.append(no_rolling(w))  # (2d) at touchdown
        if not mode_next.object_active:
            return rows
        R_o, p_o, w_o = self._object_frame(z1)
        for i in range(2):
            if mode_next.hands[i]:
                r_palm, R_palm, w_palm = self._palm(z1, i)
                r_j, R_j = self._hand_contact(z1, p1, i)
                r_j = r_j + self.palm_radius * R_j[:, 2]  # the palm centre sits off the face
                slack = _var(z1, "hand_slack")[3 * i : 3 * i + 3]
                rows_i = interactive_contact(r_palm, r_j, slack, R_palm, R_j, w_palm, w_o)
                if mode.hands[i]:
                    rows_i = ca.vertcat(rows_i[0:5], ca.dot(R_j[:, 2], w_palm - w_o))
                rows.append(rows_i)
        # Where the object starts to move its state at k and the wrench on it are fixed, so
        # (1) alone fixes its state at k + 1: a support contact there too would repeat it
        # and make the constraint Jacobian rank-deficient.
        if mode_next.object_supported and mode.object_active:
            vo1 = _var(z1, "object_v")
            surface = _par(p1, "support_z")
            slack = _var(z1, "support_slack")
            before = _var(z, "object_q")[0:3] if mode.object_supported else None
            rows.append(patch_contact(p_o, vo1[0:3], R_o, surface, k_z, slack, before))
            if not mode.object_supported:
                rows.append(no_rolling(w_o))
        return rows

    def _inequalities(self, z, p, mode: NodeMode) -> list[ca.SX]:
        """Inequalities (>= 0) of (3) at node k."""
        rows = []
        for i in range(2):
            if mode.feet[i]:
                R = self._foot(z, i)[2]
                w = _var(z, "foot_wrench")[6 * i : 6 * i + 6]
                mu = self.contact.floor_friction
                rows.append(friction_cone_cop(w[0:3], w[3:6], R, mu, *self.sole_half))
            if mode.hands[i] and not self.contact.prehensile:
                _, R_face = self._hand_contact(z, p, i)
                w = _var(z, "hand_wrench")[6 * i : 6 * i + 6]
                mu, half = self.obj.friction, self.contact.palm_half_extents_m
                rows.append(friction_cone_cop(w[0:3], w[3:6], R_face, mu, *half))
        if mode.object_active and mode.object_supported:
            R_o, _, _ = self._object_frame(z)
            w = _var(z, "support_wrench")
            half = self.obj.half_extents
            rows.append(friction_cone_cop(w[0:3], w[3:6], R_o, self.obj.friction, half[0], half[1]))
        return rows

    def _object_environment(self, z: ca.SX) -> list[ca.SX]:
        """p (11) of each corner of the object in each obstacle, and of the obstacles'
        vertical edges in the object."""
        R_o, p_o, _ = self._object_frame(z)
        half = self._object_half_size()
        corners = [p_o + R_o @ c for c in box_corners(half)]
        centre = p_o + R_o @ self.obj.com
        out = []
        for obstacle, count in zip(self.obstacles, self.edge_counts, strict=True):
            middle, R, box = obstacle.frame()
            out += [sphere_box_penetration(c, 0.0, middle, R, box, self.collision) for c in corners]
            out += [
                sphere_box_penetration(point, 0.0, centre, R_o, half, self.collision)
                for point in vertical_edge_points(obstacle, count)
            ]
        return out

    def node_cost(self, z: ca.SX, p: ca.SX, mode: NodeMode) -> ca.SX:
        """Node k's share of (8) plus the keyframe and goal costs its parameters switch on,
        but for the collision penalties (:meth:`collision_terms`)."""
        w = self.w
        q, v = _var(z, "q"), _var(z, "v")
        com = _kin(z, "com")
        yaw_ref = _par(p, "yaw_ref")
        feet = [self._foot(z, i) for i in range(2)]
        if mode.stance:
            c_all = com
            if mode.carried:
                _, co = rigid_body_momentum(
                    _var(z, "object_q"),
                    _var(z, "object_v"),
                    self.obj.mass,
                    self.obj.inertia,
                    self.obj.com,
                )
                total = self.kin.mass + self.obj.mass
                c_all = (self.kin.mass * com + self.obj.mass * co) / total
            (r_l, _, R_l, _), (r_r, _, R_r, _) = feet
            cost = stance_cost(w, q, c_all, r_l, r_r, R_l, R_r, yaw_ref)
            cost += _par(p, "kf_foot_on") * keyframe_foot_cost(w, r_l, r_r, _par(p, "kf_foot"))
        else:
            swing = next(i for i in range(2) if not mode.feet[i])
            height = feet[swing][0][2] - _par(p, "foot_surface_z")[swing]
            cost = walking_cost(w, q, height, yaw_ref)
        wrenches = ca.vertcat(_var(z, "foot_wrench"), _var(z, "hand_wrench"))
        if mode.object_active:
            wrenches = ca.vertcat(wrenches, _var(z, "support_wrench"))
        cost += regularization_cost(w, q, v, wrenches, self._base_omega(q, v), _var(z, "dt"))
        slacks = ca.vertcat(_var(z, "foot_slack"), _var(z, "hand_slack"), _var(z, "support_slack"))
        cost += w.slack * ca.sumsqr(slacks)
        q_kf = ca.vertcat(0.0, 0.0, _par(p, "kf_base"))
        cost += _par(p, "kf_base_on") * keyframe_base_cost(w, q, q_kf)
        if mode.object_active:
            qo = _var(z, "object_q")
            cost += _par(p, "goal_on") * object_goal_cost(w, qo, _par(p, "goal"))
            cost += w.object_upright * ca.sumsqr(qo[3:5])
        return cost

    def collision_terms(self, z: ca.SX, mode: NodeMode) -> CollisionTerms:
        """p (11) at node k, each kind under its treatment: of the body points, and of the
        palms not touching the object, in the object; of the object's corners while it is
        carried, and of the palms, in the obstacles. A palm is its capsule's centre and end
        spheres."""
        cfg = self.collision
        palms = [self._palm_spheres(z, i) for i in range(2)]
        terms = CollisionTerms()
        if cfg.object_body != "off":
            R_o, p_o, _ = self._object_frame(z)
            centre = p_o + R_o @ self.obj.com
            half = self._object_half_size()
            points = _kin(z, "body_points")
            spheres = [(points[3 * k : 3 * k + 3], r) for k, (_, _, r) in enumerate(BODY_POINTS)]
            spheres += [s for i in range(2) if not mode.hands[i] for s in palms[i]]
            terms.add(
                cfg.object_body,
                [sphere_box_penetration(c, r, centre, R_o, half, cfg) for c, r in spheres],
            )
        if cfg.object_environment != "off" and mode.object_active and not mode.object_supported:
            terms.add(cfg.object_environment, self._object_environment(z))
        if cfg.hands_environment != "off":
            terms.add(
                cfg.hands_environment,
                [
                    sphere_box_penetration(point, radius, *obstacle.frame(), cfg)
                    for obstacle in self.obstacles
                    for point, radius in palms[0] + palms[1]
                ],
            )
        return terms

    def _object_half_size(self) -> ca.SX:
        """(3,) the object's half sizes [m]: its patch's, and half its height (its frame
        sits at the bottom face, the CoM at half height)."""
        return ca.vertcat(self.obj.half_extents, self.obj.com[2])

    def _stage(
        self, mode: NodeMode, mode_next: NodeMode, last: bool, name: str
    ) -> tuple[ca.Function, np.ndarray, np.ndarray]:
        z, z1 = ca.SX.sym("z", WIDTH), ca.SX.sym("z1", WIDTH)
        p, p1 = ca.SX.sym("p", N_PARAMS), ca.SX.sym("p1", N_PARAMS)
        equalities = self._dynamics(z, z1, p, mode, mode_next) + self._contacts(
            z, z1, p1, mode, mode_next
        )
        collisions = [self.collision_terms(z, mode)]
        cost = self.node_cost(z, p, mode)
        if last:
            cost += self.node_cost(z1, p1, mode_next)
            collisions.append(self.collision_terms(z1, mode_next))
        inequalities = self._inequalities(z, p, mode) + [c.inequalities() for c in collisions]
        eq = ca.vertcat(*equalities)
        ineq = ca.vertcat(*inequalities)
        softness, weight = self.collision.softness, self.w.collision
        residuals = ca.vertcat(*[c.residuals(softness, weight) for c in collisions])
        fn = ca.Function(name, [z, z1, p, p1, self.theta], [ca.vertcat(eq, ineq), cost, residuals])
        lower = np.zeros(eq.numel() + ineq.numel())
        upper = np.r_[np.zeros(eq.numel()), np.full(ineq.numel(), np.inf)]
        return fn, lower, upper
