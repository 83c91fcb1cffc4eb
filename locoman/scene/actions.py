"""The actions a humanoid subtask can be, and how a prompt's verb names one.

Paper A describes a task as subtasks in words ("pick up the box from the table"). The TO
knows six contact schedules (:mod:`locoman.to.problem.schedule`); a subtask is one of them, its
*action*. A scenario may say it (``plan[i].action``); where it does not, the prompt's verb
decides through :data:`SYNONYMS` (a phrasal verb, "drop off", before its first word). Both
are resolved once, when the configuration is checked, so a word the table lacks stops the
``validate`` stage before any image is made, naming the subtask, the word and what it may be.
"""

from __future__ import annotations

import dataclasses


@dataclasses.dataclass(frozen=True)
class Action:
    """One contact schedule of the TO.

    Attributes:
        name: The action's word.
        schedule: What the TO does in the subtask (its phases).
        contacts: The end effectors the action may put on the subtask's object.
        moves_object: The action ends with the object at a ``target``.
        needs_held: The object must be in the hands when the subtask starts (taken by an
            earlier ``pick`` or ``grab`` and not set down since).
    """

    name: str
    schedule: str
    contacts: frozenset[str]
    moves_object: bool = False
    needs_held: bool = False


HANDS = frozenset({"left_hand", "right_hand"})
FEET = frozenset({"left_foot", "right_foot"})

ACTIONS = {
    a.name: a
    for a in (
        Action("walk", "steps to the keyframe's stance near the object", FEET),
        Action(
            "pick",
            "steps if needed, reach, grasp (the keyframe), lift: the object carried",
            HANDS,
        ),
        Action(
            "grab",
            "a pick from where the robot stands, possibly on another object",
            HANDS,
        ),
        Action(
            "place",
            "steps carrying the object, lower, set it on its target (the keyframe)",
            HANDS,
            moves_object=True,
            needs_held=True,
        ),
        Action(
            "push",
            "reach, grasp the handle (the keyframe), steps pushing the object on its wheels",
            HANDS,
            moves_object=True,
        ),
        Action(
            "step",
            "two swings landing the feet on the object's top, a stance on it",
            FEET,
        ),
    )
}

# A prompt's verb -> the action. Two-word verbs are looked up before one-word ones.
SYNONYMS = {
    "walk": "walk", "go": "walk", "approach": "walk", "move to": "walk", "head": "walk",
    "pick": "pick", "take": "pick", "lift": "pick", "get": "pick", "fetch": "pick",
    "collect": "pick", "pick up": "pick", "raise": "pick",
    "grab": "grab", "grasp": "grab", "seize": "grab",
    "place": "place", "put": "place", "set": "place", "carry": "place", "bring": "place",
    "move": "place", "deliver": "place", "drop off": "place", "drop": "place",
    "stack": "place", "store": "place", "return": "place", "lay": "place",
    "push": "push", "roll": "push", "wheel": "push", "shove": "push",
    "step": "step", "climb": "step", "stand": "step", "mount": "step",
}  # fmt: skip


def _verb(prompt: str) -> tuple[str, str | None]:
    """The prompt's first word, and its first two words where they are a known verb."""
    words = prompt.lower().replace(",", " ").split()
    first = words[0] if words else ""
    two = " ".join(words[:2])
    return first, two if len(words) > 1 and two in SYNONYMS else None


def resolve_action(prompt: str, action: str | None) -> str:
    """The action of a subtask: ``action`` where given (one of :data:`ACTIONS`), else the
    prompt's verb through :data:`SYNONYMS`.

    Raises:
        ValueError: The action, or the verb, is not known; the message names the word and
            the vocabulary.
    """
    if action is not None:
        if action not in ACTIONS:
            raise ValueError(f"action {action!r} is not one of {sorted(ACTIONS)}")
        return action
    first, two = _verb(prompt)
    verb = two or first
    if verb in SYNONYMS:
        return SYNONYMS[verb]
    raise ValueError(
        f"the prompt's verb {first!r} names no action: start the prompt with an action "
        f"({', '.join(sorted(ACTIONS))}) or a synonym of one (docs/scenarios.md: carry, put, "
        "take, lift, ...), or say `action:`"
    )
