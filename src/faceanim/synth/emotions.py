"""The six basic emotions as AU recipes, with their sources.

The six are MPEG-4's ``expression_select`` 1-6 (shared/mpeg4/expressions.csv, the standard's
Annex 3 words: joy, sadness, anger, fear, disgust, surprise). Their action units are the prototypes
of EMFACS (Friesen & Ekman 1983), as tabulated in the FACS Investigator's Guide (Ekman, Friesen &
Hager 2002, Table 10-1); where the MPEG-4 description asks for a movement the prototype leaves out,
the AU that makes it is added and the reason given. Intensities follow the prototypes' letters
(B for AU5 in surprise), otherwise the middle-to-high grades a posed expression shows.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType

from ..errors import InputError
from .facs import check_intensity

__all__ = ["Emotion", "EMOTIONS", "emotion_recipe"]


@dataclass(frozen=True)
class Emotion:
    """An emotion's AU recipe (code -> intensity, read-only) and where the recipe comes from."""

    name: str
    recipe: Mapping[str, float]
    source: str

    def __post_init__(self):
        object.__setattr__(self, "recipe", MappingProxyType(dict(self.recipe)))


EMOTIONS: Mapping[str, Emotion] = MappingProxyType({e.name: e for e in (
    Emotion("joy", {"6": 0.8, "12": 1.0, "25": 0.5},
            "EMFACS 6+12; MPEG-4 Annex 3 'the mouth is open' adds 25"),
    Emotion("sadness", {"1": 0.8, "4": 0.5, "15": 0.8, "17": 0.3, "43": 0.2},
            "EMFACS 1+4+15 (17 in its variant); MPEG-4 'the eyes are slightly closed' adds 43 at A-B"),
    Emotion("anger", {"4": 0.9, "5": 0.5, "7": 0.7, "23": 0.8, "24": 0.5},
            "EMFACS 4+5+7+23; MPEG-4 'the lips are pressed against each other' adds 24"),
    Emotion("fear", {"1": 0.8, "2": 0.6, "4": 0.5, "5": 0.8, "7": 0.3, "20": 0.7, "26": 0.5},
            "EMFACS 1+2+4+5+7+20+26"),
    Emotion("disgust", {"9": 0.8, "10": 0.6, "15": 0.5, "16": 0.4},
            "EMFACS 9+15+16; MPEG-4 'the upper lip is raised' adds 10"),
    Emotion("surprise", {"1": 0.9, "2": 0.9, "5": 0.25, "26": 0.8},
            "EMFACS 1+2+5B+26; MPEG-4 'the jaw is opened'"),
)})


def emotion_recipe(name: str, intensity: float = 1.0) -> dict:
    """The AU recipe of emotion ``name`` at ``intensity`` (each AU scaled; above 1 is exaggeration).

    >>> emotion_recipe("joy", 0.5)
    {'6': 0.4, '12': 0.5, '25': 0.25}
    """
    key = str(name).strip().lower()
    if key not in EMOTIONS:
        raise InputError(f"unknown emotion {name!r}; valid: {', '.join(EMOTIONS)}")
    check_intensity(float(intensity), f"--intensity for {key}")
    return {code: value * float(intensity) for code, value in EMOTIONS[key].recipe.items()}
