"""Action-unit intensities read from motion: bounded least squares on the muscles' own AU basis.

The basis is what :mod:`faceanim.synth` makes: every AU at intensity 1 on the same face whose
control points moved, so reading and making an expression share one model. Each frame solves

    min_x ||B x - d||^2 + ridge ||x||^2,   0 <= x <= 2

(``scipy.optimize.lsq_linear``). The ridge keeps AUs with nearly the same pattern (pucker and
funneler, jaw drop and mouth stretch) from trading large values, which decides which AU is read;
its shrinkage is then undone by one common factor (:meth:`AuFitter._rescale`). A sparsity term
(an L1 penalty) was tried as well and read back fewer ICT shapes correctly (64% against 84%).
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import lsq_linear

from ..motion import Motion
from .expression import au_fields
from .face import MuscleFace
from .facs import ACTION_UNITS, MAX_INTENSITY

__all__ = ["FIT_CODES", "AuFitter", "bilateral", "CSV_AUS"]

# The AUs the fitter reads, per side where FACS scores sides. AU43 and AU45 have one shape (they
# differ in timing) and AU46 is AU45 on one side, so only AU45 (per side) is read.
FIT_CODES = tuple(
    code for number, au in ACTION_UNITS.items() if number not in (43, 46)
    for code in ((f"{number}L", f"{number}R") if au.sided or au.needs_side else (str(number),)))
CSV_AUS = tuple(n for n in ACTION_UNITS if n not in (43, 46))


class AuFitter:
    """Fits AU intensities to displacements of a face's control points.

    Parameters
    ----------
    face : MuscleFace
        The face whose control points moved (its rest shape is the motion's neutral).
    names : sequence of str
        The control points the displacements are given for (names in ``face.target.points``).
    codes : sequence of str
        AU codes to read (default :data:`FIT_CODES`).
    ridge : float
        Weight of the ridge, relative to the basis' mean squared column norm.

    ``__call__(displacements (T, K, 3))`` returns intensities ``(T, len(codes))`` in [0, 2].
    """

    def __init__(self, face: MuscleFace, names, *, codes=FIT_CODES, ridge: float = 0.1):
        self.codes = tuple(codes)
        self.names = tuple(names)
        ids = face.target.ids(self.names)
        fields = au_fields(face, self.codes)[:, ids]          # (A, K, 3)
        self.basis = fields.reshape(len(self.codes), -1).T     # (3K, A)
        scale = float((self.basis ** 2).sum(axis=0).mean())
        self._system = np.vstack([self.basis, np.sqrt(ridge * scale) * np.eye(len(self.codes))])

    def __call__(self, displacements) -> np.ndarray:
        d = np.asarray(displacements, dtype=np.float64)
        single = d.ndim == 2
        d = d[None] if single else d
        out = np.full((len(d), len(self.codes)), np.nan)
        for t, frame in enumerate(d):
            if np.isfinite(frame).all():
                b = np.r_[frame.ravel(), np.zeros(len(self.codes))]
                x = lsq_linear(self._system, b, bounds=(0.0, MAX_INTENSITY), method="bvls").x
                out[t] = self._rescale(frame.ravel(), x)
        return out[0] if single else out

    def _rescale(self, d: np.ndarray, x: np.ndarray) -> np.ndarray:
        """The penalised fit's AUs and their proportions, rescaled as a whole to fit the motion
        best: the ridge shrinks every intensity (a full AU would read well below 1), and one common
        factor undoes that without letting similar AUs trade places again."""
        predicted = self.basis @ x
        norm = predicted @ predicted
        if norm <= 0:
            return x
        return np.clip(x * max(predicted @ d / norm, 0.0), 0.0, MAX_INTENSITY)

    def read_motion(self, motion: Motion) -> np.ndarray:
        """``(T, A)`` intensities of ``motion`` (its points named as ``names``); NaN on frames without
        a face. (The capture's filter has already smoothed the points; the pipeline smooths these.)"""
        at = motion.index(self.names)
        out = np.empty((len(motion), len(self.codes)))
        for start, d in motion.chunks():  # a chunk at a time: a streamed motion's frames stay on disk
            valid = motion.valid[start:start + len(d), None, None]
            out[start:start + len(d)] = self(np.where(valid, d[:, at], np.nan))
        return out


def bilateral(codes, intensities) -> tuple[tuple[int, ...], np.ndarray]:
    """Per-AU intensities ``(T, len(CSV_AUS))`` from per-code ones: the mean of the two sides of a
    sided AU (a symmetric AU at 1 reads 1), the sum of AU30's two directions."""
    index = {c: i for i, c in enumerate(codes)}
    columns = []
    for number in CSV_AUS:
        sides = [index[c] for c in (f"{number}L", f"{number}R") if c in index]
        if number == 30:
            columns.append(intensities[:, sides].sum(axis=1))
        elif sides:
            columns.append(intensities[:, sides].mean(axis=1))
        else:
            columns.append(intensities[:, index[str(number)]])
    return CSV_AUS, np.stack(columns, axis=1)
