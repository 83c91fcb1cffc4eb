"""Checks of a solved trajectory that share no code with the TO (paper A, Sec. V).

- Penetration (:mod:`locoman.sim.penetration`): the trajectory is replayed kinematically in
  the MuJoCo scene; at each node every penetrating geom pair counts once, at its deepest
  contact, in a class (self, robot-object, robot-environment, scheduled contact,
  object-environment). The paper's penetration per node is the sum over its self and
  robot pairs; its average is the sum over nodes divided by the number of nodes.
- Dynamics: Pinocchio recomputes the robot's centroidal momentum from q, v, and the rigid
  object's from its pose and rate; (1a) and (1b) are checked with the solved wrenches and
  time steps.
- Friction: (3) with the wrenches in each contact's own frame, from Pinocchio's feet and the
  object's faces.
- Slip: each stance foot's sole centre between consecutive nodes in contact.
- Rest: where each object ends, it must stand upright on a support (the floor or another
  object's top face) and be still; a placement target in mid-air fails here.
- A chassis: the lateral velocity of its rear wheels (7a), over each step as the TO holds it
  (checked) and at the nodes (reported); an object resting on another: how far it slides on
  it.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator

import mujoco
import numpy as np
import pinocchio as pin

from locoman.scene import g1
from locoman.scene.plan_state import AS_BUILT, top_face, world_pose
from locoman.scene.rotations import rpy_to_matrix
from locoman.to.problem.objects import ObjectModel
from locoman.to.terms.dynamics import GRAVITY
from locoman.to.terms.kinematics import pin_configuration, pin_velocity

ROBOT = "robot"  # the G1's side of a pair of bodies


def euler_rates_to_world(rpy: np.ndarray) -> np.ndarray:
    """E with omega = E(rpy) rpy_dot for R = Rz Ry Rx (NumPy, for the checks)."""
    p, y = rpy[1], rpy[2]
    return np.array(
        [
            [np.cos(y) * np.cos(p), -np.sin(y), 0.0],
            [np.sin(y) * np.cos(p), np.cos(y), 0.0],
            [-np.sin(p), 0.0, 1.0],
        ]
    )


def scene_qpos(
    model: mujoco.MjModel, q35: np.ndarray, names: list[str], object_q: np.ndarray
) -> np.ndarray:
    """MuJoCo qpos of the scene with the G1 at ``q35`` and each object of ``names`` at its
    row (p, rpy) of ``object_q`` (M, 6)."""
    qpos = g1.pin_to_mujoco_qpos(g1.q35_to_pin(q35), model, model.key("home").qpos)
    for name, pose in zip(names, object_q, strict=True):
        adr = model.joint(f"{name}_free").qposadr[0]
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, rpy_to_matrix(pose[3:6]).ravel())
        qpos[adr : adr + 7] = np.r_[pose[:3], quat]
    return qpos


def poses(
    traj: dict[str, np.ndarray], substeps: int, first: int = 1
) -> Iterator[tuple[int, float, np.ndarray, np.ndarray]]:
    """(node, fraction, q35, object_q (M, 6)) at every node from ``first`` (by default not
    the initial state, which is given, not solved for) and ``substeps`` poses after each
    node but the last (q and the objects' (p, rpy) linear along the step)."""
    q, object_q = traj["q"], traj["object_q"]
    n = len(q)
    for k in range(n):
        if k >= first:
            yield k, 0.0, q[k], object_q[k]
        if k == n - 1:
            continue
        for s in range(1, substeps + 1):
            t = s / (substeps + 1)
            yield k, t, (1 - t) * q[k] + t * q[k + 1], (1 - t) * object_q[k] + t * object_q[k + 1]


@dataclasses.dataclass(frozen=True)
class Residuals:
    """Largest residuals over the trajectory, in the units of each equation.

    Attributes:
        robot_momentum: (1a) [kg m/s, kg m^2/s].
        robot_configuration: (1b) [m, rad].
        objects: object -> ((1a), (1b)) over the nodes where it is simulated.
    """

    robot_momentum: float
    robot_configuration: float
    objects: dict[str, tuple[float, float]]

    @property
    def max(self) -> float:
        values = [self.robot_momentum, self.robot_configuration]
        return max(values + [v for pair in self.objects.values() for v in pair])


def _sole_frames(q35: np.ndarray, sole_centre: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    model = g1.g1_pinocchio_model()
    data = model.createData()
    pin.framesForwardKinematics(model, data, g1.q35_to_pin(q35))
    out = []
    for link in g1.FOOT_LINKS:
        pose = data.oMf[model.getFrameId(link)]
        out.append((pose.rotation @ sole_centre + pose.translation, pose.rotation.copy()))
    return out


def hand_points_world(traj: dict[str, np.ndarray]) -> np.ndarray:
    """(N, 2, 3) each hand's contact point on the object it touches, world [m]; NaN where
    it touches none."""
    out = np.full((len(traj["q"]), 2, 3), np.nan)
    for k, touched in enumerate(traj["hand_object"]):
        for i, j in enumerate(touched):
            if j >= 0:
                pose = traj["object_q"][k, j]
                out[k, i] = rpy_to_matrix(pose[3:6]) @ traj["hand_points"][j, i] + pose[:3]
    return out


def _rigid_body_momentum(obj: ObjectModel, qo: np.ndarray, vo: np.ndarray) -> tuple:
    """Centroidal momentum (6,) and CoM (3,) [m] of an object at (p, rpy), (p_dot, rpy_dot)."""
    R = rpy_to_matrix(qo[3:6])
    omega = euler_rates_to_world(qo[3:6]) @ vo[3:6]
    c = qo[:3] + R @ obj.com
    v_com = vo[:3] + np.cross(omega, R @ obj.com)
    return np.r_[obj.mass * v_com, R @ obj.inertia @ R.T @ omega], c


def _rate(mass: float, com: np.ndarray, contacts: list[tuple]) -> np.ndarray:
    """(6,) gravity plus each (point, force, moment) contact, about ``com``."""
    force, moment = mass * np.asarray(GRAVITY), np.zeros(3)
    for r, f, tau in contacts:
        force = force + f
        moment = moment + np.cross(r - com, f) + tau
    return np.r_[force, moment]


def object_contacts(
    traj: dict[str, np.ndarray], hands: np.ndarray, soles: np.ndarray, k: int, j: int
) -> list:
    """(point, force, moment) on object j at node k: its support, minus each hand touching
    it, each foot standing on it (``soles`` (N, 2, 3): the sole centres [m]) and the support
    of each object resting on it (Newton's third law (6))."""
    out = []
    if traj["support_kind"][k, j] != "none":
        w = traj["support_wrench"][k, j]
        out.append((traj["object_q"][k, j, :3], w[:3], w[3:]))
    for i in range(2):
        if traj["hand_object"][k, i] == j:
            w = traj["hand_wrench"][k, i]
            out.append((hands[k, i], -w[:3], -w[3:]))
        if traj["feet_contact"][k, i] and traj["foot_object"][k, i] == j:
            w = traj["foot_wrench"][k, i]
            out.append((soles[k, i], -w[:3], -w[3:]))
    for rider in np.flatnonzero(traj["support_base"][k] == j):
        if traj["object_active"][k, rider]:
            w = traj["support_wrench"][k, rider]
            out.append((traj["object_q"][k, rider, :3], -w[:3], -w[3:]))
    return out


def dynamics_residuals(
    traj: dict[str, np.ndarray], objects: list[ObjectModel], sole_centre: np.ndarray
) -> Residuals:
    """(1a), (1b) of the robot and of every object, recomputed; ``objects`` in the
    trajectory's order."""
    model = g1.g1_pinocchio_model()
    data = model.createData()
    mass = pin.computeTotalMass(model)
    q, v, dt = traj["q"], traj["v"], traj["dt"]
    n = len(q)
    momenta, coms = [], []
    for qk, vk in zip(q, v, strict=True):
        hg = pin.computeCentroidalMomentum(model, data, pin_configuration(qk), pin_velocity(qk, vk))
        momenta.append(np.r_[hg.linear, hg.angular])
        coms.append(data.com[0].copy())
    hands = hand_points_world(traj)
    soles = np.array([[p for p, _ in _sole_frames(qk, sole_centre)] for qk in q])
    robot_h = robot_q = 0.0
    for k in range(n - 1):
        contacts = []
        for i in range(2):
            if traj["feet_contact"][k, i]:
                w = traj["foot_wrench"][k, i]
                contacts.append((soles[k, i], w[:3], w[3:]))
            if traj["hand_object"][k, i] >= 0:
                w = traj["hand_wrench"][k, i]
                contacts.append((hands[k, i], w[:3], w[3:]))
        rate = _rate(mass, coms[k], contacts)
        robot_h = max(robot_h, np.abs(momenta[k + 1] - momenta[k] - dt[k] * rate).max())
        robot_q = max(robot_q, np.abs(q[k + 1] - q[k] - v[k + 1] * dt[k]).max())
    per_object = {}
    for j, obj in enumerate(objects):
        qo, vo = traj["object_q"][:, j], traj["object_v"][:, j]
        states = [_rigid_body_momentum(obj, qo[k], vo[k]) for k in range(n)]
        worst_h = worst_q = 0.0
        for k in range(n - 1):
            if not traj["object_active"][k + 1, j]:
                continue
            rate = _rate(obj.mass, states[k][1], object_contacts(traj, hands, soles, k, j))
            worst_h = max(worst_h, np.abs(states[k + 1][0] - states[k][0] - dt[k] * rate).max())
            worst_q = max(worst_q, np.abs(qo[k + 1] - qo[k] - vo[k + 1] * dt[k]).max())
        per_object[obj.name] = (float(worst_h), float(worst_q))
    return Residuals(float(robot_h), float(robot_q), per_object)


def cone_violation(
    force: np.ndarray, moment: np.ndarray, R: np.ndarray, mu: float, half: np.ndarray
) -> float:
    """Largest violation of (3a)-(3c) [N, N m] of a wrench in contact frame R; 0 inside."""
    f, tau = R.T @ force, R.T @ moment
    x, y = half
    margins = [
        mu * f[2] - abs(f[0]),
        mu * f[2] - abs(f[1]),
        f[2] * x - abs(tau[1]),
        f[2] * y - abs(tau[0]),
        mu * f[2] * max(x, y) - abs(tau[2]),
    ]
    return float(max(0.0, -min(margins)))


def chassis_violation(
    force: np.ndarray, moment: np.ndarray, R: np.ndarray, mu: float, half: np.ndarray, x_rear: float
) -> float:
    """Largest violation [N, N m] of a chassis contact's wrench rows (Sec. IV-A.3): (7b)
    f_x = 0, the yaw moment of the rear axle's lateral force, the lateral force within the
    wheels' friction and the CoP within the wheelbase; 0 when all hold."""
    f, tau = R.T @ force, R.T @ moment
    x, y = half
    equalities = [abs(f[0]), abs(tau[2] - x_rear * f[1])]
    margins = [mu * f[2] - abs(f[1]), f[2] * x - abs(tau[1]), f[2] * y - abs(tau[0])]
    return float(max(max(equalities), 0.0, -min(margins)))


def friction_violation(traj: dict[str, np.ndarray], sole_centre: np.ndarray) -> float:
    """Largest violation of (3) (and a chassis's wrench rows) over the nodes whose wrenches
    act (all but the last)."""
    worst = 0.0
    for k in range(len(traj["q"]) - 1):
        soles = _sole_frames(traj["q"][k], sole_centre)
        R_obj = [rpy_to_matrix(o[3:6]) for o in traj["object_q"][k]]
        for i in range(2):
            if traj["feet_contact"][k, i]:
                w = traj["foot_wrench"][k, i]
                half, mu = traj["sole_half_extents"], float(traj["floor_friction"])
                worst = max(worst, cone_violation(w[:3], w[3:], soles[i][1], mu, half))
            j = traj["hand_object"][k, i]
            if j >= 0 and not traj["prehensile"][j]:
                w = traj["hand_wrench"][k, i]
                R = R_obj[j] @ traj["hand_frames"][j, i]
                half, mu = traj["palm_half_extents"], traj["object_friction"][j]
                worst = max(worst, cone_violation(w[:3], w[3:], R, mu, half))
        for j, kind in enumerate(traj["support_kind"][k]):
            if kind == "none" or not traj["object_active"][k, j]:
                continue
            w, mu = traj["support_wrench"][k, j], traj["object_friction"][j]
            half = traj["object_half_extents"][j]
            if kind == "chassis":
                x_rear = traj["rear_axle_x"][j]
                violation = chassis_violation(w[:3], w[3:], R_obj[j], mu, half, x_rear)
            else:
                violation = cone_violation(w[:3], w[3:], R_obj[j], mu, half)
            worst = max(worst, violation)
    return worst


def _rear_axle(traj: dict[str, np.ndarray], k: int, j: int) -> tuple[np.ndarray, ...]:
    """Object j's rear-axle centre [m], its velocity [m/s] and C_ch's lateral axis at node k."""
    qo, vo = traj["object_q"][k, j], traj["object_v"][k, j]
    R = rpy_to_matrix(qo[3:6])
    lever = traj["rear_axle_x"][j] * R[:, 0]
    omega = euler_rates_to_world(qo[3:6]) @ vo[3:6]
    return qo[:3] + lever, vo[:3] + np.cross(omega, lever), R[:, 1]


def nonholonomic_violation(traj: dict[str, np.ndarray]) -> float:
    """Largest lateral velocity [m/s] of a chassis's rear wheels in C_ch, (7a), as the TO
    discretises it: over a step where the chassis rolls at both ends, the rear axle's
    displacement along C_ch's y at the step's end divided by the step; where it starts to
    roll, the rate at that node. 0 without a chassis.

    The rate at every node (:func:`nonholonomic_tangent`) differs from this by the
    discretisation: a chassis that turns moves along a chord, not its tangent.
    """
    worst = 0.0
    dt = traj["dt"]
    for k in range(1, len(traj["q"])):
        for j in np.flatnonzero(traj["support_kind"][k] == "chassis"):
            if not (traj["object_active"][k - 1, j] and traj["object_active"][k, j]):
                continue  # (1) alone fixes the state where an object starts to move
            rear, rate, lateral = _rear_axle(traj, k, j)
            if traj["support_kind"][k - 1, j] == "chassis":
                rate = (rear - _rear_axle(traj, k - 1, j)[0]) / dt[k - 1]
            worst = max(worst, abs(float(lateral @ rate)))
    return worst


def nonholonomic_tangent(traj: dict[str, np.ndarray]) -> float:
    """Largest lateral velocity [m/s] of a chassis's rear wheels in C_ch at the nodes where
    it rolls, (7a) in continuous time: what the discretisation of
    :func:`nonholonomic_violation` leaves, growing with the yaw rate and the step."""
    worst = 0.0
    for k in range(len(traj["q"])):
        for j in np.flatnonzero(traj["support_kind"][k] == "chassis"):
            if traj["object_active"][k, j]:
                _, rate, lateral = _rear_axle(traj, k, j)
                worst = max(worst, abs(float(lateral @ rate)))
    return worst


def support_slip(traj: dict[str, np.ndarray], half_extents: list[np.ndarray]) -> dict[str, float]:
    """For each object while it rests on a support: the farthest [m] a corner of its bottom
    moves along the support (horizontally, in the support's frame: the world's for a fixed
    surface, the carrier's for an object on another) from where it was when it was set down;
    settling onto it is not slip. Corners, not the origin: a box that
    turns about its centre slides at its corners (S1's box spun 0.34 rad per node on the
    floor, its origin still).

    Keys: ``<object>_on_<carrier>`` for an object on another, ``<object>_on_surface`` on a
    fixed surface.

    Args:
        half_extents: Per object, its bottom patch's half sizes (x, y) [m].
    """
    names = [str(n) for n in traj["object_names"]]
    kind, base = traj["support_kind"], traj["support_base"]
    out: dict[str, float] = {}
    for j, name in enumerate(names):
        hx, hy = half_extents[j]
        corners = np.array([[sx * hx, sy * hy, 0.0] for sx in (-1, 1) for sy in (-1, 1)])

        def local(k: int, j=j, corners=corners) -> np.ndarray:
            q = traj["object_q"][k, j]
            world = q[:3] + corners @ rpy_to_matrix(q[3:6]).T
            b = int(base[k, j])
            if kind[k, j] != "on_object" or b < 0:
                return world
            pb = traj["object_q"][k, b]
            return (world - pb[:3]) @ rpy_to_matrix(pb[3:6])

        for support in ("surface", "on_object"):
            resting = (kind[:, j] == support) & traj["object_active"][:, j]
            worst, start = None, None
            for k in range(len(resting)):
                same = k > 0 and resting[k - 1] and base[k, j] == base[k - 1, j]
                if not resting[k]:
                    continue
                if not same:
                    start = local(k)
                moved = float(np.linalg.norm((local(k) - start)[:, :2], axis=1).max())
                worst = moved if worst is None else max(worst, moved)
            if worst is None:
                continue
            carrier = names[int(base[resting, j][0])] if support == "on_object" else "surface"
            out[f"{name}_on_{carrier}"] = worst
    return out


def _stance_steps(traj: dict[str, np.ndarray], sole_centre: np.ndarray) -> Iterator[tuple]:
    """Each (sole frame at k, at k + 1) of a foot standing at both nodes: (p, R) pairs."""
    soles = [_sole_frames(q, sole_centre) for q in traj["q"]]
    for k in range(len(soles) - 1):
        for i in range(2):
            if traj["feet_contact"][k, i] and traj["feet_contact"][k + 1, i]:
                yield soles[k][i], soles[k + 1][i]


def stance_slip(traj: dict[str, np.ndarray], sole_centre: np.ndarray) -> float:
    """Largest horizontal move [m] of a sole centre between two nodes it stands on."""
    moves = (
        np.linalg.norm(p1[:2] - p0[:2]) for (p0, _), (p1, _) in _stance_steps(traj, sole_centre)
    )
    return float(max(moves, default=0.0))


def stance_turn(traj: dict[str, np.ndarray], sole_centre: np.ndarray) -> float:
    """Largest turn [rad] of a sole about its normal between two nodes it stands on: paper
    A's (2b) holds the sole's centre, not its turn, and the TO's feet pivot (a sole 0.18 m
    long turned by 12 deg slides 19 mm at its toe). Reported, not checked (docs/deviations.md)."""
    turns = (
        abs(np.arctan2((R0.T @ R1)[1, 0], (R0.T @ R1)[0, 0]))
        for (_, R0), (_, R1) in _stance_steps(traj, sole_centre)
    )
    return float(max(turns, default=0.0))


def support_under(
    objects: dict[str, dict], name: str, poses: dict[str, np.ndarray], height_tol_m: float
) -> str | None:
    """What a box-like object ``name`` rests on, its frame (its bottom face's centre, a
    trolley's chassis frame on the ground) at ``poses[name]`` (4, 4): ``floor`` when that is
    at the floor's height, else the object whose top face holds it at that face's height,
    within ``height_tol_m`` [m] (movable objects at ``poses``, fixed ones where the scene
    has them); None when it rests on nothing (it hangs in mid-air, or sinks into a
    support)."""
    bottom = poses[name][:3, 3]
    if abs(bottom[2]) <= height_tol_m:
        return "floor"
    for other, spec in sorted(objects.items()):
        face = top_face(spec) if other != name else None
        if face is None:
            continue
        centre, half = face
        pose = poses[other] if other in poses else world_pose(objects, AS_BUILT, other)
        local = np.linalg.solve(pose, np.r_[bottom, 1.0])[:3] - centre
        if abs(local[2]) <= height_tol_m and np.all(np.abs(local[:2]) <= half):
            return other
    return None


def object_at_rest(
    objects: dict[str, dict],
    name: str,
    poses: dict[str, np.ndarray],
    object_q: np.ndarray,
    object_v: np.ndarray,
    height_tol_m: float,
    speed_tol: float,
    tilt_tol_rad: float,
) -> tuple[bool, str | None]:
    """Whether object ``name`` ends upright (roll and pitch of ``object_q`` within
    ``tilt_tol_rad`` [rad]), still (every rate of ``object_v`` within ``speed_tol`` [m/s,
    rad/s]) and on a support (:func:`support_under`, ``poses`` every movable object's
    final pose); and that support."""
    support = support_under(objects, name, poses, height_tol_m)
    upright = bool(np.all(np.abs(object_q[3:5]) <= tilt_tol_rad))
    still = bool(np.all(np.abs(object_v) <= speed_tol))
    return support is not None and upright and still, support
