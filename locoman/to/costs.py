"""Stagewise costs of paper A, Table I, and the keyframe costs (9) and (10).

Every cost is a weighted squared norm, w ||.||^2. The weights are the paper's; each is a
field, so an ablation is a parameter change.
"""

from __future__ import annotations

import dataclasses

import casadi as ca

from locoman.scene.g1 import G1_JOINT_NAMES, STANDING_JOINTS

LEGS = tuple(
    k for k, n in enumerate(G1_JOINT_NAMES) if any(p in n for p in ("hip", "knee", "ankle"))
)
ARMS = tuple(
    k
    for k, n in enumerate(G1_JOINT_NAMES)
    if any(p in n for p in ("waist", "shoulder", "elbow", "wrist"))
)

# The arms' nominal angles: the G1's standing posture (elbows bent, hands off the hips).
# Table I regularises q_arm without naming a reference; at zero the G1's elbow capsules
# sit in its pelvis. The paper's legs and arms leave out the G1's three waist joints; they
# count as arm joints here: unregularised, the waist twisted by up to 2.5 rad while the
# robot walked and swung the hands through the hips.
ARM_NOMINAL = [STANDING_JOINTS.get(G1_JOINT_NAMES[k], 0.0) for k in ARMS]


def _joint(name: str) -> int:
    return 6 + G1_JOINT_NAMES.index(name)


@dataclasses.dataclass
class CostWeights:
    """Table I (stance, walking, regularisation, slack) and eqs. (9), (10).

    Attributes:
        com_over_feet: CoM (xy) over the feet's midpoint, stance [-].
        leg_symmetry: Hip pitch/knee alike, hip roll and opposite yaw zero, stance [-].
        foot_yaw_symmetry: Both feet's x axes alike, stance [-].
        base_pose_stance: Base pitch and yaw, stance [-]. The yaw is taken relative to a
            reference per node (the current subtask's keyframe yaw): Table I regularises
            the yaw, and a task that turns the robot needs a yaw to regularise towards.
        foot_clearance: Swing foot ``clearance_m`` above the surface it left, walking [-].
        clearance_m: [m].
        leg_roll: Hip roll angles, walking [-].
        base_pose_walking: Base pitch and yaw (relative, as in stance), walking [-].
        force: Contact forces and moments [-].
        base_linear_velocity: [-].
        base_angular_velocity: [-].
        leg_velocity: [-].
        arm_velocity: [-].
        arm_angle: Arm joint angles towards :data:`ARM_NOMINAL` [-].
        base_height: Base height towards ``base_height_m`` [-].
        base_height_m: [m].
        timestep: Time step towards ``timestep_s`` [-].
        timestep_s: [s].
        slack: Slacks of (2a) and (4) [-].
        keyframe_base: (9): base height and orientation at a keyframe node [-].
        keyframe_foot: (10): feet midpoint at a keyframe's stance [-].
        object_goal: Object position (xy) and yaw at the plan's target, last node; not in
            the paper, which states the target without its cost [-].
        object_upright: Object roll and pitch while it moves (ours) [-].
        collision: Penalties (12) of :mod:`locoman.to.collision` [-].
        homotopy: w_hom of (13b), on alpha^2 at every node [-] (the paper's 2e2).
        average_over_nodes: (14a): the stage and collision weights are divided by the
            number of nodes N (:func:`averaged_over_nodes`); off, they are summed at the
            weights given, as Table I lists them.
    """

    com_over_feet: float = 5e2
    leg_symmetry: float = 3e2
    foot_yaw_symmetry: float = 1e2
    base_pose_stance: float = 1e1
    foot_clearance: float = 2e3
    clearance_m: float = 0.07
    leg_roll: float = 1e1
    base_pose_walking: float = 1e2
    force: float = 1e-6
    base_linear_velocity: float = 1e-1
    base_angular_velocity: float = 1.0
    leg_velocity: float = 5e-1
    arm_velocity: float = 1.0
    arm_angle: float = 1.0
    base_height: float = 1e2
    base_height_m: float = 0.7
    timestep: float = 1e2
    timestep_s: float = 2e-2
    slack: float = 1e5
    keyframe_base: list[float] = dataclasses.field(default_factory=lambda: [1e2, 1e1])
    keyframe_foot: float = 5e2
    object_goal: float = 1e5
    object_upright: float = 1e2
    collision: float = 1e3
    homotopy: float = 2e2
    average_over_nodes: bool = False

    def check(self) -> list[tuple[str, str]]:
        values = [v for v in dataclasses.asdict(self).values() if isinstance(v, float)]
        errors = []
        if min(values) < 0.0 or min(self.keyframe_base) < 0.0:
            errors.append(("slack", "every weight must be >= 0"))
        if len(self.keyframe_base) != 2:
            errors.append(("keyframe_base", "needs two weights: base height, orientation"))
        if self.timestep_s <= 0.0:
            errors.append(("timestep_s", "must be > 0 s"))
        return errors


