"""Rig names: ARKit and FACS AU names in the spellings tools use, and the table between the two.

Names are matched without regard to case or punctuation, with the spellings tools use:

* **ARKit** (:data:`~faceanim.rig.arkit.ARKIT_NAMES`): ``jawOpen``, ``JawOpen``, ``jaw_open``; a side
  as ``Left``/``Right`` or ``_L``/``_R`` (``eyeBlink_L``, ICT-FaceKit's); a prefix before a dot or an
  underscore is skipped (``blendShape1.jawOpen``, ``ARKit_jawOpen``). A side of a shape ARKit keeps
  whole (``browInnerUp_L``, ICT's halves) is its own shape (``browInnerUpLeft``) and takes the whole
  shape's weight when the weights come by name.
* **FACS**: ``AU12``, ``AU01``, ``au_12``, ``AU12L``/``AU12_R`` (the face's own side).

:data:`FACS_ARKIT` is the one table between the two vocabularies (after the usual ARKit-to-FACS
reading of Apple's shape descriptions): an AU's weight is the mean of its ARKit shapes' weights
(each side's for a sided AU), and an ARKit shape's weight is the largest of the AUs that make it.

The rig files themselves (reading a ``.glb``'s named targets, writing their animation) are
:mod:`faceanim.rig.rigfile`'s.
"""

from __future__ import annotations

import re
from types import MappingProxyType

import numpy as np

from .arkit import ARKIT_NAMES

__all__ = ["FACS_ARKIT", "EYES_AND_BROWS", "canonical_name", "whole_shape", "weights_by_name", "arkit_of_aus",
           "EXPECTED_NAMES"]

EXPECTED_NAMES = "ARKit blendshape names (jawOpen, eyeBlinkLeft, ...) or FACS AU names (AU12, AU01, ...)"

#: FACS AU (number, with ``L``/``R`` for a side) -> the ARKit shapes it is read as. Sided AUs list
#: their left shape first; ``AU12L`` is ``mouthSmileLeft``. AU25 (lips part) and AU23 (lip tightener)
#: have no ARKit shape and are not mapped.
FACS_ARKIT: MappingProxyType = MappingProxyType({
    "1": ("browInnerUp",), "2": ("browOuterUpLeft", "browOuterUpRight"), "4": ("browDownLeft", "browDownRight"),
    "5": ("eyeWideLeft", "eyeWideRight"), "6": ("cheekSquintLeft", "cheekSquintRight"),
    "7": ("eyeSquintLeft", "eyeSquintRight"), "9": ("noseSneerLeft", "noseSneerRight"),
    "10": ("mouthUpperUpLeft", "mouthUpperUpRight"), "12": ("mouthSmileLeft", "mouthSmileRight"),
    "14": ("mouthDimpleLeft", "mouthDimpleRight"), "15": ("mouthFrownLeft", "mouthFrownRight"),
    "16": ("mouthLowerDownLeft", "mouthLowerDownRight"), "17": ("mouthShrugLower",), "18": ("mouthPucker",),
    "19": ("tongueOut",), "20": ("mouthStretchLeft", "mouthStretchRight"), "22": ("mouthFunnel",),
    "24": ("mouthPressLeft", "mouthPressRight"), "26": ("jawOpen",), "27": ("jawOpen",),
    "28": ("mouthRollLower", "mouthRollUpper"), "29": ("jawForward",), "30L": ("jawLeft",), "30R": ("jawRight",),
    "33": ("cheekPuff",), "34": ("cheekPuff",), "43": ("eyeBlinkLeft", "eyeBlinkRight"),
    "45": ("eyeBlinkLeft", "eyeBlinkRight"), "46L": ("eyeBlinkLeft",), "46R": ("eyeBlinkRight",),
    "61": ("eyeLookOutLeft", "eyeLookInRight"), "62": ("eyeLookInLeft", "eyeLookOutRight"),
    "63": ("eyeLookUpLeft", "eyeLookUpRight"), "64": ("eyeLookDownLeft", "eyeLookDownRight"),
})

#: The shapes the tracker's blendshape scores lead in the video solve (the geometry reads them poorly).
EYES_AND_BROWS: frozenset = frozenset(
    [n + side for n in ARKIT_NAMES if n.startswith(("eyeBlink", "eyeLook", "eyeSquint", "eyeWide", "brow"))
     for side in ("", "Left", "Right") if side == "" or not n.endswith(("Left", "Right"))]
    + [f"AU{c}" for c in ("1", "2", "4", "5", "7", "43", "45", "46L", "46R", "61", "62", "63", "64")]
    + [f"AU{c}{s}" for c in ("1", "2", "4", "5", "7", "43", "45") for s in "LR"])


def _key(text: str) -> str:
    return re.sub(r"[^a-z0-9]", "", text.lower())


