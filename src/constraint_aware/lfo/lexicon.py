"""From words to a constraint type and a grasp: the documented lexicon and grasp table.

Constraint type from the instruction (paper section 4): each object noun and each verb votes.
Nouns are the stronger evidence ("open" fits drawers and doors alike), so a known noun decides
and the verb only breaks a tie; unknown words give "unknown", never a guess.

| words                                   | constraint |
|-----------------------------------------|------------|
| drawer, plate, tray, pole, rod, slider,  | prismatic  |
| sliding door, window (sash)              |            |
| door, lid, handle, crank, knob, valve,  | revolute   |
| wheel, lever, flap, gate                 |            |
| verbs slide, pull out, push in           | prismatic  |
| verbs rotate, turn, swing, crank         | revolute   |
| verbs open, close, pull, push, move      | (neutral)  |

Grasp (force-exertion type, Saito et al. 2022) from the object, else from the constraint:

| object                                  | force-exertion type     | fixed orientation |
|-----------------------------------------|-------------------------|-------------------|
| drawer, door, gate, sliding door, flap, | lazy closure            | no                |
| lid, window (a hooked bar or lip)       |                         |                   |
| pole, rod, lever                        | active-force closure    | no                |
| plate, tray                             | passive-force closure   | no                |
| handle, crank, knob, valve, wheel       | passive-force closure   | yes               |
"""

from __future__ import annotations

import re
from dataclasses import dataclass

PRISMATIC_NOUNS = ("sliding door", "drawer", "plate", "tray", "pole", "rod", "slider", "window")
REVOLUTE_NOUNS = (
    "door", "lid", "handle", "crank", "knob", "valve", "wheel", "lever", "flap", "gate",
)  # fmt: skip
PRISMATIC_VERBS = ("pull out", "push in", "slide")
REVOLUTE_VERBS = ("rotate", "turn", "swing", "crank")
NEUTRAL_VERBS = ("open", "close", "pull", "push", "move")

GRASP_TABLE: dict[str, tuple[str, bool]] = {
    "drawer": ("lazy_closure", False),
    "door": ("lazy_closure", False),
    "sliding door": ("lazy_closure", False),
    "gate": ("lazy_closure", False),
    "flap": ("lazy_closure", False),
    "window": ("lazy_closure", False),
    "pole": ("active_force_closure", False),
    "rod": ("active_force_closure", False),
    "lever": ("active_force_closure", False),
    "slider": ("active_force_closure", False),
    "plate": ("passive_force_closure", False),
    "tray": ("passive_force_closure", False),
    "handle": ("passive_force_closure", True),
    "crank": ("passive_force_closure", True),
    "knob": ("passive_force_closure", True),
    "valve": ("passive_force_closure", True),
    "wheel": ("passive_force_closure", True),
    "lid": ("lazy_closure", False),
}
DEFAULT_GRASP = {"prismatic": ("lazy_closure", False), "revolute": ("lazy_closure", False)}


@dataclass(frozen=True)
class WordEvidence:
    constraint: str  # "prismatic", "revolute" or "unknown"
    noun: str | None  # the object noun that was recognised
    verb: str | None
    reason: str


def _find(text: str, words: tuple[str, ...]) -> str | None:
    for w in sorted(words, key=len, reverse=True):  # "sliding door" before "door"
        if re.search(rf"\b{re.escape(w)}s?\b", text):
            return w
    return None


