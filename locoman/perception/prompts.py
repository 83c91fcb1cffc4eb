"""Prompt augmentation (paper A, Sec. III-A.1).

The predicate is the first word of the subtask prompt; the static suffix asks the image model
for a full-body person, which contact transfer and retargeting need.
"""

from __future__ import annotations

from locoman.errors import ConfigError

TEMPLATE = (
    "A scene of person {gerund} {rest}. The person has dark hair and is wearing casual "
    "clothes such a shirt, jeans, and sneakers."
)
# Verbs whose -ing form the spelling rules below get wrong.
IRREGULAR_GERUNDS = {"lie": "lying", "die": "dying", "tie": "tying", "see": "seeing"}
_VOWELS = set("aeiou")


def gerund(verb: str) -> str:
    """The -ing form of an English verb: pick -> picking, place -> placing, step -> stepping.

    Rules: a final silent ``e`` drops (place -> placing, but not ``ee``/``ye``/``oe``); a
    one-syllable consonant-vowel-consonant verb doubles its last consonant (step ->
    stepping, grab -> grabbing), except after w, x and y (push -> pushing, fix -> fixing).
    """
    v = verb.lower()
    if not v.isalpha():
        raise ConfigError(f"predicate {verb!r} is not a word; a subtask prompt starts with a verb")
    if v in IRREGULAR_GERUNDS:
        return IRREGULAR_GERUNDS[v]
    if v.endswith("ie"):
        return v[:-2] + "ying"
    if v.endswith("e") and len(v) > 2 and not v.endswith(("ee", "ye", "oe")):
        return v[:-1] + "ing"
    vowel_groups = sum(
        1 for i, c in enumerate(v) if c in _VOWELS and (i == 0 or v[i - 1] not in _VOWELS)
    )
    if (
        vowel_groups == 1
        and len(v) >= 3
        and v[-1] not in _VOWELS | set("wxy")
        and v[-2] in _VOWELS
        and v[-3] not in _VOWELS
    ):
        return v + v[-1] + "ing"
    return v + "ing"


def augment_prompt(prompt: str) -> str:
    """The full-body prompt of paper A for a subtask prompt such as "pick up the box"."""
    words = prompt.strip().split()
    if len(words) < 2:
        raise ConfigError(f"subtask prompt {prompt!r} needs a predicate and an object")
    return TEMPLATE.format(gerund=gerund(words[0]), rest=" ".join(words[1:]))
