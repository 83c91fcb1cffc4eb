"""The stage functions of paper A's whole-body TO (Sec. IV): one per pair of contact modes.

The robot's kinematics (momentum, CoM, sole and palm frames) are lifted into variables
tied to q, v by one node function (:func:`kinematics_function`), the same at every node; the
stage functions then only combine them. A stage k couples nodes k and k + 1
(:mod:`locoman.to.nlp`). Its constraints are

- the centroidal dynamics (1a), (1b) of the robot, with the wrenches of node k's contacts;
- the same dynamics for every object once it is active (touched by a hand, or resting on or
  carrying an active object; before, it rests where the scene put it and its variables are
  fixed);
- the contact constraints of node k + 1: patch contact (2a)-(2c) of each foot on the ground,
  the interactive contact (4), (5a), (5b) of each hand on the object it touches, and each
  object's support contact (:mod:`locoman.to.supports`: a surface, another object, a
  wheeled chassis); (2d) only where the contact starts at k + 1 (elsewhere (2c) at both
  nodes with (1b) already fixes those rates, and imposing both makes the constraint
  Jacobian singular); after the first node of a hand contact, (5b) keeps only the rate about
  the contact normal, for the same reason;
- the friction cone and CoP (3) of node k's non-prehensile contacts, and the wrench rows of
  the supports ((7b) of a chassis).

Newton's third law (6) holds by construction: an object receives minus each hand's wrench,
and an object carrying another minus that one's support wrench, at the same point. The cost
is node k's (8): L_st or L_wk by the mode, L_reg, L_slack, the keyframe costs (9), (10)
where the parameters switch them on, and the objects' goals, with the collision penalties
(12) as residuals (:mod:`locoman.to.nlp` takes their Hessian as Gauss-Newton); the last
stage adds node N - 1's.
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
    SphereBox,
    box_corners,
    edge_point_counts,
    edge_points,
    link_spheres,
    self_collision_penetrations,
)
from locoman.to.contacts import friction_cone_cop, interactive_contact, no_rolling, patch_contact
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
from locoman.to.layout import BODY_POINTS, FEET, HANDS, KINEMATICS, NodeLayout, ObjectModel
from locoman.to.nlp import StageGroup
from locoman.to.parameters import GlobalParameters, SymbolicGlobals
from locoman.to.supports import BodyFrame, OnObject, Support, SupportContact

FOREARM_LINKS = ("left_wrist_roll_link", "right_wrist_roll_link")
ELBOW_LINKS = ("left_elbow_link", "right_elbow_link")
# The hips, thighs and shins (``legs_object``), as their capsules' sphere chains. The hip
# roll links stand out sideways from the pelvis: without them, S2's carried box went 7 cm
# into one unseen.
LEG_LINKS = tuple(
    f"{side}_{link}"
    for side in ("left", "right")
    for link in ("hip_roll_link", "hip_yaw_link", "knee_link")
)
FOOT_SPHERE_M = 0.04  # radius of the heel and toe spheres [m]


def _sphere_function(kin: SymbolicKinematics, link: str) -> tuple[ca.Function, list[float]]:
    """q -> the world centres [m] of a link's capsule spheres, and their radii [m]."""
    R, p = kin.frame_pose(link)
    spheres = link_spheres(link)
    centres = [p + R @ ca.DM(s.centre) for s in spheres]
    return ca.Function(f"{link}_spheres", [kin.q], centres), [s.radius for s in spheres]


def _smallest_half_size(obj: ObjectModel) -> float:
    """An object box's smallest half size [m]: its patch's half sizes and half its height
    (its CoM sits at half height)."""
    return float(min(np.min(obj.half_extents), obj.com[2]))


def _pairs(spheres: list[tuple[ca.SX, float]], boxes: list[tuple]) -> list[SphereBox]:
    """Each sphere (centre [m], radius [m]) against each box (centre [m], rotation, half
    sizes [m]), box by box."""
    return [SphereBox(c, r, *box) for box in boxes for c, r in spheres]