def constraint_from_words(instruction: str, object_name: str = "") -> WordEvidence:
    """The constraint type the words suggest, with the words that decided it."""
    text = f"{instruction} {object_name}".lower()
    noun_p = _find(text, PRISMATIC_NOUNS)
    noun_r = _find(text, REVOLUTE_NOUNS)
    # "sliding door" contains "door": the longer prismatic phrase wins
    if noun_p and noun_r and noun_r in noun_p:
        noun_r = None
    verb_p = _find(text, PRISMATIC_VERBS)
    verb_r = _find(text, REVOLUTE_VERBS)
    verb = verb_p or verb_r or _find(text, NEUTRAL_VERBS)
    if noun_p and not noun_r:
        return WordEvidence("prismatic", noun_p, verb, f"object '{noun_p}' slides on a guide")
    if noun_r and not noun_p:
        return WordEvidence("revolute", noun_r, verb, f"object '{noun_r}' turns on a hinge")
    if verb_p and not verb_r:
        return WordEvidence("prismatic", noun_p or noun_r, verb_p, f"verb '{verb_p}'")
    if verb_r and not verb_p:
        return WordEvidence("revolute", noun_p or noun_r, verb_r, f"verb '{verb_r}'")
    if noun_p and noun_r:
        return WordEvidence("unknown", noun_p, verb, f"words name both '{noun_p}' and '{noun_r}'")
    return WordEvidence("unknown", None, verb, "no known object or verb in the words")


def grasp_for(noun: str | None, constraint: str) -> tuple[str, bool, str]:
    """(force-exertion type, fixed orientation, source) from the grasp table."""
    if noun is not None and noun in GRASP_TABLE:
        g, fixed = GRASP_TABLE[noun]
        return g, fixed, f"grasp table: {noun}"
    g, fixed = DEFAULT_GRASP.get(constraint, ("lazy_closure", False))
    return g, fixed, f"default for a {constraint} constraint"


#: The simulated object kind (sim.tasks.KINDS) each noun names; a noun whose kind contradicts
#: the geometry is overruled by it (lfo/scene.py).
NOUN_KINDS: dict[str, str] = {
    "drawer": "drawer", "sliding door": "drawer", "slider": "pole",
    "plate": "plate", "tray": "plate",
    "pole": "pole", "rod": "pole",
    "window": "window",
    "door": "door", "gate": "door", "flap": "lid", "lid": "lid",
    "handle": "crank", "crank": "crank", "knob": "crank", "valve": "crank", "wheel": "crank",
}  # fmt: skip

#: How large each noun's motion is, to judge a demonstration's unit (lfo/plausibility.py):
#: (what is measured, low, high [m]): the handle's travel on a slide or its radius about a
#: hinge. The bounds are what the objects measure: drawers travel up to their full extension
#: (~0.6 m for a deep one); a door's handle sits at most the widest leaves' 1.2 m from the
#: hinge; gates are wider; cranks, knobs, valves and wheels are turned at 1-50 cm.
NOUN_SIZES: dict[str, tuple[str, float, float]] = {
    "drawer": ("travel", 0.05, 0.7), "sliding door": ("travel", 0.1, 1.5),
    "plate": ("travel", 0.03, 1.0), "tray": ("travel", 0.03, 1.0),
    "pole": ("travel", 0.03, 1.0), "rod": ("travel", 0.03, 1.0),
    "slider": ("travel", 0.03, 1.0), "window": ("travel", 0.05, 1.5),
    "door": ("radius", 0.1, 1.2), "gate": ("radius", 0.3, 2.5), "lid": ("radius", 0.1, 1.0),
    "flap": ("radius", 0.05, 1.0), "lever": ("radius", 0.05, 1.0),
    "handle": ("radius", 0.01, 0.5), "crank": ("radius", 0.01, 0.5),
    "knob": ("radius", 0.01, 0.5), "valve": ("radius", 0.01, 0.5),
    "wheel": ("radius", 0.01, 0.5),
}  # fmt: skip

#: Verbs that say which way the object moves: opening pulls the handle (toward the palm's back,
#: against the palm normal) or raises it; closing pushes or lowers it.
OPENING_VERBS = ("open", "pull out", "pull", "lift", "raise")
CLOSING_VERBS = ("close", "shut", "push in", "push", "lower")


def verb_sense(instruction: str) -> str | None:
    """ "open", "close" or None: the sense of motion the instruction asks for."""
    text = instruction.lower()
    opening, closing = _find(text, OPENING_VERBS), _find(text, CLOSING_VERBS)
    if opening and not closing:
        return "open"
    if closing and not opening:
        return "close"
    return None
