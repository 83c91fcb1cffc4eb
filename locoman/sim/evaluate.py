"""Checks of a solved trajectory that share no code with the TO (paper A, Sec. V).

- Penetration: the trajectory is replayed kinematically in the MuJoCo scene; at each node the
  negative signed distances of all contacts (robot, object, environment, the robot's own
  links) are summed. The paper's average penetration is the sum over nodes divided by the
  number of nodes.
- Dynamics: Pinocchio recomputes the robot's centroidal momentum from q, v, and the rigid
  object's from its pose and rate; (1a) and (1b) are checked with the solved wrenches and
  time steps.
- Friction: (3) with the wrenches in each contact's own frame, from Pinocchio's feet and the
  object's faces.
- Slip: each stance foot's sole centre between consecutive nodes in contact.
- Rest: where the object ends, it must stand upright on a support (the floor or a fixed
  object's top face) and be still; a placement target in mid-air fails here.
"""

from __future__ import annotations

import dataclasses

import mujoco
import numpy as np
import pinocchio as pin

from locoman.scene import g1
from locoman.scene.plan_state import PlanState, top_face, world_pose
from locoman.scene.rotations import rpy_to_matrix
from locoman.to.kinematics import pin_configuration, pin_velocity
from locoman.to.layout import ObjectModel

GRAVITY = np.array([0.0, 0.0, -9.81])  # [m/s^2]


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
    model: mujoco.MjModel, q35: np.ndarray, object_name: str, object_q: np.ndarray
) -> np.ndarray:
    """MuJoCo qpos of the scene with the G1 at ``q35`` and the object at (p, rpy)."""
    qpos = g1.pin_to_mujoco_qpos(g1.q35_to_pin(q35), model, model.key("home").qpos)
    adr = model.joint(f"{object_name}_free").qposadr[0]
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, rpy_to_matrix(object_q[3:6]).ravel())
    qpos[adr : adr + 7] = np.r_[object_q[:3], quat]
    return qpos


def geom_label(model: mujoco.MjModel, geom: int) -> str:
    """The geom's name, or, for the robot's unnamed mesh geoms, its body's name and index."""
    name = model.geom(geom).name
    return name or f"{model.body(model.geom_bodyid[geom]).name}#{geom}"


def penetrations(
    model: mujoco.MjModel, q: np.ndarray, object_name: str, object_q: np.ndarray
) -> tuple[np.ndarray, list[tuple[str, str, float]]]:
    """Total penetration [m] per node (sum of -dist over contacts with dist < 0), and the
    deepest (geom, geom, depth) per node."""
    data = mujoco.MjData(model)
    totals, worst = [], []
    for qk, ok in zip(q, object_q, strict=True):
        data.qpos[:] = scene_qpos(model, qk, object_name, ok)
        mujoco.mj_forward(model, data)
        depth, deepest = 0.0, ("", "", 0.0)
        for c in data.contact[: data.ncon]:
            if c.dist < 0.0:
                depth -= c.dist
                if -c.dist > deepest[2]:
                    deepest = (geom_label(model, c.geom1), geom_label(model, c.geom2), -c.dist)
        totals.append(depth)
        worst.append(deepest)
    return np.array(totals), worst


@dataclasses.dataclass(frozen=True)
class Residuals:
    """Largest residuals over the trajectory, in the units of each equation."""

    robot_momentum: float  # (1a) [kg m/s, kg m^2/s]
    robot_configuration: float  # (1b) [m, rad]
    object_momentum: float
    object_configuration: float

    @property
    def max(self) -> float:
        return max(dataclasses.astuple(self))


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
    """(N, 2, 3) hand contact points on the object, world [m]."""
    R = np.array([rpy_to_matrix(o[3:6]) for o in traj["object_q"]])
    return np.einsum("nij,hj->nhi", R, traj["hand_points"]) + traj["object_q"][:, None, :3]


