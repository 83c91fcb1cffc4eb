"""The TO's trajectory as the controller's reference, sampled at the controller's period.

The TO gives nodes 20-80 ms apart (``trajectory.npz``). Between them:
    * the acceleration of the configuration (base position, roll-pitch-yaw, joints) is
      constant along step k, (v_{k+1} - v_k) / dt_k, what node k's wrenches give the TO's
      momentum, and the configuration passes through every node (:func:`interpolate_nodes`):
      the feedforward agrees with the TO's wrenches (on tiny the centroidal dynamics of the
      samples differ from them by 0.1 N and 1.2 N m at the median; a cubic spline through
      the nodes has the centre of mass accelerate at 13 m/s^2 where the wrenches give 3);
    * a contact and its wrench are node k's over the step from node k to k + 1 (the TO's
      implicit Euler step integrates node k's rates; on S1 the G1 then stands 2.4 s, against
      1.3 s with the contacts of both nodes and the wrenches linear between them);
    * a hand's wrench only while it carries its object alone (:func:`carried`).
Before the motion the robot holds the first node for ``settle_s``, standing on both soles,
after it the last for ``hold_s`` with the last node's contacts.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pinocchio as pin

from locoman.execute.model import BASE, PALMS, SOLES, TORSO, execution_model
from locoman.scene.rotations import rpy_to_matrix
from locoman.sim.evaluate import euler_rates_to_world

#: Frames with a pose reference: the soles, the palms, the pelvis, the torso.
TRACKED_FRAMES = (*SOLES, *PALMS, BASE, TORSO)


@dataclasses.dataclass(frozen=True)
class FrameReference:
    """A frame's reference at every sample, world axes.

    Attributes:
        position: (T, 3) [m].
        rotation: (T, 3, 3).
        velocity: (T, 6) linear [m/s] and angular [rad/s] velocity.
        acceleration: (T, 6) classical linear [m/s^2] and angular [rad/s^2] acceleration.
    """

    position: np.ndarray
    rotation: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray


@dataclasses.dataclass(frozen=True)
class Reference:
    """The planned motion at the controller's samples.

    Attributes:
        time: (T,) [s] from the start of the settling.
        q: (T, 36) Pinocchio configuration.
        v: (T, 35) Pinocchio velocity [m/s, rad/s].
        a: (T, 35) its derivative [m/s^2, rad/s^2].
        com: (T, 3) centre of mass [m]; ``com_velocity``, ``com_acceleration`` the same
            shape [m/s, m/s^2].
        frames: Frame name -> its :class:`FrameReference` (:data:`TRACKED_FRAMES`).
        foot_contact: (T, 2) whether each foot (left, right) is on its support.
        foot_wrench: (T, 2, 6) the TO's wrench on each sole centre, world axes [N, N m].
        hand_object: (T, 2) object each hand holds, -1 for none.
        hand_wrench: (T, 2, 6) the TO's wrench of the object on each hand, world axes.
        object_q: (T, M, 6) each object's planned pose (p [m], rpy [rad]).
    """

    time: np.ndarray
    q: np.ndarray
    v: np.ndarray
    a: np.ndarray
    com: np.ndarray
    com_velocity: np.ndarray
    com_acceleration: np.ndarray
    frames: dict[str, FrameReference]
    foot_contact: np.ndarray
    foot_wrench: np.ndarray
    hand_object: np.ndarray
    hand_wrench: np.ndarray
    object_q: np.ndarray

    def __len__(self) -> int:
        return len(self.time)


def node_times(traj: dict[str, np.ndarray]) -> np.ndarray:
    """(N,) time of each node [s] (``dt[k]`` is the step from node k to k + 1)."""
    return np.r_[0.0, np.cumsum(traj["dt"][:-1])]


def pin_state(
    q35: np.ndarray, q35_dot: np.ndarray, q35_ddot: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pinocchio (q, v, a) of a TO configuration (position, rpy, joints) and its two rates.

    v's base part is the twist in the base frame, (R^T p_dot, R^T omega) with omega =
    E(rpy) rpy_dot; a is its derivative, (R^T p_ddot - omega_b x R^T p_dot, R^T omega_dot)
    with omega_b = R^T omega and omega_dot = E rpy_ddot + (dE/dt) rpy_dot."""
    rpy, rpy_dot = q35[3:6], q35_dot[3:6]
    rotation = rpy_to_matrix(rpy)
    rates = euler_rates_to_world(rpy)
    omega = rates @ rpy_dot
    # dE/dt rpy_dot by a forward difference along rpy_dot (E is smooth; 1e-7 rad).
    eps = 1e-7
    rates_dot = (euler_rates_to_world(rpy + eps * rpy_dot) - rates) / eps
    omega_dot = rates @ q35_ddot[3:6] + rates_dot @ rpy_dot
    linear = rotation.T @ q35_dot[:3]
    omega_b = rotation.T @ omega
    q = np.concatenate([q35[:3], pin.Quaternion(rotation).coeffs(), q35[6:]])
    v = np.concatenate([linear, omega_b, q35_dot[6:]])
    a = np.concatenate(
        [
            rotation.T @ q35_ddot[:3] - np.cross(omega_b, linear),
            rotation.T @ omega_dot,
            q35_ddot[6:],
        ]
    )
    return q, v, a


