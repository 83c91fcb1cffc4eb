"""Where each quantity sits in a node's block of decision variables and of parameters."""

from __future__ import annotations

import dataclasses

import numpy as np

NQ = 35  # G1: 6 base + 29 joints
FEET = ("left_foot", "right_foot")
HANDS = ("left_hand", "right_hand")


def _slices(sizes: dict[str, int]) -> tuple[dict[str, slice], int]:
    out, start = {}, 0
    for name, size in sizes.items():
        out[name] = slice(start, start + size)
        start += size
    return out, start


# The robot's kinematic quantities at a node, lifted into decision variables (each tied to
# q, v by one node constraint, so that the expensive kinematics appear once per node in the
# derivatives): centroidal momentum, CoM, per sole its centre, velocity, rotation (3x3,
# column-major) and angular velocity, per palm its centre, contact frame and angular
# velocity; world axes.
KINEMATICS, N_KIN = _slices(
    {
        "h": 6,
        "com": 3,
        **{
            f"{foot}_{q}": n
            for foot in FEET
            for q, n in (("r", 3), ("r_dot", 3), ("R", 9), ("w", 3))
        },
        **{f"{hand}_{q}": n for hand in HANDS for q, n in (("r", 3), ("R", 9), ("w", 3))},
        "body_points": 3 * 6,
    }
)

# Points on the robot kept out of the carried object by the penalty (12), with the radius
# of the collision capsule around each [m]: link, offset in the link frame.
BODY_POINTS = (
    ("pelvis", (0.0, 0.0, -0.07), 0.09),
    ("torso_link", (0.0, 0.0, 0.15), 0.12),
    ("left_hip_yaw_link", (-0.035, 0.0, -0.1), 0.07),
    ("right_hip_yaw_link", (-0.035, 0.0, -0.1), 0.07),
    ("left_knee_link", (0.01, 0.0, -0.14), 0.065),
    ("right_knee_link", (0.01, 0.0, -0.14), 0.065),
)

# One node's decision variables: robot q, v; per foot and hand a force [N] and moment [N m]
# at the contact point (world axes; a hand's is the box's push on the robot); the object's
# q = (p, rpy) and v = dq/dt; the wrench of its support on it; the slacks of (2a) and (4);
# the time step to the next node [s]; the lifted kinematics.
VARIABLES, WIDTH = _slices(
    {
        "q": NQ,
        "v": NQ,
        "kin": N_KIN,
        "foot_wrench": 12,  # (f_l, tau_l, f_r, tau_r)
        "hand_wrench": 12,
        "object_q": 6,
        "object_v": 6,
        "support_wrench": 6,
        "foot_slack": 2,
        "hand_slack": 6,
        "support_slack": 1,
        "dt": 1,
    }
)

# One node's parameters: phase flags and references, so that one stage function serves
# every node of a mode and costs switch without rebuilding.
PARAMETERS, N_PARAMS = _slices(
    {
        "swing": 2,  # left, right foot in swing: foot clearance of L_wk
        "yaw_ref": 1,  # [rad] base yaw the pose costs regularise towards
        "kf_base_on": 1,  # (9) at this node
        "kf_base": 4,  # base z [m], rpy [rad] of the keyframe
        "kf_foot_on": 1,  # (10) at this node
        "kf_foot": 2,  # desired feet midpoint xy [m]
        "foot_surface_z": 2,  # [m] height of the surface under each foot
        "support_z": 1,  # [m] height of the surface under the object
        "goal_on": 1,
        "goal": 3,  # object x, y [m], yaw [rad] at the end
        "hand_points": 6,  # contact points on the object, its frame [m]
        "hand_frames": 18,  # contact frames (3x3, columns, z = outward normal), object frame
    }
)


@dataclasses.dataclass(frozen=True)
class ObjectModel:
    """The manipulated rigid body (paper A: objects obey the same dynamics (1)).

    Attributes:
        name: Object name in the scene.
        mass: [kg].
        inertia: (3, 3) about the CoM, body axes [kg m^2].
        com: (3,) CoM in the body frame [m]; the body frame sits at the bottom face's centre.
        half_extents: (2,) half sizes of the bottom patch [m].
        friction: Coefficient of its surfaces [-].
    """

    name: str
    mass: float
    inertia: np.ndarray
    com: np.ndarray
    half_extents: np.ndarray
    friction: float

    @classmethod
    def from_spec(cls, name: str, spec: dict) -> ObjectModel:
        """The object of the scene's object table (``objects.json``) entry ``spec``."""
        return cls.box(name, np.array(spec["size_m"]), spec["mass_kg"], spec["friction"])

    @classmethod
    def box(cls, name: str, size: np.ndarray, mass: float, friction: float) -> ObjectModel:
        """A solid box of full ``size`` (3,) [m] with its frame at the bottom centre."""
        a, b, c = np.asarray(size, dtype=float)
        inertia = mass / 12.0 * np.diag([b * b + c * c, a * a + c * c, a * a + b * b])
        return cls(name, mass, inertia, np.array([0.0, 0.0, c / 2]), np.array([a, b]) / 2, friction)
