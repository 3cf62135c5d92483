"""FACS action units as muscle activations, and AU recipes ("6:0.8,12:1.0").

Each action unit (Ekman, Friesen & Hager, *Facial Action Coding System*, 2002) is the set of movers
of :mod:`faceanim.synth.muscles` that produce it, with their activation at full intensity. Muscle
anatomy follows the FACS manual's table of AUs and muscles; placements and strengths were set from
that anatomy and then adjusted while comparing with ICT-FaceKit's FACS shapes
(``benchmarks/facs_ict.py``), which is where the amplitudes at intensity 1 come from.

Intensity is 0-1 (1 the strongest the face makes without strain); up to 2 is accepted as
exaggeration. FACS scores intensity with the letters A-E on an unequal scale, where the middle
grades span more than the ends (FACS 2002, ch. 2): here A is 0-0.15, B 0.15-0.35, C 0.35-0.65,
D 0.65-0.9 and E 0.9-1; a letter in a recipe stands for the middle of its range.

Sides: an AU the manual scores unilaterally takes ``L`` or ``R`` (the face's own left or right):
``12L:0.5`` is a half smile on the left. AU30 (jaw sideways) and AU46 (wink) need a side.
"""

from __future__ import annotations

import json
import re
import warnings
from collections.abc import Mapping
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from types import MappingProxyType

from ..errors import InputError
from .muscles import Gaze, Inflation, LinearMuscle, Rotator, Sphincter, Translator

__all__ = ["ActionUnit", "ACTION_UNITS", "MOVERS", "load_movers", "mover_from_spec", "INTENSITY_LETTERS",
           "parse_recipe", "recipe_text", "muscle_activations", "valid_codes", "check_intensity", "MAX_INTENSITY"]

_MOVER_TYPES = {cls.__name__: cls for cls in (LinearMuscle, Sphincter, Rotator, Gaze, Translator, Inflation)}


def mover_from_spec(spec: dict):
    spec = dict(spec)
    cls = _MOVER_TYPES[spec.pop("type")]
    spec.pop("paired")
    spec.pop("hand", None)  # the hand placement the calibration started from, kept for its bounds
    return cls(**{k: tuple(tuple(p) if isinstance(p, list) else p for p in v) if isinstance(v, list) else v
                  for k, v in spec.items()})


def load_movers(path=None) -> dict[str, tuple[object, bool]]:
    """The mover table ``{name: (mover, paired)}`` from ``data/movers.json`` (or ``path``)."""
    text = Path(path).read_text() if path else resources.files(__package__).joinpath("data/movers.json").read_text()
    return {name: (mover_from_spec(spec), bool(spec["paired"])) for name, spec in json.loads(text).items()}


# Movers of the face's left side (mirrored for the right) and whether a bilateral AU uses both sides.
# The table is data (``data/movers.json``): ``benchmarks/calibrate_muscles.py`` writes it.
MOVERS: dict[str, tuple[object, bool]] = load_movers()


@dataclass(frozen=True)
class ActionUnit:
    """An action unit: its FACS number and name, the movers that make it at intensity 1, and whether
    it is scored per side (``sided``) or must be (``needs_side``)."""

    number: int
    name: str
    movers: tuple
    sided: bool = True
    needs_side: bool = False


_AUS = (
    ActionUnit(1, "Inner brow raiser", (("frontalis_medial", 1.0),)),
    ActionUnit(2, "Outer brow raiser", (("frontalis_lateral", 1.0),)),
    ActionUnit(4, "Brow lowerer", (("corrugator", 1.0), ("procerus", 0.7))),
    ActionUnit(5, "Upper lid raiser", (("lid_raise", 1.0),)),
    ActionUnit(6, "Cheek raiser", (("oculi_orbital", 1.0),)),
    ActionUnit(7, "Lid tightener", (("oculi_palpebral", 1.0),)),
    ActionUnit(9, "Nose wrinkler", (("levator_nasi", 1.0), ("procerus", 0.3), ("levator_labii", 0.2))),
    ActionUnit(10, "Upper lip raiser", (("levator_labii", 1.0),)),
    ActionUnit(11, "Nasolabial deepener", (("zygomatic_minor", 1.0),)),
    ActionUnit(12, "Lip corner puller", (("zygomatic_major", 1.0),)),
    ActionUnit(14, "Dimpler", (("buccinator", 1.0),)),
    ActionUnit(15, "Lip corner depressor", (("triangularis", 1.0),)),
    ActionUnit(16, "Lower lip depressor", (("depressor_labii", 1.0),)),
    ActionUnit(17, "Chin raiser", (("mentalis", 1.0),), sided=False),
    ActionUnit(18, "Lip pucker", (("oris_pucker", 1.0),), sided=False),
    ActionUnit(20, "Lip stretcher", (("risorius", 1.0),)),
    ActionUnit(22, "Lip funneler", (("oris_funnel", 1.0),), sided=False),
    ActionUnit(23, "Lip tightener", (("oris_tighten", 1.0),), sided=False),
    ActionUnit(24, "Lip pressor", (("oris_press", 1.0), ("jaw_open", -0.3), ("mentalis", 0.4)), sided=False),
    ActionUnit(25, "Lips part", (("jaw_open", 0.2), ("depressor_labii", 0.4)), sided=False),
    ActionUnit(26, "Jaw drop", (("jaw_open", 1.0),), sided=False),
    ActionUnit(27, "Mouth stretch", (("jaw_open", 2.4), ("risorius", 0.3)), sided=False),
    ActionUnit(28, "Lip suck", (("oris_suck", 1.0),), sided=False),
    ActionUnit(29, "Jaw thrust", (("jaw_thrust", 1.0),), sided=False),
    ActionUnit(30, "Jaw sideways", (("jaw_sideways", 1.0),), needs_side=True),
    ActionUnit(33, "Cheek blow", (("cheek_blow", 1.0), ("lips_blow", 1.0))),
    ActionUnit(43, "Eyes closed", (("lid_close", 0.9), ("lower_lid_raise", 0.1))),
    ActionUnit(45, "Blink", (("lid_close", 0.9), ("lower_lid_raise", 0.1))),
    ActionUnit(46, "Wink", (("lid_close", 0.9), ("lower_lid_raise", 0.1)), needs_side=True),
    ActionUnit(61, "Eyes turn left", (("gaze_left", 1.0),), sided=False),
    ActionUnit(62, "Eyes turn right", (("gaze_left", -1.0),), sided=False),
    ActionUnit(63, "Eyes up", (("gaze_up", 1.0),), sided=False),
    ActionUnit(64, "Eyes down", (("gaze_up", -1.0),), sided=False),
)
ACTION_UNITS: Mapping[int, ActionUnit] = MappingProxyType({au.number: au for au in _AUS})  # read-only tables

