"""Where each quantity sits in a node's block of decision variables and of parameters."""

from __future__ import annotations

import dataclasses
import functools

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
        "body_points": 3 * 2,
    }
)

# Points on the trunk kept out of the objects (``object_body``), with the radius of the
# collision capsule around each [m]: link, offset in the link frame. The legs are their
# capsules' sphere chains (``locoman.to.collisions.spheres.LEG_LINKS``): a single sphere
# per link left most of a thigh and a shin uncovered (S1's carried box went 5 cm into the
# hips unseen).
BODY_POINTS = (
    ("pelvis", (0.0, 0.0, -0.07), 0.09),
    ("torso_link", (0.0, 0.0, 0.15), 0.12),
)


def object_key(j: int, quantity: str) -> str:
    """The layout name of object ``j``'s ``quantity`` (``q``, ``v``, ``support_wrench``,
    ``support_slack``; parameters ``support_z``, ``goal_on``, ``goal``)."""
    return f"object{j}_{quantity}"


# Named parts of a node's blocks, relative to a block's start (:func:`part`).
POSITION = slice(0, 3)  # of a q = (p, rpy) [m]

ORIENTATION = slice(3, 6)  # roll, pitch, yaw of a q [rad]

TILT = slice(3, 5)  # roll, pitch of a q [rad]

JOINTS = slice(6, NQ)  # of the robot's q [rad] or v [rad/s]

LINEAR = slice(0, 3)  # of a v = (dp/dt, drpy/dt) [m/s]

ANGULAR = slice(3, 6)  # Euler rates of a v [rad/s]

FORCE = slice(0, 3)  # of a wrench [N]

MOMENT = slice(3, 6)  # of a wrench [N m]

VERTICAL = 2  # the z entry of a position or a force


def part(block: slice, within: slice | int) -> slice | int:
    """``within``, indices relative to ``block``'s start, as indices of the node's block."""
    if isinstance(within, slice):
        return slice(block.start + within.start, block.start + within.stop)
    return block.start + within


def limb(block: slice, i: int) -> slice:
    """Limb ``i``'s (0: left, 1: right) share of a block that holds both limbs' in turn
    (``foot_wrench``, ``hand_slack``, ``hand_points``, ...)."""
    size = (block.stop - block.start) // 2
    return slice(block.start + i * size, block.start + (i + 1) * size)


@dataclasses.dataclass(frozen=True)
class NodeLayout:
    """One node's decision variables and parameters for a scene with ``n_objects`` rigid
    objects (paper A: every object obeys the same dynamics (1) as the robot's centroid).

    Variables: robot q, v; per foot and hand a force [N] and moment
    [N m] at the contact point (world axes; a hand's is the touched object's push on the
    robot); per object its q = (p, rpy), v = dq/dt and the wrench of its support on it (at
    its bottom centre); the slacks of (2a) and (4), per object the slack of its support's
    (2a); the homotopy parameter alpha of (13); the time step to the next node [s].

    Parameters (the numbers that vary along the trajectory, which the transcription hands
    the terms): swing flags, the yaw reference [rad], the keyframe costs' switches
    and references, the height of the surface under each foot [m], the hands' contact points
    and frames on the object they touch (its frame), per object the height of its support's
    surface [m] (in the supporting object's frame when it rests on one) and its goal.

    Attributes:
        n_objects: Number of objects.
        variables, parameters: name -> slice of the node's block.
        width, n_params: Block sizes.
    """

    n_objects: int
    variables: dict[str, slice]
    width: int
    parameters: dict[str, slice]
    n_params: int

    @classmethod
    @functools.cache
    def of(cls, n_objects: int) -> NodeLayout:
        objects = range(n_objects)
        variables, width = _slices(
            {
                "q": NQ,
                "v": NQ,
                "foot_wrench": 12,  # (f_l, tau_l, f_r, tau_r)
                "hand_wrench": 12,
                **{
                    object_key(j, name): 6 for j in objects for name in ("q", "v", "support_wrench")
                },
                "foot_slack": 2,
                "hand_slack": 6,
                **{object_key(j, "support_slack"): 1 for j in objects},
                "alpha": 1,  # (13)'s homotopy parameter [-]; 0 without a homotopy kind
                "dt": 1,
            }
        )
        parameters, n_params = _slices(
            {
                "swing": 2,  # left, right foot in swing: foot clearance of L_wk
                "yaw_ref": 1,  # [rad] base yaw the pose costs regularise towards
                "kf_base_on": 1,  # (9) at this node
                "kf_base": 4,  # base z [m], rpy [rad] of the keyframe
                "kf_foot_on": 1,  # (10) at this node
                "kf_foot": 2,  # desired feet midpoint xy [m]
                "foot_surface_z": 2,  # [m] height of the surface under each foot
                "hand_points": 6,  # contact points on the touched object, its frame [m]
                "hand_frames": 18,  # contact frames (3x3, columns, z = outward normal)
                **{
                    object_key(j, name): size
                    for j in objects
                    for name, size in (("support_z", 1), ("goal_on", 1), ("goal", 3))
                },
            }
        )
        return cls(n_objects, variables, width, parameters, n_params)

    def object_variables(self, j: int, quantity: str) -> slice:
        return self.variables[object_key(j, quantity)]

    def object_parameters(self, j: int, quantity: str) -> slice:
        return self.parameters[object_key(j, quantity)]
