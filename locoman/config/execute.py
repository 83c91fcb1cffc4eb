"""Section ``execute``: the G1 carries out the TO's trajectory in MuJoCo's forward dynamics.

The controller is a task-space inverse-dynamics QP (:mod:`locoman.execute`); these are its
gains, weights and limits, and the checks of the executed motion.
"""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class TaskCfg:
    """One tracking task: a PD law on its error, weighted in the QP's cost.

    The task asks for the acceleration ``a_ref + kp e + kd e_dot`` of its quantity and the QP
    pays ``weight * |J a + J_dot v - that|^2`` for missing it.

    Attributes:
        weight: Weight in the cost [1 per (m/s^2)^2 or (rad/s^2)^2].
        kp: Proportional gain [1/s^2].
        kd: Derivative gain [1/s]; 0 means critically damped, 2 sqrt(kp).
    """

    weight: float
    kp: float
    kd: float = 0.0

    @property
    def damping(self) -> float:
        """The derivative gain in use [1/s]."""
        return self.kd if self.kd > 0.0 else 2.0 * self.kp**0.5


@dataclass
class MomentumCfg:
    """The centroidal angular momentum task: the QP asks dL/dt = -gain L of the momentum L
    about the centre of mass [kg m^2/s] (Orin, Goswami and Lee 2013's A_G), its reference
    zero, as the linear inverted pendulum of the centre-of-mass reference has it.

    Attributes:
        weight: Weight in the cost [1 per (N m)^2].
        gain: Rate at which the momentum is asked to decay [1/s].
    """

    weight: float = 1.0
    gain: float = 10.0


COM_PATHS = ("plan", "lipm")


@dataclass
class BalanceCfg:
    """The centre-of-mass reference (:mod:`locoman.execute.balance`).

    Attributes:
        com_path: ``lipm``: the horizontal centre of mass replanned by the linear inverted
            pendulum over the plan's footsteps, its CoP mid-sole; ``plan``: the TO's, with
            its foot wrenches as the QP's force reference.
        period_s: The LIPM fit's jerk is constant over this [s].
        jerk_weight: The jerk's weight against the ZMP's error in the fit [s^6].
    """

    com_path: str = "lipm"
    period_s: float = 0.02
    jerk_weight: float = 1e-6

    def check(self) -> list[tuple[str, str]]:
        errors = []
        if self.com_path not in COM_PATHS:
            errors.append(("com_path", f"must be one of {', '.join(COM_PATHS)}"))
        if self.period_s <= 0.0 or self.jerk_weight <= 0.0:
            errors.append(("period_s", "period_s and jerk_weight must be > 0"))
        return errors


