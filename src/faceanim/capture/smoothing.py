"""Temporal filtering of tracked landmarks: the One Euro filter (one way, or both ways without lag), and the
jitter figure it is judged by."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["OneEuro", "OneEuroFilter", "one_euro", "one_euro_both_ways", "jitter"]


@dataclass(frozen=True)
class OneEuro:
    """Settings of the One Euro filter (Casiez, Roussel and Vogel, CHI 2012).

    A low-pass filter whose cut-off rises with speed: still faces are smoothed hard (``min_cutoff``
    Hz), fast motion passes with little lag (``beta`` Hz more per unit/s of speed). Defaults are
    for head-frame landmarks in centimetres at video rates.
    """

    min_cutoff: float = 1.5
    beta: float = 0.5
    d_cutoff: float = 1.0

    def __post_init__(self):
        for name in ("min_cutoff", "beta", "d_cutoff"):
            if not getattr(self, name) >= 0 or (name != "beta" and getattr(self, name) == 0):
                raise ValueError(f"{name} must be positive, got {getattr(self, name)}")


def _alpha(cutoff, dt):
    tau = 1.0 / (2 * np.pi * cutoff)
    return 1.0 / (1.0 + tau / dt)


class OneEuroFilter:
    """The One Euro filter run over a signal a block at a time: it carries its state from one block
    to the next, so a long capture is filtered as it streams, with the result :func:`one_euro` gives
    for the whole at once.

    >>> t = np.arange(10) / 30.0
    >>> x = np.random.default_rng(0).normal(size=(10, 4, 3))
    >>> run = OneEuroFilter()
    >>> bool(np.array_equal(np.concatenate([run(x[:3], t[:3]), run(x[3:], t[3:])]), one_euro(x, t)))
    True
    """

    def __init__(self, settings: OneEuro = OneEuro()):
        self.settings = settings
        self._previous = self._derivative = self._last_time = None

    def __call__(self, signal, times, *, out: np.ndarray | None = None) -> np.ndarray:
        """Filter the next frames ``signal (t, ...)`` at ``times (t,)`` seconds; ``out`` as for :func:`one_euro`."""
        x = np.asarray(signal, dtype=np.float64)
        times = np.asarray(times, dtype=np.float64)
        if out is None:
            out = np.empty_like(x)
        elif out.shape != x.shape or out.dtype != np.float64:
            raise ValueError(f"out must be a float64 array of shape {x.shape}, got {out.dtype} {out.shape}")
        settings = self.settings
        previous, derivative, last_time = self._previous, self._derivative, self._last_time
        for t in range(len(x)):
            if not np.isfinite(x[t]).all():
                previous = None
                out[t] = np.nan
                continue
            if previous is None:
                out[t], previous, derivative = x[t], x[t].copy(), np.zeros_like(x[t])
                last_time = times[t]
                continue
            dt = max(times[t] - last_time, 1e-6)
            last_time = times[t]
            a_d = _alpha(settings.d_cutoff, dt)
            derivative = a_d * (x[t] - previous) / dt + (1 - a_d) * derivative
            speed = np.linalg.norm(derivative, axis=-1, keepdims=True)
            a = _alpha(settings.min_cutoff + settings.beta * speed, dt)
            previous = a * x[t] + (1 - a) * previous
            out[t] = previous
        self._previous, self._derivative, self._last_time = previous, derivative, last_time
        return out


def one_euro(signal, times, settings: OneEuro = OneEuro(), *, out: np.ndarray | None = None) -> np.ndarray:
    """Filter ``signal (T, ...)`` sampled at ``times (T,)`` seconds; NaN frames restart the filter
    (and come out all NaN). ``out``, a float64 array of the signal's shape (the signal itself is
    allowed: each frame is read before it is written), receives the result.

    The speed that sets the cut-off is taken per point (the norm over the last axis), so the three
    coordinates of a landmark are filtered alike.

    >>> t = np.arange(100) / 30.0
    >>> x = np.ones((100, 1, 3))
    >>> bool(np.allclose(one_euro(x, t), 1.0))
    True
    """
    return OneEuroFilter(settings)(signal, times, out=out)


def one_euro_both_ways(signal, times, settings: OneEuro = OneEuro()) -> np.ndarray:
    """:func:`one_euro` run forward and backward in time, the two averaged: the lag of each way cancels
    the other's (a whole recording, where the frames after each one are known). A signal that is a
    straight line in time comes out unchanged away from its ends, where the one-way filter trails it.

    >>> t = np.arange(60) / 30.0
    >>> ramp = np.stack([t, 2 * t, -t], axis=-1)[:, None, :]
    >>> bool(np.allclose(one_euro_both_ways(ramp, t)[20:-20], ramp[20:-20], atol=1e-3))
    True
    >>> bool(np.allclose(one_euro(ramp, t)[20:-20], ramp[20:-20], atol=1e-3))
    False
    """
    x = np.asarray(signal, dtype=np.float64)
    times = np.asarray(times, dtype=np.float64)
    forward = one_euro(x, times, settings)
    backward = one_euro(x[::-1], -times[::-1], settings)[::-1]
    return 0.5 * (forward + backward)


def jitter(points, fps: float, still) -> float:
    """Mean landmark acceleration (units/s^2) over the frames marked ``still``: the shake a viewer
    sees on a face that is not moving. ``points (T, K, 3)``, ``still (T,)`` bool."""
    p = np.asarray(points, dtype=np.float64)
    accel = np.linalg.norm(p[2:] - 2 * p[1:-1] + p[:-2], axis=-1).mean(axis=-1) * fps * fps
    mask = np.asarray(still)[1:-1] & np.isfinite(accel)
    return float(accel[mask].mean()) if mask.any() else float("nan")