# (14a) averages the stage and collision costs over the nodes, the keyframe foot cost (10)
# with them (it is part of the stance cost L_st); the keyframe base cost (9) and the object
# goal are summed once. The rest of these fields are not weights.
SUMMED = ("keyframe_base", "object_goal")
NOT_WEIGHTS = ("clearance_m", "base_height_m", "timestep_s", "average_over_nodes")


def averaged_over_nodes(weights: CostWeights, nodes: int) -> CostWeights:
    """The weights of (14a): every stage and collision weight, (10)'s included, divided by N
    ``nodes``."""
    return dataclasses.replace(
        weights,
        **{
            f.name: getattr(weights, f.name) / nodes
            for f in dataclasses.fields(weights)
            if f.name not in SUMMED + NOT_WEIGHTS
        },
    )


def _hip(side: str, axis: str) -> int:
    return _joint(f"{side}_hip_{axis}_joint")


def stance_cost(
    w: CostWeights,
    q: ca.SX,
    com: ca.SX,
    r_lf: ca.SX,
    r_rf: ca.SX,
    R_lf: ca.SX,
    R_rf: ca.SX,
    yaw_ref: ca.SX | float = 0.0,
) -> ca.SX:
    """L_st of Table I: both feet down. ``com`` is c_all, the CoM of the robot and what it
    carries [m]."""
    legs = ca.vertcat(
        q[_joint("left_hip_pitch_joint")] - q[_joint("right_hip_pitch_joint")],
        q[_joint("left_hip_roll_joint")],
        q[_joint("right_hip_roll_joint")],
        q[_joint("left_hip_yaw_joint")] + q[_joint("right_hip_yaw_joint")],
        q[_joint("left_knee_joint")] - q[_joint("right_knee_joint")],
    )
    return (
        w.com_over_feet * ca.sumsqr(com[0:2] - 0.5 * (r_lf[0:2] + r_rf[0:2]))
        + w.leg_symmetry * ca.sumsqr(legs)
        + w.foot_yaw_symmetry * ca.sumsqr(R_lf[:, 0] - R_rf[:, 0])
        + w.base_pose_stance * (q[4] ** 2 + (q[5] - yaw_ref) ** 2)
    )


def walking_cost(
    w: CostWeights, q: ca.SX, swing_height: ca.SX | None, yaw_ref: ca.SX | float = 0.0
) -> ca.SX:
    """L_wk of Table I: one foot in the air, ``swing_height`` [m] above its surface (the
    one it left, or, stepping up, the top it lands on; None: no swing foot)."""
    roll = ca.vertcat(q[_hip("left", "roll")], q[_hip("right", "roll")])
    cost = w.leg_roll * ca.sumsqr(roll) + w.base_pose_walking * (q[4] ** 2 + (q[5] - yaw_ref) ** 2)
    if swing_height is not None:
        cost += w.foot_clearance * (swing_height - w.clearance_m) ** 2
    return cost


def regularization_cost(
    w: CostWeights,
    q: ca.SX,
    v: ca.SX,
    wrench: ca.SX,
    base_omega: ca.SX,
    dt: ca.SX,
    ground: ca.SX | float = 0.0,
) -> ca.SX:
    """L_reg of Table I; the base height is taken over ``ground`` [m], the surface the
    feet stand on."""
    legs = [6 + k for k in LEGS]
    arms = [6 + k for k in ARMS]
    return (
        w.force * ca.sumsqr(wrench)
        + w.base_linear_velocity * ca.sumsqr(v[0:3])
        + w.base_angular_velocity * ca.sumsqr(base_omega)
        + w.leg_velocity * ca.sumsqr(v[legs])
        + w.arm_velocity * ca.sumsqr(v[arms])
        + w.arm_angle * ca.sumsqr(q[arms] - ca.DM(ARM_NOMINAL))
        + w.base_height * (q[2] - ground - w.base_height_m) ** 2
        + w.timestep * (dt - w.timestep_s) ** 2
    )


def keyframe_base_cost(w: CostWeights, q: ca.SX, q_keyframe: ca.SX) -> ca.SX:
    """(9): the base height and orientation of a keyframe."""
    height, orientation = w.keyframe_base
    return height * (q[2] - q_keyframe[2]) ** 2 + orientation * ca.sumsqr(q[3:6] - q_keyframe[3:6])


def object_goal_cost(w: CostWeights, q_object: ca.SX, goal: ca.SX) -> ca.SX:
    """The object at its target: position xy [m] and yaw [rad] (goal = (x, y, yaw))."""
    return w.object_goal * (ca.sumsqr(q_object[0:2] - goal[0:2]) + (q_object[5] - goal[2]) ** 2)


def keyframe_foot_cost(w: CostWeights, r_lf: ca.SX, r_rf: ca.SX, r_des: ca.SX) -> ca.SX:
    """(10): the feet's midpoint at the keyframe's."""
    return w.keyframe_foot * ca.sumsqr(0.5 * (r_lf[0:2] + r_rf[0:2]) - r_des[0:2])