INTENSITY_LETTERS = MappingProxyType({"A": (0.0, 0.15), "B": (0.15, 0.35), "C": (0.35, 0.65), "D": (0.65, 0.9),
                                      "E": (0.9, 1.0)})
MAX_INTENSITY = 2.0
_CODE = re.compile(r"^(?:AU)?0*(\d+)([LR]?)$", re.IGNORECASE)


def valid_codes() -> str:
    """The AU codes a recipe may name, as one line."""
    return ", ".join(f"{n}{'(L/R)' if au.sided or au.needs_side else ''}" for n, au in ACTION_UNITS.items())


def _split_code(code: str) -> tuple[int, str]:
    match = _CODE.match(code.strip())
    if not match or int(match.group(1)) not in ACTION_UNITS:
        raise InputError(f"unknown action unit {code.strip()!r}; valid: {valid_codes()}")
    number, side = int(match.group(1)), match.group(2).upper()
    au = ACTION_UNITS[number]
    if side and not (au.sided or au.needs_side):
        raise InputError(f"AU{number} ({au.name}) has no left/right variants; write {number} without L or R")
    if au.needs_side and not side:
        raise InputError(f"AU{number} ({au.name}) needs a side: {number}L or {number}R")
    return number, side


def _intensity(text: str, code: str) -> float:
    text = text.strip()
    if text.upper() in INTENSITY_LETTERS:
        low, high = INTENSITY_LETTERS[text.upper()]
        return 0.5 * (low + high)
    try:
        value = float(text)
    except ValueError:
        raise InputError(f"AU{code}: intensity {text!r} is neither a number nor a FACS letter A-E") from None
    return value


def check_intensity(value: float, what: str) -> float:
    """Reject intensities outside [0, 2]; warn above 1 (exaggeration)."""
    if not 0.0 <= value <= MAX_INTENSITY:
        raise InputError(f"{what}: intensity {value:g} is outside [0, {MAX_INTENSITY:g}]")
    if value > 1.0:
        warnings.warn(f"{what}: intensity {value:g} is above 1, an exaggeration beyond what a face does",
                      stacklevel=3)
    return float(value)


def parse_recipe(text) -> dict[str, float]:
    """AU recipe ``"6:0.8,12:1.0"`` (or a mapping) as ``{"6": 0.8, "12": 1.0}``.

    Codes may carry ``AU``, leading zeros and a side (``AU06``, ``12L``); intensities are numbers in
    [0, 2] or FACS letters A-E. A code repeated adds up.

    >>> parse_recipe("AU06:0.8, 12L:C")
    {'6': 0.8, '12L': 0.5}
    """
    items = text.items() if isinstance(text, Mapping) else [
        part.split(":", 1) if ":" in part else (part, "") for part in str(text).split(",") if part.strip()]
    recipe: dict[str, float] = {}
    for code, value in items:
        number, side = _split_code(str(code))
        key = f"{number}{side}"
        if isinstance(value, str):
            if not value.strip():
                raise InputError(f"AU{key}: give an intensity, like {key}:0.5")
            value = _intensity(value, key)
        recipe[key] = recipe.get(key, 0.0) + float(value)
    if not recipe:
        raise InputError("the AU recipe is empty; write it like 6:0.8,12:1.0")
    for key, value in recipe.items():
        check_intensity(value, f"AU{key}")
    return recipe


def recipe_text(recipe: dict) -> str:
    """The recipe in the form :func:`parse_recipe` reads: ``"6:0.80,12:1.00"``."""
    return ",".join(f"{code}:{value:.2f}" for code, value in recipe.items())


def muscle_activations(recipe: dict) -> dict[tuple[str, str], float]:
    """``{(mover, side): activation}`` of a parsed recipe; movers shared by AUs add up."""
    out: dict[tuple[str, str], float] = {}
    for key, intensity in recipe.items():
        number, side = _split_code(key)
        for mover, scale in ACTION_UNITS[number].movers:
            paired = MOVERS[mover][1]
            sides = (side,) if side else (("L", "R") if paired else ("L",))
            for s in sides:
                out[(mover, s)] = out.get((mover, s), 0.0) + scale * intensity
    return out