def dynamics_residuals(
    traj: dict[str, np.ndarray], obj: ObjectModel, sole_centre: np.ndarray
) -> Residuals:
    """(1a), (1b) of the robot and of the object, recomputed."""
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
    obj_momenta, obj_coms = [], []
    for qo, vo in zip(traj["object_q"], traj["object_v"], strict=True):
        R = rpy_to_matrix(qo[3:6])
        omega = euler_rates_to_world(qo[3:6]) @ vo[3:6]
        c = qo[:3] + R @ obj.com
        v_com = vo[:3] + np.cross(omega, R @ obj.com)
        obj_momenta.append(np.r_[obj.mass * v_com, R @ obj.inertia @ R.T @ omega])
        obj_coms.append(c)
    robot_h = robot_q = obj_h = obj_q = 0.0
    for k in range(n - 1):
        force, moment = mass * GRAVITY, np.zeros(3)
        soles = _sole_frames(q[k], sole_centre)
        for i in range(2):
            if traj["feet_contact"][k, i]:
                f, tau = traj["foot_wrench"][k, i, :3], traj["foot_wrench"][k, i, 3:]
                force = force + f
                moment = moment + np.cross(soles[i][0] - coms[k], f) + tau
            if traj["hands_contact"][k, i]:
                f, tau = traj["hand_wrench"][k, i, :3], traj["hand_wrench"][k, i, 3:]
                force = force + f
                moment = moment + np.cross(hands[k, i] - coms[k], f) + tau
        rate = np.r_[force, moment]
        robot_h = max(robot_h, np.abs(momenta[k + 1] - momenta[k] - dt[k] * rate).max())
        robot_q = max(robot_q, np.abs(q[k + 1] - q[k] - v[k + 1] * dt[k]).max())
        if not traj["object_active"][k + 1]:
            continue
        force, moment = obj.mass * GRAVITY, np.zeros(3)
        if traj["object_supported"][k]:
            f, tau = traj["support_wrench"][k, :3], traj["support_wrench"][k, 3:]
            force = force + f
            moment = moment + np.cross(traj["object_q"][k, :3] - obj_coms[k], f) + tau
        for i in range(2):
            if traj["hands_contact"][k, i]:
                f, tau = -traj["hand_wrench"][k, i, :3], -traj["hand_wrench"][k, i, 3:]
                force = force + f
                moment = moment + np.cross(hands[k, i] - obj_coms[k], f) + tau
        rate = np.r_[force, moment]
        obj_h = max(obj_h, np.abs(obj_momenta[k + 1] - obj_momenta[k] - dt[k] * rate).max())
        step = traj["object_q"][k + 1] - traj["object_q"][k] - traj["object_v"][k + 1] * dt[k]
        obj_q = max(obj_q, np.abs(step).max())
    return Residuals(float(robot_h), float(robot_q), float(obj_h), float(obj_q))


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


def friction_violation(traj: dict[str, np.ndarray], sole_centre: np.ndarray) -> float:
    """Largest violation of (3) over the nodes whose wrenches act (all but the last)."""
    mu_floor, mu_hand, mu_obj = traj["mu"]
    worst = 0.0
    for k in range(len(traj["q"]) - 1):
        soles = _sole_frames(traj["q"][k], sole_centre)
        R_obj = rpy_to_matrix(traj["object_q"][k, 3:6])
        for i in range(2):
            if traj["feet_contact"][k, i]:
                w = traj["foot_wrench"][k, i]
                half = traj["sole_half_extents"]
                worst = max(worst, cone_violation(w[:3], w[3:], soles[i][1], mu_floor, half))
            if traj["hands_contact"][k, i] and not traj["prehensile"]:
                w = traj["hand_wrench"][k, i]
                R = R_obj @ traj["hand_frames"][i]
                half = traj["palm_half_extents"]
                worst = max(worst, cone_violation(w[:3], w[3:], R, mu_hand, half))
        if traj["object_active"][k] and traj["object_supported"][k]:
            w = traj["support_wrench"][k]
            half = traj["object_half_extents"]
            worst = max(worst, cone_violation(w[:3], w[3:], R_obj, mu_obj, half))
    return worst


def stance_slip(traj: dict[str, np.ndarray], sole_centre: np.ndarray) -> float:
    """Largest horizontal move [m] of a sole centre between two nodes it stands on."""
    soles = [_sole_frames(q, sole_centre) for q in traj["q"]]
    worst = 0.0
    for k in range(len(soles) - 1):
        for i in range(2):
            if traj["feet_contact"][k, i] and traj["feet_contact"][k + 1, i]:
                move = soles[k + 1][i][0][:2] - soles[k][i][0][:2]
                worst = max(worst, float(np.linalg.norm(move)))
    return worst


# The scene before any subtask: every object where the scene puts it.
_AS_BUILT = PlanState(-1, {}, None)


def support_under(
    objects: dict[str, dict], object_q: np.ndarray, height_tol_m: float
) -> str | None:
    """What a box-like object at ``object_q`` (p, rpy; its frame at its bottom face's
    centre) rests on: ``floor`` when its bottom is at the floor's height, else the fixed
    object whose top face holds its bottom centre at that face's height, within
    ``height_tol_m`` [m]; None when it rests on nothing (it hangs in mid-air, or sinks into
    a support)."""
    bottom = np.asarray(object_q[:3], dtype=float)
    if abs(bottom[2]) <= height_tol_m:
        return "floor"
    for name, spec in sorted(objects.items()):
        face = top_face(spec) if not spec["movable"] else None
        if face is None:
            continue
        centre, half = face
        pose = world_pose(objects, _AS_BUILT, name)
        local = np.linalg.solve(pose, np.r_[bottom, 1.0])[:3] - centre
        if abs(local[2]) <= height_tol_m and np.all(np.abs(local[:2]) <= half):
            return name
    return None


def object_at_rest(
    objects: dict[str, dict],
    object_q: np.ndarray,
    object_v: np.ndarray,
    height_tol_m: float,
    speed_tol: float,
    tilt_tol_rad: float,
) -> tuple[bool, str | None]:
    """Whether the object ends upright (roll and pitch within ``tilt_tol_rad`` [rad]), still
    (every rate within ``speed_tol`` [m/s, rad/s]) and on a support; and that support."""
    support = support_under(objects, object_q, height_tol_m)
    upright = bool(np.all(np.abs(object_q[3:5]) <= tilt_tol_rad))
    still = bool(np.all(np.abs(object_v) <= speed_tol))
    return support is not None and upright and still, support
