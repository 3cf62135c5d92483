"""Teeth, gums and tongue split between the skull and the jaw, along a bite line fitted through them;
the jaw's turning centre behind the last lower teeth."""

from __future__ import annotations

import numpy as np

from ..geometry.mesh import Mesh
from ..geometry.topology import component_labels
from .faceparts import _ROLE
from .frame import _Frame


def _teeth_pieces(mesh: Mesh, kind: np.ndarray, frame: _Frame):
    """The whole pieces of teeth found by place or name (vertex ids each) and their centres (face frame)."""
    part = component_labels(mesh)
    mouth = np.flatnonzero(kind == "rigid")
    pieces = [mouth[part[mouth] == k] for k in np.unique(part[mouth])]
    centres = np.array([frame.local(mesh.vertices[p].mean(axis=0)[None])[0] for p in pieces]).reshape(-1, 3)
    return pieces, centres


def _fitted_bite(centres: np.ndarray, frame: _Frame):
    """The bite line through the teeth pieces' centres, or None where they are one set (all at one height)."""
    if len(centres) >= 2 and np.ptp(centres[:, 1]) > 0.1 * frame.mouth_width:
        return _bite_line(centres[:, 2], centres[:, 1])
    return None


def _bite_line(z: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    """The line ``y = a + b z`` between the upper and the lower pieces (centres ``(z, y)``): two
    groups by height (Otsu), then a line fitted through each and their mean taken as the boundary,
    regrouping until stable (a back molar of the lower arch sits higher than a front tooth of the
    upper one, so no single height splits them)."""
    order = np.sort(y)
    spread = [k * order[:k].var() + (len(order) - k) * order[k:].var() for k in range(1, len(order))]
    k = int(np.argmin(spread)) + 1
    a, b = 0.5 * (order[k - 1] + order[k]), 0.0
    for _ in range(10):
        upper = y > a + b * z
        if upper.sum() < 2 or (~upper).sum() < 2:
            break
        lines = [np.polyfit(z[group], y[group], 1) if np.ptp(z[group]) > 0 else (0.0, y[group].mean())
                 for group in (upper, ~upper)]
        a, b = 0.5 * (lines[0][1] + lines[1][1]), 0.5 * (lines[0][0] + lines[1][0])
        if np.array_equal(upper, y > a + b * z):
            break
    return float(a), float(b)


def _split_teeth(mesh: Mesh, role: np.ndarray, kind: np.ndarray, jaw: np.ndarray, frame: _Frame, pieces,
                 centres, *, fitted: bool) -> None:
    """Teeth, gums and tongue to the skull or the jaw (``role``, ``jaw`` filled in): whole pieces by
    their centres against ``frame.bite`` (``fitted`` through them), pieces that straddle the bite
    vertex by vertex, a set of teeth alone by whether it reaches above the lips' meeting."""
    given = np.flatnonzero(kind == "given")
    jaw[given] = role[given] == _ROLE["lower_teeth"]
    band = 0.1 * frame.mouth_width
    for piece, centre in zip(pieces, centres, strict=True):
        local = frame.local(mesh.vertices[piece])
        above = local[:, 1] - frame.bite[1] * local[:, 2] - frame.bite[0]
        if min((above > band).mean(), (above < -band).mean()) > 0.25:
            weight = frame.below_bite(mesh.vertices[piece])  # gums and tongue in one piece
            kind[piece] = "split"
            jaw[piece] = weight
            role[piece] = np.where(weight >= 0.5, _ROLE["lower_teeth"], _ROLE["upper_teeth"])
            continue
        if fitted:
            lower = centre[1] < frame.bite[0] + frame.bite[1] * centre[2]
        else:  # one set of teeth alone: upper if it reaches above the lips' meeting (the skull holds it)
            lower = local[:, 1].max() < frame.bite[0]
        role[piece] = _ROLE["lower_teeth" if lower else "upper_teeth"]
        jaw[piece] = float(lower)


def _centre_behind_the_teeth(mesh: Mesh, lower: np.ndarray, frame: _Frame):
    """Where the lower teeth are known, the jaw's turning centre behind the last of them, level with
    the bite there (face frame), or None to keep it: the ramus rises behind the molars, and a centre
    in front of them would lift the back molars as the jaw opens. Feature points placed on a
    silhouette (the jaw's corners) say little about depth."""
    if not lower.any():
        return None
    local = frame.local(mesh.vertices[lower])
    back = local[:, 2].min() - 0.25 * frame.mouth_width
    if back >= frame.hinge_local[2]:
        return None
    return np.array([frame.hinge_local[0], frame.bite[0] + frame.bite[1] * local[:, 2].min(), back])