def interpolate_nodes(
    traj: dict[str, np.ndarray], t: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(q35, q35_dot, q35_ddot) at times ``t`` [s] in [0, duration].

    Along step k the acceleration is the TO's, a_k = (v_{k+1} - v_k) / dt_k (what node k's
    wrenches give its momentum), the rate linear from v_k to v_{k+1}, and the configuration
    that rate's integral from node k's, offset linearly along the step so that it reaches
    node k + 1's: q(tau) = q_k + tau v_k + tau^2 a_k / 2 + tau (q_{k+1} - q_k - dt_k (v_k +
    v_{k+1}) / 2) / dt_k, whose rate is the linear one plus that offset's (dt_k a_k / 2, the
    implicit Euler step's lead)."""
    t_nodes = node_times(traj)
    q, v = traj["q"], traj["v"]
    k = np.clip(np.searchsorted(t_nodes, t, side="right") - 1, 0, len(t_nodes) - 2)
    h = (t_nodes[k + 1] - t_nodes[k])[:, None]
    tau = np.clip(t[:, None] - t_nodes[k][:, None], 0.0, h)
    acceleration = (v[k + 1] - v[k]) / h
    lead = (q[k + 1] - q[k] - h * (v[k] + v[k + 1]) / 2) / h
    position = q[k] + tau * (v[k] + lead) + 0.5 * tau**2 * acceleration
    rate = v[k] + lead + tau * acceleration
    return position, rate, acceleration


def time_to_contact(touching: np.ndarray, timestep_s: float) -> np.ndarray:
    """(T,) each sample's time [s] to the nearest sample where ``touching`` (T,) holds (inf
    if none does)."""
    T = len(touching)
    index = np.arange(T)
    hits = np.flatnonzero(touching)
    if len(hits) == 0:
        return np.full(T, np.inf)
    nearest = np.clip(np.searchsorted(hits, index), 1, len(hits)) - 1
    after = np.minimum(nearest + 1, len(hits) - 1)
    gap = np.minimum(np.abs(index - hits[nearest]), np.abs(index - hits[after]))
    return gap * timestep_s


def contact_blend(touching: np.ndarray, timestep_s: float, blend_s: float) -> np.ndarray:
    """(T,) 0 where ``touching`` (T,) holds, 1 from ``blend_s`` [s] away from any such
    sample, a smoothstep 3 s^2 - 2 s^3 of the time to contact between (C1: no jump in the
    reference's velocity)."""
    s = np.clip(time_to_contact(touching, timestep_s) / blend_s, 0.0, 1.0)
    return s * s * (3.0 - 2.0 * s)


def translated(frame: FrameReference, shift: np.ndarray, timestep_s: float) -> FrameReference:
    """``frame`` moved by ``shift`` (T, 3) [m], its velocity and acceleration by the shift's
    rates (central differences over ``timestep_s`` [s])."""
    rate = np.gradient(shift, timestep_s, axis=0)
    velocity = frame.velocity.copy()
    acceleration = frame.acceleration.copy()
    velocity[:, :3] += rate
    acceleration[:, :3] += np.gradient(rate, timestep_s, axis=0)
    return dataclasses.replace(
        frame, position=frame.position + shift, velocity=velocity, acceleration=acceleration
    )


def with_hand_clearance(
    ref: Reference, clearance_m: float, timestep_s: float, blend_s: float
) -> Reference:
    """``ref`` with each palm backed off its contact normal by ``clearance_m`` [m] when it is
    ``blend_s`` [s] or more from touching an object, by none while it touches, a smoothstep
    between (:func:`contact_blend`): the hand comes to the object's face from outside. The
    TO passes a palm within 1-2 cm of the face's edge on its way; a few millimetres of
    tracking error then catch the fingers on the corner and drag the hand."""
    frames = dict(ref.frames)
    for k, name in enumerate(PALMS):
        frame = ref.frames[name]
        away = contact_blend(ref.hand_object[:, k] >= 0, timestep_s, blend_s)
        normal = frame.rotation[:, :, 2]  # the palm's outward normal, into the object
        frames[name] = translated(frame, -clearance_m * away[:, None] * normal, timestep_s)
    return dataclasses.replace(ref, frames=frames)