@dataclass
class ExecuteCfg:
    """Stage ``execute``: the tracking controller and the checks of what it carried out.

    Attributes:
        timestep_s: MuJoCo's step, which is also the controller's period [s].
        settle_s: Time the robot stands on both soles at the first node before the motion
            starts [s]: MuJoCo's soft floor settles and the centre of mass shifts over the
            first stance sole.
        hold_s: Time it holds the last node after the motion ends [s]: an object set
            down must stay where it was put.
        balance: Where the centre-of-mass reference comes from.
        com: Centre-of-mass task (3 rows).
        base_orientation: The pelvis's orientation (3 rows).
        torso_orientation: The torso's (3 rows): without it the QP moves the centre of
            mass with the heavy torso, leaning it back against the waist pitch's limit,
            the hands 10-25 cm off.
        angular_momentum: The centroidal angular momentum (3 rows): without it the QP
            swings the trunk and arms to move the centre of mass, and in single support the
            CoM drifts sideways off the stance sole (S1 fell at 2.9 s, its third step).
        swing_foot: A foot off the ground: its sole's pose (6 rows).
        hand: A hand: its palm's pose (6 rows), holding or not.
        posture: Every joint's angle (29 rows).
        hand_clearance_m: A hand away from its object tracks the plan's palm backed off
            the contact normal by this [m], coming to the face from outside.
        hand_blend_s: Time before and after touching an object over which a hand moves
            from its free reference (backed off, moving with the replanned centre of mass)
            to the plan's [s].
        grasp_grace_s: A hand the plan has holding an object that has not touched it for
            this long has lost it (``grasps_lost`` in the metrics) [s].
        force_weight: Weight of the contact wrenches' distance from the TO's [1/N^2].
        contact_kd: Damping of a stance foot's velocity in its contact constraint [1/s].
        min_normal_force_n: Least normal force a stance foot keeps [N].
        support_scale: The sole the QP may put its centre of pressure on, as a fraction of
            the foot box's half length and half width: on MuJoCo's soft floor a CoP on the
            edge rolls the foot over it.
        torque_margin: Fraction of each joint's torque limit the QP may use.
        fallen_height_m: The pelvis below this height counts as a fall [m].
        fallen_tilt_rad: The pelvis tilted more than this from the plan's pelvis counts as a
            fall [rad] (S1's plan bends it 1.06 rad to pick its basket up).
        goal_tol_m: An object's final distance from its goal allowed [m].
        goal_yaw_tol_rad: Its final yaw error allowed [rad].
        penetration_tol_m: Deepest unscheduled contact allowed [m] (the evaluation's bound).
        filmstrip_frames: Frames in the executed-beside-planned filmstrip.
        video: Write the MP4 (a test leaves it out).
    """

    timestep_s: float = 0.001
    settle_s: float = 1.0
    hold_s: float = 1.0
    balance: BalanceCfg = field(default_factory=BalanceCfg)
    com: TaskCfg = field(default_factory=lambda: TaskCfg(weight=100.0, kp=100.0))
    base_orientation: TaskCfg = field(default_factory=lambda: TaskCfg(weight=1.0, kp=100.0))
    torso_orientation: TaskCfg = field(default_factory=lambda: TaskCfg(weight=1.0, kp=100.0))
    angular_momentum: MomentumCfg = field(default_factory=MomentumCfg)
    swing_foot: TaskCfg = field(default_factory=lambda: TaskCfg(weight=10.0, kp=400.0))
    hand: TaskCfg = field(default_factory=lambda: TaskCfg(weight=1.0, kp=200.0))
    posture: TaskCfg = field(default_factory=lambda: TaskCfg(weight=0.1, kp=100.0))
    hand_clearance_m: float = 0.03
    hand_blend_s: float = 0.5
    grasp_grace_s: float = 0.25
    force_weight: float = 1e-4
    contact_kd: float = 20.0
    min_normal_force_n: float = 5.0
    support_scale: float = 1.0
    torque_margin: float = 1.0
    fallen_height_m: float = 0.5
    fallen_tilt_rad: float = 0.6
    goal_tol_m: float = 0.05
    goal_yaw_tol_rad: float = 0.2
    penetration_tol_m: float = 0.02
    filmstrip_frames: int = 8
    video: bool = True

    def check(self) -> list[tuple[str, str]]:
        errors = []
        if not 0.0 < self.timestep_s <= 0.005:
            errors.append(("timestep_s", "the controller's period must be in (0, 5 ms]"))
        if self.settle_s < 0.0 or self.hold_s < 0.0:
            errors.append(("settle_s", "settle_s and hold_s must be >= 0 s"))
        tasks = ("com", "base_orientation", "torso_orientation", "swing_foot", "hand", "posture")
        for name in tasks:
            task = getattr(self, name)
            if task.weight < 0.0 or task.kp < 0.0 or task.kd < 0.0:
                errors.append((name, "weight, kp and kd must be >= 0"))
        if self.angular_momentum.weight < 0.0 or self.angular_momentum.gain < 0.0:
            errors.append(("angular_momentum", "weight and gain must be >= 0"))
        if not 0.0 < self.support_scale <= 1.0:
            errors.append(("support_scale", "must be in (0, 1]: a fraction of the sole"))
        if not 0.0 < self.torque_margin <= 1.0:
            errors.append(("torque_margin", "must be in (0, 1]: a fraction of each limit"))
        if self.grasp_grace_s <= 0.0:
            errors.append(("grasp_grace_s", "must be > 0 s"))
        if self.hand_clearance_m < 0.0 or self.hand_blend_s <= 0.0:
            errors.append(("hand_blend_s", "hand_clearance_m >= 0 m, hand_blend_s > 0 s"))
        if self.contact_kd < 0.0:
            errors.append(("contact_kd", "must be >= 0"))
        if self.min_normal_force_n < 0.0 or self.force_weight <= 0.0:
            errors.append(("force_weight", "force_weight > 0, min_normal_force_n >= 0"))
        if self.filmstrip_frames < 1:
            errors.append(("filmstrip_frames", "must be >= 1"))
        return errors