@dataclasses.dataclass(frozen=True)
class ObjectMode:
    """One object's state of contact at a node.

    Attributes:
        active: Simulated: its variables are free and obey (1). An inactive object rests
            where the scene put it.
        support: What it rests on (:mod:`locoman.to.supports`); None while carried.
    """

    active: bool
    support: Support | None


@dataclasses.dataclass(frozen=True)
class NodeMode:
    """Which contacts hold at one node.

    Attributes:
        feet: (left, right) foot in contact.
        hands: (left, right): the index of the object the hand touches, or None.
        objects: Each object's :class:`ObjectMode`.
        feet_on: (left, right): the object a foot in contact stands on (its top face, at
            the node's ``foot_surface_z``), None: the ground. The object receives the
            foot's wrench (6) and carries it to its own support.
        underfoot: The objects resting on the floor, where a foot can reach them: the
            feet are kept off them (the ``feet_object`` kind), but for a foot standing on
            one.
    """

    feet: tuple[bool, bool]
    hands: tuple[int | None, int | None]
    objects: tuple[ObjectMode, ...]
    feet_on: tuple[int | None, int | None] = (None, None)
    underfoot: tuple[int, ...] = ()

    @property
    def stance(self) -> bool:
        return all(self.feet)

    def supported(self, j: int) -> bool:
        """Object j is active and rests on a support."""
        return self.objects[j].active and self.objects[j].support is not None

    def carried(self, j: int) -> bool:
        """Object j is held off any support."""
        return self.objects[j].active and self.objects[j].support is None

    def riders(self, j: int) -> list[int]:
        """The active objects that rest on object j."""
        return [
            o
            for o, m in enumerate(self.objects)
            if m.active and isinstance(m.support, OnObject) and m.support.base == j
        ]


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