def carried(traj: dict[str, np.ndarray], node: np.ndarray) -> np.ndarray:
    """(T, 2) whether each hand holds, at nodes ``node`` (T,), an object nothing else
    supports (``support_kind`` none). While a support carries the object too, the TO's
    split of its weight between hands and support is one of many (on tiny it presses the
    box onto the table with 85 N at the grasp); only a carried object's wrench is fed
    forward."""
    hands = traj["hand_object"][node]
    free = traj["support_kind"][node] == "none"  # (T, M)
    if free.shape[1] == 0:
        return np.zeros(hands.shape, dtype=bool)
    rows = np.arange(len(node))[:, None]
    return (hands >= 0) & free[rows, np.maximum(hands, 0)]


def build_reference(
    traj: dict[str, np.ndarray], timestep_s: float, settle_s: float, hold_s: float
) -> Reference:
    """Sample the TO's trajectory ``traj`` every ``timestep_s`` [s], ``settle_s`` [s] at
    the first node before it and ``hold_s`` [s] at the last after it."""
    t_nodes = node_times(traj)
    duration = float(t_nodes[-1])
    time = np.arange(0.0, settle_s + duration + hold_s + 0.5 * timestep_s, timestep_s)
    t = np.clip(time - settle_s, 0.0, duration)
    moving = (time >= settle_s) & (time <= settle_s + duration)
    q35, q35_dot, q35_ddot = interpolate_nodes(traj, t)
    q35_dot[~moving] = 0.0
    q35_ddot[~moving] = 0.0
    n = len(t_nodes)
    node = np.clip(np.searchsorted(t_nodes, t, side="right") - 1, 0, n - 2)
    # The TO's step k (implicit Euler) integrates node k's rates: node k's contacts and
    # wrenches act over it, held until node k + 1 (a foot the TO lifts during step k stays
    # down until node k + 1; one it lands at node k + 1 touches at its time).
    feet = traj["feet_contact"][node].copy()
    settling = time < settle_s
    feet[settling] = True
    hands = traj["hand_object"][node]
    foot_wrench = np.where(feet[..., None], traj["foot_wrench"][node], 0.0)
    hand_wrench = np.where(carried(traj, node)[..., None], traj["hand_wrench"][node], 0.0)
    at_end = t >= duration
    feet[at_end] = traj["feet_contact"][-1]
    hands = np.where(at_end[:, None], traj["hand_object"][-1], hands)
    # Node 0's wrenches belong to its step (often all the weight on one foot, the CoM
    # falling into the first step), the last node's to no step: while settling and holding
    # the QP's least-norm wrenches, the CoP mid-sole, serve instead.
    foot_wrench[settling | at_end] = 0.0
    frac = np.clip((t - t_nodes[node]) / (t_nodes[node + 1] - t_nodes[node]), 0.0, 1.0)
    w = frac[:, None, None]
    object_q = (1 - w) * traj["object_q"][node] + w * traj["object_q"][node + 1]
    return _with_kinematics(
        time, q35, q35_dot, q35_ddot, feet, foot_wrench, hands, hand_wrench, object_q
    )


def _with_kinematics(
    time, q35, q35_dot, q35_ddot, feet, foot_wrench, hands, hand_wrench, object_q
) -> Reference:
    """The samples' Pinocchio state and, by its kinematics, every task's reference."""
    model = execution_model()
    data = model.createData()
    T = len(time)
    q = np.zeros((T, model.nq))
    v = np.zeros((T, model.nv))
    a = np.zeros((T, model.nv))
    for i in range(T):
        q[i], v[i], a[i] = pin_state(q35[i], q35_dot[i], q35_ddot[i])
    com = np.zeros((T, 3))
    com_velocity = np.zeros((T, 3))
    com_acceleration = np.zeros((T, 3))
    ids = {name: model.getFrameId(name) for name in TRACKED_FRAMES}
    frame_rows = {name: ([], [], [], []) for name in TRACKED_FRAMES}
    world = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
    for i in range(T):
        pin.forwardKinematics(model, data, q[i], v[i], a[i])
        pin.updateFramePlacements(model, data)
        pin.centerOfMass(model, data, q[i], v[i], a[i])
        com[i], com_velocity[i], com_acceleration[i] = data.com[0], data.vcom[0], data.acom[0]
        for name, f in ids.items():
            rows = frame_rows[name]
            rows[0].append(data.oMf[f].translation.copy())
            rows[1].append(data.oMf[f].rotation.copy())
            rows[2].append(pin.getFrameVelocity(model, data, f, world).vector.copy())
            rows[3].append(pin.getFrameClassicalAcceleration(model, data, f, world).vector.copy())
    frames = {
        name: FrameReference(*(np.array(r) for r in rows)) for name, rows in frame_rows.items()
    }
    return Reference(
        time=time,
        q=q,
        v=v,
        a=a,
        com=com,
        com_velocity=com_velocity,
        com_acceleration=com_acceleration,
        frames=frames,
        foot_contact=feet,
        foot_wrench=foot_wrench,
        hand_object=hands,
        hand_wrench=hand_wrench,
        object_q=object_q,
    )
