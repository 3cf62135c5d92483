"""AU recipes made on a face: displacement fields, with the lips and lids kept apart.

Linear muscles, sphincters and the cheek's air are linear in their activation, and the jaw and lids
turn; an expression is the sum of its movers' fields, each mover applied once with the activation
all the recipe's AUs give it. Exaggeration (intensity above 1) is kept plausible by
:func:`synthesise`'s guard: where a recipe would close a lid past the other lid or push one lip
through the other, the part of each intensity above 1 is scaled back until it does not.
"""

from __future__ import annotations

import warnings

import numpy as np

from .face import MuscleFace
from .facs import MOVERS, muscle_activations

__all__ = ["expression_field", "synthesise", "au_fields", "crossings", "resolve_contact", "CONTACT_PAIRS"]

# Feature points that face each other across an opening (upper, lower): the lids and the inner lips.
CONTACT_PAIRS = (("3.1", "3.3"), ("3.2", "3.4"), ("2.2", "2.3"), ("2.6", "2.8"), ("2.7", "2.9"))
_TOLERANCE = 0.004  # ES0: a pair may touch, not cross


def expression_field(face: MuscleFace, recipe: dict) -> np.ndarray:
    """``(V, 3)`` displacement of every vertex under ``recipe`` (parsed, ``{"12": 1.0}``), model units."""
    field = np.zeros((len(face.mesh.vertices), 3))
    for (mover, side), activation in muscle_activations(recipe).items():
        if activation:
            field += MOVERS[mover][0].displacement(face, activation, side)
    return field


def _overlaps(face: MuscleFace, field: np.ndarray, pairs) -> dict[str, float]:
    """For each of ``pairs`` the target has: how far (model units, along the face's up axis) ``field``
    has pushed the upper point below the lower one, beyond where it was at rest (<= 0: not crossed)."""
    up = face.axes[1]
    out = {}
    for upper, lower in pairs:
        if upper in face.target.points and lower in face.target.points:
            i, j = face.target.points[upper], face.target.points[lower]
            rest = (face.mesh.vertices[i] - face.mesh.vertices[j]) @ up
            moved = rest + (field[i] - field[j]) @ up
            out[f"{upper}/{lower}"] = min(rest, 0.0) - moved
    return out


def crossings(face: MuscleFace, field: np.ndarray) -> list[str]:
    """The contact pairs that ``field`` pushes through each other by more than the tolerance."""
    return [pair for pair, depth in _overlaps(face, field, CONTACT_PAIRS).items() if depth > _TOLERANCE * face.unit]


def _overlap(face: MuscleFace, field: np.ndarray, pairs) -> float:
    """The deepest crossing among ``pairs`` (0 when none crossed)."""
    return max([0.0, *_overlaps(face, field, pairs).values()])


def resolve_contact(face: MuscleFace, field: np.ndarray) -> np.ndarray:
    """``field`` with lips and lids that were pushed through each other stopped where they meet.

    Lips already together cannot close further (pressing, a raised chin or a clenched jaw only
    squeeze them): the lower lip's layer (the jaw's weight field) is moved back down by the overlap.
    A lid closed past the other is moved back up over the upper lid's weight field.
    """
    out = field.copy()
    up = face.axes[1]
    lips = _overlap(face, out, CONTACT_PAIRS[2:])
    if lips > 0:
        out[face.skin_ids] -= lips * face.jaw_weight[:, None] * up
    for side, pair in (("L", CONTACT_PAIRS[0]), ("R", CONTACT_PAIRS[1])):
        lid = _overlap(face, out, (pair,))
        if lid > 0:
            out[face.skin_ids] += lid * face.lid_weight(side, "upper")[:, None] * up
    return out


def synthesise(face: MuscleFace, recipe: dict, *, guard: bool = True) -> tuple[np.ndarray, dict]:
    """The displacement field of ``recipe`` and the recipe actually made.

    With ``guard``, intensities above 1 that would push a lid or lip through its partner (see
    :func:`crossings`) are scaled back toward 1 (bisection on the excess) and a warning says so;
    what still overlaps at the normal range (lips pressed that were already together) is stopped at
    contact (:func:`resolve_contact`).
    """
    field = expression_field(face, recipe)
    if not guard or not crossings(face, field):
        return field, dict(recipe)
    base = {k: min(v, 1.0) for k, v in recipe.items()}
    excess = {k: v - base[k] for k, v in recipe.items()}

    def scaled(s):
        return {k: base[k] + s * excess[k] for k in recipe}

    low, high = 0.0, 1.0
    if crossings(face, expression_field(face, base)):  # crossing within the normal range: contact, not excess
        return resolve_contact(face, field), dict(recipe)
    for _ in range(12):
        mid = 0.5 * (low + high)
        if crossings(face, expression_field(face, scaled(mid))):
            high = mid
        else:
            low = mid
    made = scaled(low)
    warnings.warn("exaggeration limited to keep the lips and lids from crossing: "
                  + ", ".join(f"AU{k} {recipe[k]:.2f}->{made[k]:.2f}" for k in recipe if made[k] != recipe[k]),
                  stacklevel=2)
    return expression_field(face, made), made


def au_fields(face: MuscleFace, codes) -> np.ndarray:
    """``(K, V, 3)`` the field of each AU code at intensity 1 (morph targets, a fitting basis)."""
    return np.stack([expression_field(face, {code: 1.0}) for code in codes])