class StageBuilder:
    """Builds and caches one stage function per (mode at k, mode at k + 1, last) triple.

    Every function takes the global parameters theta (:mod:`locoman.to.parameters`) as its
    last input: the numbers below only set the problem's structure (which terms exist, how
    many edge points an obstacle has), and :attr:`parameters` holds their values.

    Args:
        kin: Symbolic kinematics of the G1.
        objects: The scene's rigid objects, in the layout's order.
        frames: The G1's sole and palm frames.
        weights: Cost weights.
        contact: Contact parameters.
        collision: Which collision terms (Sec. IV-D) to add.
        obstacles: The scene's fixed boxes.
    """

    def __init__(
        self,
        kin: SymbolicKinematics,
        objects: tuple[ObjectModel, ...],
        frames: ContactFrames,
        weights: CostWeights,
        contact: ContactCfg,
        collision: CollisionCfg,
        obstacles: tuple[Obstacle, ...],
    ) -> None:
        self.layout = NodeLayout.of(len(objects))
        self.parameters = GlobalParameters.of(weights, contact, collision, objects, obstacles)
        symbols = SymbolicGlobals(self.parameters.layout)
        self.theta = symbols.theta
        self.kin, self.objects = kin, symbols.objects(objects)
        self.w, self.contact = symbols.weights(weights), symbols.contact(contact)
        self.collision, self.obstacles = symbols.collision(collision), symbols.obstacles(obstacles)
        # Points per edge of each obstacle, spaced by each object's smallest half size.
        self.edge_counts = [
            [edge_point_counts(o.half_extents, _smallest_half_size(obj)) for o in obstacles]
            for obj in objects
        ]
        self.sole_half = np.asarray(frames.sole_half_extents)
        self.palm_radius = float(frames.palm_radius)
        self.palm_half_length = float(frames.palm_half_length)
        self.kinematics = kinematics_function(kin, frames)
        q, v = kin.q, kin.v
        self._base_omega = ca.Function(
            "base_omega", [q, v], [euler_rates_to_world(q[3:6]) @ v[3:6]]
        )
        self._sphere_functions = {
            link: _sphere_function(kin, link) for link in (*FOREARM_LINKS, *ELBOW_LINKS, *LEG_LINKS)
        }
        self._cache: dict[tuple, tuple[ca.Function, np.ndarray, np.ndarray]] = {}

    # --- access to a node's block ---------------------------------------------------------

    def _var(self, z: ca.SX, name: str) -> ca.SX:
        return z[self.layout.variables[name]]

    def _ovar(self, z: ca.SX, j: int, quantity: str) -> ca.SX:
        return z[self.layout.object_variables(j, quantity)]

    def _par(self, p: ca.SX, name: str) -> ca.SX:
        return p[self.layout.parameters[name]]

    def _opar(self, p: ca.SX, j: int, quantity: str) -> ca.SX:
        return p[self.layout.object_parameters(j, quantity)]

    def _kin(self, z: ca.SX, name: str) -> ca.SX:
        """A lifted kinematic quantity; rotations come back as (3, 3)."""
        value = self._var(z, "kin")[KINEMATICS[name]]
        return ca.reshape(value, 3, 3) if name.endswith("_R") else value

    def _symbols(self) -> tuple[ca.SX, ca.SX]:
        layout = self.layout
        return ca.SX.sym("z", layout.width), ca.SX.sym("p", layout.n_params)

    # --- groups ---------------------------------------------------------------------------

    def group(
        self,
        mode: NodeMode,
        mode_next: NodeMode,
        last: bool,
        stages: np.ndarray,
        curvature: bool = True,
    ) -> StageGroup:
        """The stage group of the given stages, which share ``(mode, mode_next, last)``;
        without ``curvature`` the constraints' and the penalties' second derivatives stay
        out of the Hessian (Gauss-Newton)."""
        key = (mode, mode_next, last)
        if key not in self._cache:
            self._cache[key] = self._stage(mode, mode_next, last, f"stage_{len(self._cache)}")
        fn, lower, upper = self._cache[key]
        stages = np.asarray(stages, dtype=int)
        return StageGroup(fn, stages, lower, upper, curvature, residual_curvature=curvature)

    def kinematics_group(self, nodes: np.ndarray, curvature: bool = True) -> StageGroup:
        """The node constraint tying the lifted kinematics to q, v at ``nodes``; without
        ``curvature`` its second derivatives stay out of the Hessian (Gauss-Newton)."""
        z, p = self._symbols()
        residual = self._var(z, "kin") - self.kinematics(self._var(z, "q"), self._var(z, "v"))
        fn = ca.Function("kinematics_node", [z, p, self.theta], [residual, ca.SX(0), ca.SX(0, 1)])
        rows = residual.numel()
        return StageGroup(
            fn, np.asarray(nodes, dtype=int), np.zeros(rows), np.zeros(rows), curvature
        )

    def self_collision_group(self, nodes: np.ndarray) -> StageGroup | None:
        """(12), or (11), between the spheres of each of ``collision.self_pairs`` and of
        ``collision.knee_pairs``, from q; None when no kind has pairs and a treatment."""
        cfg = self.collision
        kinds = [
            (pairs, treatment)
            for pairs, treatment in (
                (cfg.self_pairs, cfg.self_collision),
                (cfg.knee_pairs, cfg.knee_collision),
            )
            if pairs and treatment != "off"
        ]
        if not kinds:
            return None
        z, p = self._symbols()
        terms = CollisionTerms()
        for pairs, treatment in kinds:
            terms.add_penetrations(
                treatment, self_collision_penetrations(self.kin.frame_pose, pairs, cfg.margin_m)
            )
        # Sphere pairs have no homotopy (CollisionCfg.check), so no alpha.
        of_q = ca.Function(
            "self_collision",
            [self.kin.q, self.theta],
            [terms.inequalities(), terms.residuals(cfg.softness, self.w.collision)],
        )
        rows, residuals = of_q(self._var(z, "q"), self.theta)
        fn = ca.Function("self_collision_node", [z, p, self.theta], [rows, ca.SX(0), residuals])
        n = rows.numel()
        return StageGroup(fn, np.asarray(nodes, dtype=int), np.zeros(n), np.full(n, np.inf))

    # --- the robot's and the objects' frames ------------------------------------------------

    def _foot(self, z: ca.SX, i: int) -> tuple[ca.SX, ca.SX, ca.SX, ca.SX]:
        """Sole centre [m], its velocity [m/s], rotation and angular velocity [rad/s]."""
        f = FEET[i]
        kin = self._kin
        return kin(z, f"{f}_r"), kin(z, f"{f}_r_dot"), kin(z, f"{f}_R"), kin(z, f"{f}_w")

    def _foot_spheres(self, z: ca.SX, i: int) -> list[tuple[ca.SX, float]]:
        """(centre [m], radius [m]) of a heel and a toe sphere, resting on the sole and
        reaching its ends (the G1's sole is 18 cm long)."""
        r, _, R, _ = self._foot(z, i)
        return [(r + R @ ca.DM([x, 0.0, FOOT_SPHERE_M]), FOOT_SPHERE_M) for x in (-0.05, 0.05)]

    def _palm(self, z: ca.SX, i: int) -> tuple[ca.SX, ca.SX, ca.SX]:
        """Palm centre [m], contact frame and angular velocity [rad/s]."""
        h = HANDS[i]
        return self._kin(z, f"{h}_r"), self._kin(z, f"{h}_R"), self._kin(z, f"{h}_w")

    def _palm_spheres(self, z: ca.SX, i: int) -> list[tuple[ca.SX, float]]:
        """(centre [m], radius [m]) of spheres covering the hand's collision capsule: its
        centre and both ends of its axis (the contact frame's x), which reach 3 cm further."""
        r, R, _ = self._palm(z, i)
        ends = [r + sign * self.palm_half_length * R[:, 0] for sign in (-1.0, 1.0)]
        return [(point, self.palm_radius) for point in (r, *ends)]

    def _link_spheres(self, z: ca.SX, link: str) -> list[tuple[ca.SX, float]]:
        """(centre [m], radius [m]) of the spheres of a link's collision capsules, from q."""
        of_q, radii = self._sphere_functions[link]
        return list(zip(of_q.call([self._var(z, "q")]), radii, strict=True))

    def _forearm(self, z: ca.SX, i: int) -> list[tuple[ca.SX, float]]:
        """The spheres of the forearm's (wrist roll link's) collision capsules."""
        return self._link_spheres(z, FOREARM_LINKS[i])

    def _object_frame(self, z: ca.SX, j: int) -> BodyFrame:
        qo, vo = self._ovar(z, j, "q"), self._ovar(z, j, "v")
        R = rpy_matrix(qo[3:6])
        return BodyFrame(qo[0:3], R, vo[0:3], euler_rates_to_world(qo[3:6]) @ vo[3:6])

    def _hand_contact(self, z: ca.SX, p: ca.SX, i: int, j: int) -> tuple[ca.SX, ca.SX]:
        """Hand i's contact point on object j's surface [m] and the face's frame, world."""
        frame = self._object_frame(z, j)
        point = self._par(p, "hand_points")[3 * i : 3 * i + 3]
        face = ca.reshape(self._par(p, "hand_frames")[9 * i : 9 * i + 9], 3, 3)
        return frame.p + frame.R @ point, frame.R @ face

    def _hand_wrench(self, z: ca.SX, i: int) -> ca.SX:
        return self._var(z, "hand_wrench")[6 * i : 6 * i + 6]

    # --- dynamics (1) -----------------------------------------------------------------------

    def _robot_contacts(self, z: ca.SX, p: ca.SX, mode: NodeMode) -> list[tuple]:
        """(point, force, moment) of each of the robot's contacts at a node."""
        out = []
        for i in range(2):
            if mode.feet[i]:
                r = self._foot(z, i)[0]
                w = self._var(z, "foot_wrench")[6 * i : 6 * i + 6]
                out.append((r, w[0:3], w[3:6]))
            if mode.hands[i] is not None:
                r, _ = self._hand_contact(z, p, i, mode.hands[i])
                w = self._hand_wrench(z, i)
                out.append((r, w[0:3], w[3:6]))
        return out

    def _object_contacts(self, z: ca.SX, p: ca.SX, mode: NodeMode, j: int) -> list[tuple]:
        """(point, force, moment) on object j at a node: its support's wrench, and (6)
        minus each touching hand's, each foot's standing on it and each rider's support
        wrench."""
        out = []
        # An object not yet simulated rests on its support's fixed wrench: the stage into
        # its first simulated node needs it.
        if mode.objects[j].support is not None:
            w = self._ovar(z, j, "support_wrench")
            out.append((self._ovar(z, j, "q")[0:3], w[0:3], w[3:6]))
        for i in range(2):
            if mode.hands[i] == j:
                r, _ = self._hand_contact(z, p, i, j)
                w = self._hand_wrench(z, i)
                out.append((r, -w[0:3], -w[3:6]))
        for i in range(2):
            if mode.feet[i] and mode.feet_on[i] == j:
                w = self._var(z, "foot_wrench")[6 * i : 6 * i + 6]
                out.append((self._foot(z, i)[0], -w[0:3], -w[3:6]))
        for rider in mode.riders(j):
            w = self._ovar(z, rider, "support_wrench")
            out.append((self._ovar(z, rider, "q")[0:3], -w[0:3], -w[3:6]))
        return out

    def _dynamics(self, z, z1, p, mode: NodeMode, mode_next: NodeMode) -> list[ca.SX]:
        var = self._var
        q, q1, v1, dt = var(z, "q"), var(z1, "q"), var(z1, "v"), var(z, "dt")
        h, com, h1 = self._kin(z, "h"), self._kin(z, "com"), self._kin(z1, "h")
        wrench = wrench_sum(com, self._robot_contacts(z, p, mode), self.kin.mass)
        rows = [h1 - h - wrench * dt, q1 - q - v1 * dt]  # (1a), (1b)
        for j, obj in enumerate(self.objects):
            if not mode_next.objects[j].active:
                continue
            qo, vo = self._ovar(z, j, "q"), self._ovar(z, j, "v")
            qo1, vo1 = self._ovar(z1, j, "q"), self._ovar(z1, j, "v")
            ho, co = rigid_body_momentum(qo, vo, obj.mass, obj.inertia, obj.com)
            ho1, _ = rigid_body_momentum(qo1, vo1, obj.mass, obj.inertia, obj.com)
            wrench_o = wrench_sum(co, self._object_contacts(z, p, mode, j), obj.mass)
            rows += [ho1 - ho - wrench_o * dt, qo1 - qo - vo1 * dt]
        return rows

    # --- contacts ---------------------------------------------------------------------------

    def _contacts(self, z, z1, p1, mode: NodeMode, mode_next: NodeMode) -> list[ca.SX]:
        """Equalities of node k + 1's contacts."""
        k_z = self.contact.stiffness
        rows = []
        for i in range(2):
            if mode_next.feet[i]:
                r, r_dot, R, w = self._foot(z1, i)
                surface = self._par(p1, "foot_surface_z")[i]
                slack = self._var(z1, "foot_slack")[i]
                before = self._foot(z, i)[0] if mode.feet[i] else None
                rows.append(patch_contact(r, r_dot, R, surface, k_z, slack, before))
                if not mode.feet[i]:
                    rows.append(no_rolling(w))  # (2d) at touchdown
        for i in range(2):
            j = mode_next.hands[i]
            if j is None:
                continue
            r_palm, R_palm, w_palm = self._palm(z1, i)
            r_j, R_j = self._hand_contact(z1, p1, i, j)
            r_j = r_j + self.palm_radius * R_j[:, 2]  # the palm centre sits off the face
            slack = self._var(z1, "hand_slack")[3 * i : 3 * i + 3]
            w_o = self._object_frame(z1, j).omega
            rows_i = interactive_contact(r_palm, r_j, slack, R_palm, R_j, w_palm, w_o)
            if mode.hands[i] == j:
                rows_i = ca.vertcat(rows_i[0:5], ca.dot(R_j[:, 2], w_palm - w_o))
            rows.append(rows_i)
        for j, obj in enumerate(self.objects):
            # Where an object starts to move its state at k and the wrenches on it are
            # fixed, so (1) alone fixes its state at k + 1: a support contact there too
            # would repeat it and make the constraint Jacobian rank-deficient.
            support = mode_next.objects[j].support
            if support is None or not (mode.objects[j].active and mode_next.objects[j].active):
                continue
            on_before = mode.objects[j].support == support
            base = getattr(support, "base", None)
            contact = SupportContact(
                obj=obj,
                now=self._object_frame(z1, j),
                before=self._object_frame(z, j) if on_before else None,
                base_now=self._object_frame(z1, base) if base is not None else None,
                base_before=self._object_frame(z, base) if base is not None else None,
                height=self._opar(p1, j, "support_z"),
                stiffness=k_z,
                slack=self._ovar(z1, j, "support_slack"),
            )
            rows.append(support.equalities(contact))
        return rows

    def _prehensile(self, j: int) -> bool:
        return bool(self.contact.prehensile or self.objects[j].prehensile)

    def _wrench_rows(self, z, p, mode: NodeMode) -> tuple[list[ca.SX], list[ca.SX]]:
        """Node k's rows on its wrenches: equalities (a chassis's (7b)) and inequalities
        (>= 0) of (3)."""
        equalities, inequalities = [], []
        for i in range(2):
            if mode.feet[i]:
                R = self._foot(z, i)[2]
                w = self._var(z, "foot_wrench")[6 * i : 6 * i + 6]
                mu = self.contact.floor_friction
                inequalities.append(friction_cone_cop(w[0:3], w[3:6], R, mu, *self.sole_half))
            j = mode.hands[i]
            if j is not None and not self._prehensile(j):
                _, R_face = self._hand_contact(z, p, i, j)
                w = self._hand_wrench(z, i)
                mu, half = self.objects[j].friction, self.contact.palm_half_extents_m
                inequalities.append(friction_cone_cop(w[0:3], w[3:6], R_face, mu, *half))
        for j, obj in enumerate(self.objects):
            if mode.supported(j):
                support = mode.objects[j].support
                frame, w = self._object_frame(z, j), self._ovar(z, j, "support_wrench")
                equalities.append(support.wrench_equalities(obj, frame, w))
                inequalities.append(support.inequalities(obj, frame, w))
        return equalities, inequalities

    # --- costs and collisions ----------------------------------------------------------------

    def node_cost(self, z: ca.SX, p: ca.SX, mode: NodeMode) -> ca.SX:
        """Node k's share of (8) plus the keyframe and goal costs its parameters switch on,
        but for the collision penalties (:meth:`collision_terms`)."""
        w, var, par = self.w, self._var, self._par
        q, v = var(z, "q"), var(z, "v")
        com = self._kin(z, "com")
        yaw_ref = par(p, "yaw_ref")
        feet = [self._foot(z, i) for i in range(2)]
        if mode.stance:
            c_all = com
            carried = [j for j in range(len(self.objects)) if mode.carried(j)]
            if carried:  # the CoM of the robot and what it carries
                moment, mass = self.kin.mass * com, self.kin.mass
                for j in carried:
                    obj = self.objects[j]
                    qo, vo = self._ovar(z, j, "q"), self._ovar(z, j, "v")
                    _, co = rigid_body_momentum(qo, vo, obj.mass, obj.inertia, obj.com)
                    moment, mass = moment + obj.mass * co, mass + obj.mass
                c_all = moment / mass
            (r_l, _, R_l, _), (r_r, _, R_r, _) = feet
            cost = stance_cost(w, q, c_all, r_l, r_r, R_l, R_r, yaw_ref)
            cost += par(p, "kf_foot_on") * keyframe_foot_cost(w, r_l, r_r, par(p, "kf_foot"))
        else:
            swing = next(i for i in range(2) if not mode.feet[i])
            height = feet[swing][0][2] - par(p, "foot_surface_z")[swing]
            cost = walking_cost(w, q, height, yaw_ref)
        active = [j for j in range(len(self.objects)) if mode.objects[j].active]
        wrenches = ca.vertcat(
            var(z, "foot_wrench"),
            var(z, "hand_wrench"),
            *[self._ovar(z, j, "support_wrench") for j in active],
        )
        # The base height is over the surface the feet stand on (the floor, or a box's top).
        down = [i for i in range(2) if mode.feet[i]]
        ground = sum(par(p, "foot_surface_z")[i] for i in down) / len(down)
        cost += regularization_cost(w, q, v, wrenches, self._base_omega(q, v), var(z, "dt"), ground)
        slacks = ca.vertcat(
            var(z, "foot_slack"),
            var(z, "hand_slack"),
            *[self._ovar(z, j, "support_slack") for j in range(len(self.objects))],
        )
        cost += w.slack * ca.sumsqr(slacks)
        q_kf = ca.vertcat(0.0, 0.0, par(p, "kf_base"))
        cost += par(p, "kf_base_on") * keyframe_base_cost(w, q, q_kf)
        for j in active:
            qo = self._ovar(z, j, "q")
            goal = object_goal_cost(w, qo, self._opar(p, j, "goal"))
            cost += self._opar(p, j, "goal_on") * goal
            cost += w.object_upright * ca.sumsqr(qo[3:5])
        return cost

    def _object_box(self, z: ca.SX, j: int) -> tuple[ca.SX, ca.SX, ca.SX]:
        """Object j's collision box: centre [m], rotation, half sizes (3,) [m] (its patch's,
        and half its height: its frame sits at the bottom face, the CoM at half height)."""
        frame, obj = self._object_frame(z, j), self.objects[j]
        return frame.p + frame.R @ obj.com, frame.R, ca.vertcat(obj.half_extents, obj.com[2])

    def _object_parts(self, z: ca.SX, j: int, parts: tuple) -> list[tuple[ca.SX, ca.SX, ca.DM]]:
        """Centre [m], rotation and half sizes [m] of boxes fixed to object j, each
        (centre, half sizes) in its frame (:attr:`ObjectModel.parts`, ``wheels``)."""
        frame = self._object_frame(z, j)
        return [(frame.p + frame.R @ ca.DM(centre), frame.R, ca.DM(half)) for centre, half in parts]

    def _object_environment(self, z: ca.SX, j: int) -> list[SphereBox]:
        """Each corner of object j against each obstacle, and the obstacles' vertical and
        top edges against the object."""
        centre, R_o, half = self._object_box(z, j)
        bottom = self._object_frame(z, j).p
        corners = [bottom + R_o @ c for c in box_corners(half)]
        out = []
        for obstacle, count in zip(self.obstacles, self.edge_counts[j], strict=True):
            out += [SphereBox(c, 0.0, *obstacle.frame()) for c in corners]
            out += [
                SphereBox(point, 0.0, centre, R_o, half) for point in edge_points(obstacle, count)
            ]
        return out

    def _arm_spheres(
        self, z: ca.SX, mode: NodeMode, i: int, j: int, palm: list[tuple[ca.SX, float]]
    ) -> list[tuple[ca.SX, float]]:
        """The spheres of arm i kept out of all of object j's boxes (``hands_object``) while
        its hand does not touch it: the palm; a solid box's own corners catch a forearm,
        while a trolley's thin handle bar passes between the palms and the body points, so
        an open object checks the forearm too."""
        if mode.hands[i] == j:
            return []
        return palm if self.objects[j].solid else palm + self._forearm(z, i)

    def _holding_forearms(
        self, z: ca.SX, mode: NodeMode, j: int, parts: list[tuple]
    ) -> list[SphereBox]:
        """The forearms of the hands holding open object j against its ``parts``, touching
        allowed (the least margin, ``SphereBox.touching``): a hand pressing a basket's wall
        keeps its forearm out of the basket (as a solid box it went 5 cm into its floor).
        The palm's centre is 5.6 cm off the wall's outer face and the forearm's spheres
        have a 4 cm radius: with the full margin, the forearm sat on the penalty's
        boundary all through the holding phase. A gripped handle sits in the hand, and a
        solid box's face is the palm's contact: not checked (the tiny and S2 boxes)."""
        obj = self.objects[j]
        if obj.solid or self._prehensile(j):
            return []
        forearms = [s for i in range(2) if mode.hands[i] == j for s in self._forearm(z, i)]
        return [dataclasses.replace(pair, touching=True) for pair in _pairs(forearms, parts)]

    def collision_terms(self, z: ca.SX, mode: NodeMode) -> CollisionTerms:
        """The collision terms at node k, each kind under its treatment: the trunk's and the
        legs' body points, the feet's spheres and the palms not touching it against each
        object's boxes; each carried object's corners against the obstacles; the
        palms and the feet against the obstacles. A palm is its capsule's centre and end
        spheres."""
        cfg = self.collision
        points = self._kin(z, "body_points")
        body = [(points[3 * k : 3 * k + 3], r) for k, (_, _, r) in enumerate(BODY_POINTS)]
        legs = [s for link in LEG_LINKS for s in self._link_spheres(z, link)]
        palms = [self._palm_spheres(z, i) for i in range(2)]
        feet = [s for i in range(2) for s in self._foot_spheres(z, i)]
        terms = CollisionTerms()
        for j, obj in enumerate(self.objects):
            boxes = [self._object_box(z, j)] if obj.solid else self._object_parts(z, j, obj.parts)
            under_feet = boxes if obj.solid else self._object_parts(z, j, obj.wheels or obj.parts)
            # The elbows, also of an arm whose hand holds the object: taking a basket that
            # overhangs a shelf, they went into its floor.
            hands = [s for i in range(2) for s in self._arm_spheres(z, mode, i, j, palms[i])]
            hands += [s for link in ELBOW_LINKS for s in self._link_spheres(z, link)]
            arms = _pairs(hands, boxes) + self._holding_forearms(z, mode, j, boxes)
            # The feet are kept off an object on the floor (Sec. V-A, S1: the box stepped
            # onto; S2: a trolley's wheels), but for one whose sole rests on its top.
            feet_j = [
                s
                for i in range(2)
                if j in mode.underfoot and mode.feet_on[i] != j
                for s in self._foot_spheres(z, i)
            ]
            for kind, pairs in (
                ("object_body", _pairs(body, boxes)),
                ("hands_object", arms),
                ("legs_object", _pairs(legs, boxes)),
                ("feet_object", _pairs(feet_j, under_feet)),
            ):
                treatment = getattr(cfg, kind)
                if treatment != "off":
                    terms.add(treatment, pairs, cfg)
        if cfg.object_environment != "off":
            for j in range(len(self.objects)):
                if mode.carried(j):
                    terms.add(cfg.object_environment, self._object_environment(z, j), cfg)
        # The forearms too: reaching over a shelf's edge, the wrists went through its top.
        arms = [s for i in range(2) for s in palms[i] + self._forearm(z, i)]
        for kind, spheres in (
            ("hands_environment", arms),
            ("feet_environment", feet),
        ):
            treatment = getattr(cfg, kind)
            if treatment != "off":
                pairs = [
                    SphereBox(c, r, *obstacle.frame())
                    for obstacle in self.obstacles
                    for c, r in spheres
                ]
                terms.add(treatment, pairs, cfg)
        return terms

    def _stage(
        self, mode: NodeMode, mode_next: NodeMode, last: bool, name: str
    ) -> tuple[ca.Function, np.ndarray, np.ndarray]:
        z, p = self._symbols()
        z1, p1 = self._symbols()
        equalities = self._dynamics(z, z1, p, mode, mode_next) + self._contacts(
            z, z1, p1, mode, mode_next
        )
        wrench_eq, inequalities = self._wrench_rows(z, p, mode)
        equalities += wrench_eq
        collisions = [self.collision_terms(z, mode)]
        cost = self.node_cost(z, p, mode)
        if last:
            cost += self.node_cost(z1, p1, mode_next)
            collisions.append(self.collision_terms(z1, mode_next))
        alphas = [self._var(z, "alpha")] + ([self._var(z1, "alpha")] if last else [])
        inequalities += [c.inequalities(a) for c, a in zip(collisions, alphas, strict=True)]
        eq = ca.vertcat(*equalities)
        ineq = ca.vertcat(*inequalities)
        softness, weight, w_hom = self.collision.softness, self.w.collision, self.w.homotopy
        residuals = ca.vertcat(
            *[
                c.residuals(softness, weight, a, w_hom)
                for c, a in zip(collisions, alphas, strict=True)
            ]
        )
        fn = ca.Function(name, [z, z1, p, p1, self.theta], [ca.vertcat(eq, ineq), cost, residuals])
        lower = np.zeros(eq.numel() + ineq.numel())
        upper = np.r_[np.zeros(eq.numel()), np.full(ineq.numel(), np.inf)]
        return fn, lower, upper
