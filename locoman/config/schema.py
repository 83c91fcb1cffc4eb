"""Typed configuration: one dataclass per section of ``conf/`` (and so of ``params.yaml``).

Every value has a type, and ranges are checked by :func:`locoman.config.load.validate`, so a
wrong key, type or value fails at start-up with the key's full path.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from omegaconf import MISSING

from locoman.config.contacts import ContactsCfg
from locoman.config.execute import ExecuteCfg
from locoman.config.figures import FiguresCfg
from locoman.config.perception import PerceptionCfg
from locoman.config.retarget import RetargetCfg
from locoman.config.skill_transfer import DemosCfg, HqpCfg, KmpCfg
from locoman.config.to import EvaluateCfg, SolveCfg
from locoman.scene.actions import ACTIONS, resolve_action
from locoman.scene.plan_checks import check_layout
from locoman.stage import SCENARIO_NAME_RULE, valid_scenario_name


@dataclass
class ObjectCfg:
    """An object or a piece of environment.

    Attributes:
        kind: Registered object kind (``locoman.scene.objects.OBJECT_KINDS``).
        extents_m: Kind-specific extents [m]; a box is (length x, width y, height z). Not
            named ``size``: DVC's run cache drops keys named ``size`` from a stage's hash.
        pos: Position (x, y, z) [m] of the object's origin: the centre of its bottom face.
        yaw: Rotation about world z [rad].
        mass: [kg]; ``null`` makes the object static (welded to the world).
        friction: Sliding friction coefficient [-].
        rgba: Colour, each channel in [0, 1].
    """

    kind: str = MISSING
    extents_m: list[float] = MISSING
    pos: list[float] = MISSING
    yaw: float = 0.0
    mass: float | None = None
    friction: float = 0.8
    rgba: list[float] = field(default_factory=lambda: [0.6, 0.45, 0.3, 1.0])

    def check(self) -> list[tuple[str, str]]:
        errors = []
        if len(self.pos) != 3:
            errors.append(("pos", f"needs 3 values (x, y, z) [m], got {len(self.pos)}"))
        if any(s <= 0.0 for s in self.extents_m):
            errors.append(("extents_m", f"every extent must be > 0 m, got {self.extents_m}"))
        if self.mass is not None and self.mass <= 0.0:
            errors.append(("mass", f"must be > 0 kg or null (static), got {self.mass}"))
        if not 0.0 < self.friction <= 5.0:
            errors.append(("friction", f"must be in (0, 5], got {self.friction}"))
        if len(self.rgba) != 4 or any(not 0.0 <= c <= 1.0 for c in self.rgba):
            errors.append(("rgba", f"needs 4 values in [0, 1], got {self.rgba}"))
        return errors


@dataclass
class PlacementCfg:
    """Where a subtask puts an object: position of its origin [m] and yaw [rad]."""

    pos: list[float] = MISSING
    yaw: float = 0.0

    def check(self) -> list[tuple[str, str]]:
        if len(self.pos) != 3:
            return [("pos", f"needs 3 values (x, y, z) [m], got {len(self.pos)}")]
        return []


@dataclass
class SubtaskCfg:
    """One step of the high-level plan, in the paper's prompt style.

    Attributes:
        prompt: e.g. "pick up the box from the floor", as a person would say it; the image
            of the subtask shows it.
        object: Name of the object the subtask acts on.
        contacts: End effectors in contact with the object during the subtask
            (``left_hand``, ``right_hand``, ``left_foot``, ``right_foot``, ``gripper``).
        target: Placement of ``object`` at the end of the subtask, if it moves it.
        action: A humanoid subtask's contact schedule, one of
            :data:`locoman.scene.actions.ACTIONS` (``walk``, ``pick``, ``grab``, ``place``,
            ``push``, ``step``); null: the prompt's verb decides
            (:data:`locoman.scene.actions.SYNONYMS`: "carry" and "put" are ``place``).
    """

    prompt: str = MISSING
    object: str = MISSING
    contacts: list[str] = field(default_factory=list)
    target: PlacementCfg | None = None
    action: str | None = None

    @property
    def resolved_action(self) -> str:
        """The subtask's action (:func:`locoman.scene.actions.resolve_action`).

        Raises:
            ValueError: It names none.
        """
        return resolve_action(self.prompt, self.action)

    def check(self) -> list[tuple[str, str]]:
        allowed = {"left_hand", "right_hand", "left_foot", "right_foot", "gripper"}
        bad = sorted(set(self.contacts) - allowed)
        if bad:
            return [("contacts", f"unknown end effectors {bad}; use {sorted(allowed)}")]
        if not self.prompt.strip():
            return [("prompt", "must not be empty")]
        return []


@dataclass
class RobotStartCfg:
    """Initial robot pose on the floor: base position (x, y) [m] and yaw [rad]."""

    xy: list[float] = field(default_factory=lambda: [0.0, 0.0])
    yaw: float = 0.0

    def check(self) -> list[tuple[str, str]]:
        if len(self.xy) != 2:
            return [("xy", f"needs 2 values (x, y) [m], got {len(self.xy)}")]
        return []


@dataclass
class ScenarioCfg:
    """A scenario: robot, objects, environment and the high-level plan.

    Attributes:
        robot: ``g1`` (paper A) or ``mobile_manipulator`` (paper B).
        description: One line for people.
        start: Initial robot pose. For the mobile manipulator this is the base frame Sigma_B,
            which tracks the demonstrator's pelvis (paper B, q_b = [x_pe, y_pe, phi_pe]).
        arm_start: Mobile manipulator only: initial end-effector position [m] (world).
        objects: Objects and environment pieces by name. ``floor`` is always present.
        plan: Ordered subtasks.
        check_reach: Check, before perception, that the G1's hands can reach what each
            subtask takes or sets down (a heuristic: :mod:`locoman.scene.plan_checks`).
    """

    robot: str = MISSING
    description: str = ""
    start: RobotStartCfg = field(default_factory=RobotStartCfg)
    arm_start: list[float] | None = None
    objects: dict[str, ObjectCfg] = field(default_factory=dict)
    plan: list[SubtaskCfg] = field(default_factory=list)
    check_reach: bool = True

    def check(self) -> list[tuple[str, str]]:
        errors = []
        if self.robot not in ("g1", "mobile_manipulator"):
            errors.append(("robot", f"must be g1 or mobile_manipulator, got {self.robot!r}"))
        for i, sub in enumerate(self.plan):
            if sub.object not in self.objects:
                errors.append(
                    (f"plan[{i}].object", f"{sub.object!r} is not one of {sorted(self.objects)}")
                )
            elif sub.target is not None and self.objects[sub.object].mass is None:
                errors.append((f"plan[{i}].target", f"{sub.object!r} is static; give it a mass"))
        if self.robot == "mobile_manipulator" and (
            self.arm_start is None or len(self.arm_start) != 3
        ):
            errors.append(("arm_start", "the mobile manipulator needs (x, y, z) [m]"))
        if self.robot == "g1":
            errors += self._plan_errors()
        return errors

    def _plan_errors(self) -> list[tuple[str, str]]:
        """A humanoid plan: each subtask's action, the end effectors it uses, its target,
        and that what it sets down is in the hands."""
        errors: list[tuple[str, str]] = []
        held: set[str] = set()
        for i, sub in enumerate(self.plan):
            try:
                action = ACTIONS[sub.resolved_action]
            except ValueError as exc:
                key = "action" if sub.action is not None else "prompt"
                errors.append((f"plan[{i}].{key}", f"{sub.prompt!r}: {exc}"))
                continue
            unused = sorted(set(sub.contacts) - action.contacts)
            if unused:
                errors.append(
                    (
                        f"plan[{i}].contacts",
                        f"{action.name!r} does not use {unused}: it puts "
                        f"{sorted(action.contacts)} on its object ({action.schedule})",
                    )
                )
            if action.moves_object and sub.target is None:
                errors.append(
                    (f"plan[{i}].target", f"{action.name!r} needs a target for {sub.object!r}")
                )
            elif not action.moves_object and sub.target is not None:
                errors.append(
                    (
                        f"plan[{i}].target",
                        f"{action.name!r} moves nothing to a target; only "
                        f"{sorted(a for a, x in ACTIONS.items() if x.moves_object)} do",
                    )
                )
            if action.needs_held and sub.object not in held:
                errors.append(
                    (
                        f"plan[{i}]",
                        f"{action.name!r} sets down {sub.object!r}, which the robot does not "
                        "hold: an earlier subtask must pick or grab it",
                    )
                )
            if action.name in ("pick", "grab"):
                held.add(sub.object)
            elif action.name == "place":
                held.discard(sub.object)
        return errors


@dataclass
class ScenarioKnobsCfg:
    """Paper A's sweep knobs (Sec. V-C), applied to every humanoid scenario.

    Attributes:
        box_mass: Mass of the object named ``box`` [kg] (paper: 2.5, 5.0, 7.5).
        initial_yaw: Initial robot yaw [rad] (paper: 0, +-0.6, +-1.2).
    """

    box_mass: float = 5.0
    initial_yaw: float = 0.0

    def check(self) -> list[tuple[str, str]]:
        errors = []
        if not 0.0 < self.box_mass <= 50.0:
            errors.append(("box_mass", f"must be in (0, 50] kg, got {self.box_mass}"))
        if abs(self.initial_yaw) > 3.1416:
            errors.append(("initial_yaw", f"must be in [-pi, pi] rad, got {self.initial_yaw}"))
        return errors


@dataclass
class SceneCheckCfg:
    """Tolerances of the scene stage's validity checks.

    Attributes:
        penetration_tol: Largest penetration allowed between any two bodies at start [m].
        foot_ground_tol: Largest gap or penetration between a G1 sole and the floor [m].
        render_width: Overview image width [px].
        render_height: Overview image height [px].
        rest_tol_m: An object rests on the floor or on another object's top when its bottom
            is within this of it [m] (:mod:`locoman.scene.plan_checks`).
        hand_height_m: The heights [m] of an object's hand faces above the surface the G1
            stands on that its hands reach, [low, high]: below 0.14 m the G1 bends past 90
            deg (S1's 0.2 m box held near its top); 1.45 m is S1's basket from its box.
    """

    penetration_tol: float = 1e-3
    foot_ground_tol: float = 2e-3
    render_width: int = 640
    render_height: int = 480
    rest_tol_m: float = 5e-3
    hand_height_m: list[float] = field(default_factory=lambda: [0.14, 1.45])

    def check(self) -> list[tuple[str, str]]:
        errors = []
        if self.penetration_tol < 0.0 or self.foot_ground_tol < 0.0 or self.rest_tol_m < 0.0:
            errors.append(("penetration_tol", "tolerances must be >= 0 m"))
        if len(self.hand_height_m) != 2 or not 0.0 <= self.hand_height_m[0] < self.hand_height_m[1]:
            errors.append(("hand_height_m", "needs [low, high] with 0 <= low < high [m]"))
        if not (16 <= self.render_width <= 4096 and 16 <= self.render_height <= 4096):
            errors.append(("render_width", "image size must be within [16, 4096] px"))
        return errors


@dataclass
class RootCfg:
    """The whole composed configuration (``params.yaml``)."""

    seed: int = 0
    scenario: ScenarioKnobsCfg = field(default_factory=ScenarioKnobsCfg)
    scenarios: dict[str, ScenarioCfg] = field(default_factory=dict)
    # The G1 scenarios, listed by `make params` (locoman.config.compose); the perception and
    # solve stages' lists default to it.
    humanoid_scenarios: list[str] = field(default_factory=list)
    scene: SceneCheckCfg = field(default_factory=SceneCheckCfg)
    demos: DemosCfg = field(default_factory=DemosCfg)
    kmp: KmpCfg = field(default_factory=KmpCfg)
    hqp: HqpCfg = field(default_factory=HqpCfg)
    perception: PerceptionCfg = field(default_factory=PerceptionCfg)
    contacts: ContactsCfg = field(default_factory=ContactsCfg)
    retarget: RetargetCfg = field(default_factory=RetargetCfg)
    solve: SolveCfg = field(default_factory=SolveCfg)
    evaluate: EvaluateCfg = field(default_factory=EvaluateCfg)
    execute: ExecuteCfg = field(default_factory=ExecuteCfg)
    figures: FiguresCfg = field(default_factory=FiguresCfg)

    def check(self) -> list[tuple[str, str]]:
        errors = [] if self.seed >= 0 else [("seed", "must be >= 0")]
        errors += [
            ("scenarios", f"{name!r}: {SCENARIO_NAME_RULE}")
            for name in self.scenarios
            if not valid_scenario_name(name)
        ]
        if self.demos.scenario not in self.scenarios:
            errors.append(("demos.scenario", f"{self.demos.scenario!r} is not a scenario"))
        for case, case_cfg in self.kmp.cases.items():
            for i, point in enumerate(case_cfg.via_points):
                if point.time_s > self.demos.duration_s:
                    errors.append(
                        (
                            f"kmp.cases.{case}.via_points[{i}].time_s",
                            f"{point.time_s} s is after the task's end "
                            f"(demos.duration_s = {self.demos.duration_s} s)",
                        )
                    )
        for name, scenario in self.scenarios.items():
            if self.scene.check() or scenario.check():
                continue  # the layout needs a valid scenario and tolerances
            errors += [
                (f"scenarios.{name}.{key}", msg)
                for key, msg in check_layout(
                    scenario.objects,
                    scenario.plan,
                    scenario.robot,
                    self.scene.rest_tol_m,
                    self.scene.penetration_tol,
                    self.scene.hand_height_m,
                    scenario.check_reach,
                )
            ]
        g1 = [n for n, s in self.scenarios.items() if s.robot == "g1"]
        if sorted(self.humanoid_scenarios) != sorted(g1):
            errors.append(
                (
                    "humanoid_scenarios",
                    f"lists {self.humanoid_scenarios}, the G1 scenarios are {g1}: "
                    "run `make params`",
                )
            )
        for name in self.perception.scenarios:
            if name not in self.scenarios or self.scenarios[name].robot != "g1":
                errors.append(("perception.scenarios", f"{name!r} is not a G1 scenario"))
        for name in self.solve.scenarios:
            if name not in self.perception.scenarios:
                errors.append(("solve.scenarios", f"{name!r} is not a perception scenario"))
        for name in self.figures.scenarios:
            if name not in self.solve.scenarios:
                errors.append(("figures.scenarios", f"{name!r} is not a solve scenario"))
        return errors


def walk_checks(node: Any, path: str = "", nan_free: bool = False) -> list[tuple[str, str]]:
    """Run every ``check()`` in a config tree and refuse every number that is not finite;
    return (full key path, message) pairs.

    A field named in its dataclass's ``NAN_MEANS_FREE`` may hold NaN (an unconstrained
    entry), never an infinity.
    """
    if isinstance(node, float) and not math.isfinite(node):
        if not (nan_free and math.isnan(node)):
            return [(path, f"must be a finite number, got {node}")]
        return []
    errors: list[tuple[str, str]] = []
    if hasattr(node, "check"):
        errors += [(f"{path}.{key}" if path else key, msg) for key, msg in node.check()]
    children: dict[str, Any] = {}
    free: tuple[str, ...] = ()
    if hasattr(node, "__dataclass_fields__"):
        children = {name: getattr(node, name) for name in node.__dataclass_fields__}
        free = getattr(node, "NAN_MEANS_FREE", ())
    elif isinstance(node, dict):
        children = {str(k): v for k, v in node.items()}
    elif isinstance(node, list):
        children = {f"[{i}]": v for i, v in enumerate(node)}
    for key, child in children.items():
        sub = f"{path}{key}" if key.startswith("[") else (f"{path}.{key}" if path else key)
        errors += walk_checks(child, sub, key in free or (nan_free and key.startswith("[")))
    return errors