def _arkit_keys() -> dict[str, str]:
    keys = {}
    for name in ARKIT_NAMES:
        key = _key(name)
        keys[key] = name
        for side, short in (("left", "l"), ("right", "r")):
            if key.endswith(side) and name not in ("jawLeft", "jawRight", "mouthLeft", "mouthRight"):
                keys.setdefault(key[:-len(side)] + short, name)
    for name in ARKIT_NAMES:  # a side of a shape ARKit keeps whole: browInnerUp_L is browInnerUpLeft
        if not name.endswith(("Left", "Right")):
            for side, spelt in (("l", "Left"), ("r", "Right"), ("left", "Left"), ("right", "Right")):
                keys.setdefault(_key(name) + side, name + spelt)
    return keys


def whole_shape(name: str) -> str:
    """The ARKit shape a canonical name reads its weight from: ``browInnerUpLeft`` -> ``browInnerUp``
    (a side of a shape ARKit keeps whole); any other name is its own."""
    for side in ("Left", "Right"):
        if name.endswith(side) and name not in ARKIT_NAMES and name[:-len(side)] in ARKIT_NAMES:
            return name[:-len(side)]
    return name


_ARKIT_KEYS = _arkit_keys()
_AU = re.compile(r"^(?:au|actionunit)0*(\d{1,2})(l|r|left|right)?$")


def canonical_name(name: str) -> str | None:
    """The ARKit name (``jawOpen``) or AU code (``AU12``, ``AU12L``) a morph target's name stands for,
    None when it is neither (see the module's notes for the spellings).

    >>> [canonical_name(n) for n in ("JawOpen", "eyeBlink_L", "blendShape1.mouthSmileRight", "AU01", "au_12_r",
    ...                              "browInnerUp_R", "shape00")]
    ['jawOpen', 'eyeBlinkLeft', 'mouthSmileRight', 'AU1', 'AU12R', 'browInnerUpRight', None]
    """
    candidates = [name, name.rsplit(".", 1)[-1]]
    tokens = re.split(r"[._:|]", name)
    candidates += ["_".join(tokens[i:]) for i in range(1, len(tokens))]
    for text in candidates:
        key = _key(text)
        if key in _ARKIT_KEYS:
            return _ARKIT_KEYS[key]
        match = _AU.match(key)
        if match:
            side = (match.group(2) or "")[:1].upper()
            return f"AU{int(match.group(1))}{side}"
    return None


def arkit_of_aus(aus: dict) -> dict[str, np.ndarray]:
    """ARKit weights from AU intensities ``{"12": (T,), "30L": (T,), ...}`` (0-1) through
    :data:`FACS_ARKIT`: each ARKit shape the largest of the AUs that make it (a bilateral AU's value
    on both sides; a sided one, ``12L``, on its side's shape only). Shapes no AU makes are absent."""
    out: dict[str, np.ndarray] = {}
    for code, values in aus.items():
        number, side = (code[:-1], code[-1]) if code[-1:] in ("L", "R") else (code, "")
        shapes = FACS_ARKIT.get(code) or FACS_ARKIT.get(number) or ()
        if side and code not in FACS_ARKIT:
            shapes = [s for s in shapes if not s.endswith("Left" if side == "R" else "Right")]
        for shape in shapes:
            value = np.asarray(values, dtype=np.float64)
            out[shape] = value if shape not in out else np.maximum(out[shape], value)
    return out


def weights_by_name(canonical, *, arkit: dict | None = None, aus: dict | None = None, length: int) -> np.ndarray:
    """``(T, len(canonical))`` weights for targets of these canonical names from ``arkit`` (``{name:
    (T,)}``) or ``aus`` (``{"12": (T,), "12L": ...}``, 0-1), through :data:`FACS_ARKIT` where the
    vocabularies differ; clipped to [0, 1]; a target nothing drives (or None) stays 0."""
    arkit = dict(arkit or {})
    aus = dict(aus or {})
    if aus:
        arkit = {**arkit_of_aus(aus), **arkit}
    out = np.zeros((length, len(canonical)))
    for j, name in enumerate(canonical):
        if name is None:
            continue
        if name.startswith("AU"):
            code = name[2:]
            number = code[:-1] if code[-1:] in ("L", "R") else code
            if code in aus:
                out[:, j] = aus[code]
            elif number in aus:
                out[:, j] = aus[number]
            else:
                shapes = FACS_ARKIT.get(code) or FACS_ARKIT.get(number) or ()
                if code != number and code not in FACS_ARKIT:  # a side of a bilateral AU: its side's shapes
                    shapes = [s for s in shapes if not s.endswith("Left" if code[-1] == "R" else "Right")]
                have = [arkit[s] for s in shapes if s in arkit]
                if have:
                    out[:, j] = np.mean(have, axis=0)
        elif whole_shape(name) in arkit:
            out[:, j] = arkit[whole_shape(name)]
    return np.clip(np.nan_to_num(out), 0.0, 1.0)
