"""`SpeakerModel`: a speaker's linear articulatory model and its interpretation of FAP streams.

The mobile points of a face during speech (lips, jaw, chin, cheeks) move as ``x = x0 + sum_k a_k d_k``:
a rest shape and ``K`` displacement vectors, one per articulatory parameter (jaw, lip protrusion,
opening, ...). That model, kept inside a decoder, interprets a received FAP stream (the ICP "clone"
platform, Elisei, Odisio and Bailly 2001): it finds the parameters that best explain whichever FAPs
arrived in each frame, in the least-squares sense, and regenerates every FAP the model ties to a
point. The FAPs that were not sent are filled in, and much of the coding noise goes.

With a temporal prior (``temporal=True``), the interpretation is a causal Kalman filter over the
frames (low delay: a frame's parameters depend on it and the frames before it, never after). Each
parameter is a first-order autoregression with the persistence (lag-one correlation) that the model
measured on the frames it was built from, :attr:`SpeakerModel.persistence`, and unit variance, the
prior the frame-by-frame solve's ridge already stands for: with persistence 0 the filter is that
solve. Each frame then borrows what the frames before it saw, which removes more of the coding noise.
With ``window`` the prior is a smoother over windows of frames that arrive together (a ``.fba``'s
packets), which on a coded stream also keeps each FAP within its quantiser cell
(:mod:`faceanim.speaker.smoother`).

The forward map is exact and linear. Parameters give points; points give FAPs as
:func:`faceanim.motion.motion_to_faps` measures them (a point's displacement along the FAP's direction,
in its FAPU; the points the jaw carries after the jaw's swing, :mod:`faceanim.mpeg4.jaw`), with one
difference: the swing here follows the chin's drop on both sides of rest, as the decoder plays
``open_jaw`` (``motion_to_faps`` takes no swing out for a chin above rest). The two agree wherever the
chin is at or below rest.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.linalg import solve_discrete_are

from ..errors import InputError
from ..mpeg4 import FAP_COUNT, Fapu, fap_table
from ..mpeg4.fapstream import FapStream
from ..mpeg4.jaw import JAW_CARRIED, jaw_hinge
from ..validation import as_array, as_index_array, restore_frozen

__all__ = ["SpeakerModel", "Interpreter", "DEFAULT_RIDGE", "fap_measurement"]

# The ridge of the interpretation, in cm^2: the parameters have unit variance over the frames the model
# was built on, so this is, as a prior, the squared error (here 0.3 mm) a received FAP's point may carry.
# Small beside a frame of 34 FAPs; enough to hold a parameter that a few FAPs barely see. Chosen on the
# talking clips d12 and d20 (held-out FAP error from 8 FAPs lowest at 1e-3 to 3e-3 cm^2), not on the
# speech clips the benchmarks report.
DEFAULT_RIDGE = 1e-3
# The smoother's cells (regularise with window and quant) reach this far (FAPU) beyond half a step: the
# .fap format holds whole FAPU, so every coded stream was rounded to them first.
CELL_MARGIN = 0.5


def fap_measurement(names, neutral: np.ndarray, fapu: Fapu, others: dict | None = None
                    ) -> tuple[np.ndarray, np.ndarray]:
    """The FAPs that points ``names`` observe, as a linear map of their displacements.

    Parameters
    ----------
    names : sequence of str, (P,)
        The moving points (MPEG-4 feature points by number, others by any name).
    neutral : (P, 3) float64
        Their rest positions (model units, head frame, MPEG-4 axes).
    fapu : Fapu
    others : dict of str to (3,) array, optional
        Positions of points that do not move, for the jaw's hinge (9.15, 2.13, 2.14 where they are not
        among ``names``).

    Returns
    -------
    columns : (J,) int64
        The FAPs observed (column ``j`` is FAP ``j + 1``), ascending.
    matrix : (J, 3P) float64
        ``faps = matrix @ displacements.reshape(-1)`` in FAPU; the swing of the jaw (first order,
        :func:`faceanim.mpeg4.jaw.jaw_swing`) is taken out of the carried points as the decoder puts it in.
    """
    table = fap_table()
    names = tuple(names)
    lookup = {n: i for i, n in enumerate(names)}
    units = fapu.scale()
    at = {**(others or {}), **dict(zip(names, neutral, strict=True))}
    opening = table.number("open_jaw") - 1
    down = table.direction[opening]
    hinge = jaw_hinge(at, fapu) if "2.1" in lookup else None
    rows, columns = [], []
    for j in range(2, FAP_COUNT):
        points = table.feature_points[j]
        if len(points) != 1 or points[0] not in lookup or not table.direction[j].any():
            continue
        row = np.zeros((len(names), 3))
        row[lookup[points[0]]] = table.direction[j]
        if hinge is not None and (points[0] in JAW_CARRIED or (points[0] == "2.1" and j != opening)):
            r = at[points[0]] - hinge
            arm = at["2.1"][2] - hinge[2]
            row[lookup["2.1"]] -= down * (np.array([0.0, -r[2], r[1]]) @ table.direction[j]) / arm
        rows.append(row.reshape(-1) / units[j])
        columns.append(j)
    return np.array(columns, dtype=np.int64), np.array(rows).reshape(len(rows), 3 * len(names))


@dataclass(frozen=True, eq=False)
class SpeakerModel:
    """A speaker's linear articulatory model; immutable, checked on construction.

    Parameters
    ----------
    names : tuple of str, (P,)
        The mobile points (lips, jaw, chin, cheeks).
    neutral : (P, 3) float64
        Their positions at rest, where every FAP is 0 (cm, head frame, MPEG-4 axes).
    rest : (P, 3) float64
        ``x0``, the shape at parameters 0 (the mean of the frames the model was built on).
    basis : (K, P, 3) float64
        ``d_k``, cm per unit of parameter ``k``.
    parameter_names : tuple of str, (K,)
    static_names : tuple of str, (S,)
        The rest of the face, which the model holds still.
    static_points : (S, 3) float64
    triangles : (F, 3) int64
        A triangulation of the mobile then the static points (indices into both, in that order).
    fapu : Fapu
        Of the speaker's neutral face (cm).
    ranges : (K, 2) float64
        The lowest and highest value of each parameter over the frames the model was built on.
    fps : float
        The frame rate of the video it was built from: the rate of the streams :meth:`to_faps` makes.
    method : str
        How the displacement vectors were found (``"pca"`` or ``"guided"``).
    ridge : float
        The interpretation's ridge, cm^2 (see :data:`DEFAULT_RIDGE`).
    persistence : (K,) float64 or None
        Each parameter's correlation with itself one frame earlier over the frames the model was built
        on, from 0 to below 1: the temporal prior's autoregression (``temporal=True``). None: no
        temporal prior (a model file of version 1).
    """

    names: tuple[str, ...]
    neutral: np.ndarray
    rest: np.ndarray
    basis: np.ndarray
    parameter_names: tuple[str, ...]
    static_names: tuple[str, ...]
    static_points: np.ndarray
    triangles: np.ndarray
    fapu: Fapu
    ranges: np.ndarray
    fps: float
    method: str = "guided"
    ridge: float = DEFAULT_RIDGE
    persistence: np.ndarray | None = None
    _cache: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    def __post_init__(self):
        names, static = tuple(self.names), tuple(self.static_names)
        for what, group in (("names", names), ("static_names", static), ("parameter_names", self.parameter_names)):
            if not all(isinstance(n, str) for n in group):
                raise TypeError(f"{what} must be strings")
        if len(set(names + static)) != len(names) + len(static):
            raise ValueError("point names must be distinct across names and static_names")
        if not isinstance(self.fapu, Fapu):
            raise TypeError(f"fapu must be a Fapu, got {type(self.fapu).__name__}")
        P = len(names)
        neutral = as_array(self.neutral, "neutral", shape=(P, 3), frozen=True)
        rest = as_array(self.rest, "rest", shape=(P, 3), frozen=True)
        basis = as_array(self.basis, "basis", shape=("K", P, 3), min_length=1, frozen=True)
        K = len(basis)
        if len(self.parameter_names) != K:
            raise ValueError(f"parameter_names must name the {K} parameters, got {len(self.parameter_names)}")
        points = as_array(self.static_points, "static_points", shape=(len(static), 3), frozen=True)
        triangles = as_index_array(self.triangles, "triangles", upper=P + len(static), shape=("F", 3), frozen=True)
        ranges = as_array(self.ranges, "ranges", shape=(K, 2), frozen=True)
        if not (np.isfinite(self.fps) and self.fps > 0):
            raise ValueError(f"fps must be a positive number, got {self.fps!r}")
        if self.method not in ("pca", "guided"):
            raise ValueError(f"method must be pca or guided, got {self.method!r}")
        if not (np.isfinite(self.ridge) and self.ridge >= 0):
            raise ValueError(f"ridge must be a number from 0, got {self.ridge!r}")
        persistence = (None if self.persistence is None
                       else as_array(self.persistence, "persistence", shape=(K,), frozen=True))
        if persistence is not None and not ((persistence >= 0) & (persistence < 1)).all():
            raise ValueError("persistence must hold correlations from 0 to below 1")
        if np.linalg.matrix_rank(basis.reshape(K, -1)) < K:
            raise ValueError(f"basis must hold {K} independent displacement vectors")
        for name, value in (("names", names), ("neutral", neutral), ("rest", rest), ("basis", basis),
                            ("parameter_names", tuple(self.parameter_names)), ("static_names", static),
                            ("static_points", points), ("triangles", triangles), ("ranges", ranges),
                            ("fps", float(self.fps)), ("ridge", float(self.ridge)),
                            ("persistence", persistence)):
            object.__setattr__(self, name, value)
        if len(self.fap_columns) < K:
            raise ValueError(f"the mobile points observe {len(self.fap_columns)} FAPs, fewer than the {K} parameters")

    def __getstate__(self):
        state = dict(self.__dict__)
        state["_cache"] = {}
        return state

    def __setstate__(self, state):
        restore_frozen(self, state)

    def _cached(self, key, compute) -> Any:
        """The derived value ``key``, made once and kept (read-only) on this model, which never changes."""
        try:
            return self._cache[key]
        except KeyError:
            pass
        value = compute()
        for array in value if isinstance(value, tuple) else (value,):
            if isinstance(array, np.ndarray):
                array.flags.writeable = False
        self._cache[key] = value
        return value

    # ---- the forward map: parameters -> points -> FAPs

    @property
    def parameter_count(self) -> int:
        return len(self.basis)

    def points(self, parameters) -> np.ndarray:
        """(T, P, 3) positions of the mobile points for ``parameters (T, K)`` (cm, head frame)."""
        a = as_array(parameters, "parameters", shape=("T", self.parameter_count), finite=False)
        return self.rest + np.einsum("tk,kpc->tpc", a, self.basis)

    def _forward(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        static = dict(zip(self.static_names, self.static_points, strict=True))
        columns, M = fap_measurement(self.names, self.neutral, self.fapu, static)
        G = M @ self.basis.reshape(self.parameter_count, -1).T  # (J, K) FAPU per unit parameter
        offset = M @ (self.rest - self.neutral).reshape(-1)  # (J,) the FAPs at parameters 0
        weight = self.fapu.scale()[columns]  # cm per FAP unit: residuals are weighed in cm
        return columns, G, offset, weight

    @property
    def fap_columns(self) -> np.ndarray:
        """(J,) the FAPs the model's points observe (column ``j`` is FAP ``j + 1``), ascending."""
        return self._cached("forward", self._forward)[0]

    @property
    def fap_matrix(self) -> np.ndarray:
        """(J, K) FAPU per unit of each parameter, for the FAPs :attr:`fap_columns`."""
        return self._cached("forward", self._forward)[1]

    @property
    def fap_offset(self) -> np.ndarray:
        """(J,) the FAPs of the rest shape (parameters 0)."""
        return self._cached("forward", self._forward)[2]

    def to_faps(self, parameters, *, fps: float | None = None, name: str = "speaker") -> FapStream:
        """The FAP stream of ``parameters (T, K)`` at ``fps`` (default: the model's): every FAP of
        :attr:`fap_columns` on every frame whose parameters are finite; no FAP on the others."""
        a = as_array(parameters, "parameters", shape=("T", self.parameter_count), finite=False)
        present = np.isfinite(a).all(axis=1)
        values = np.zeros((len(a), FAP_COUNT))
        mask = np.zeros((len(a), FAP_COUNT), dtype=bool)
        values[np.ix_(present, self.fap_columns)] = a[present] @ self.fap_matrix.T + self.fap_offset
        mask[np.ix_(present, self.fap_columns)] = True
        return FapStream(values, mask, self.fps if fps is None else fps, name=name)

    # ---- the inverse: the FAPs that arrived -> parameters

    def solver(self, received, *, quant: float | None = None) -> np.ndarray:
        """(K, n) the ridge pseudo-inverse for the model's FAPs flagged in ``received (J,) bool`` (n of
        them): ``parameters = solver @ (faps - offset)`` on those FAPs. It depends only on which FAPs
        arrived (and ``quant``), so it is made once per subset and kept.

        The solve is ``min |W (G a - f)|^2 + r |a|^2``. By default ``W`` is the FAPs' units in cm, so
        every FAP's error counts as the distance its point is off, and ``r`` is :attr:`ridge`: the
        setting for measured FAPs, whose error is the model's misfit of real motion. With ``quant``, the
        quantiser scale a FAP coder used (steps ``QP x quant``, :mod:`faceanim.mpeg4.fapcoder`), ``W`` is
        one over each FAP's step and ``r`` is 1/12, the variance of a rounding error in steps: the
        least-squares estimate for FAPs whose error is their quantisation (parameters of unit prior
        variance)."""
        received = np.asarray(received, dtype=bool)
        if quant is not None and not (np.isfinite(quant) and quant > 0):
            raise ValueError(f"quant must be a positive number, got {quant!r}")
        key = ("solver", received.tobytes(), None if quant is None else float(quant))
        return self._cached(key, lambda: self._solver(received, quant))

    def _weights(self, quant: float | None) -> tuple[np.ndarray, float]:
        """(J,) the weight of each FAP's error and the ridge (see :meth:`solver`)."""
        columns, _, _, weight = self._cached("forward", self._forward)
        if quant is None:
            return weight, self.ridge
        return 1.0 / (fap_table().quant_step[columns] * quant), 1.0 / 12.0

    def _solver(self, received: np.ndarray, quant: float | None) -> np.ndarray:
        G = self.fap_matrix
        weight, ridge = self._weights(quant)
        A = weight[received, None] * G[received]
        normal = A.T @ A + ridge * np.eye(self.parameter_count)
        return np.linalg.solve(normal, A.T * weight[received])

    def filter_gain(self, received, *, quant: float | None = None) -> tuple[np.ndarray, np.ndarray]:
        """``(A (K, K), B (K, n))`` of the temporal prior's steady-state Kalman filter for the FAPs
        flagged in ``received (J,) bool``: ``a_t = A @ a_(t-1) + B @ (faps_t - offset)``. Kept per subset.

        The state is the parameters, ``a_t = R a_(t-1) + w_t`` with ``R`` the diagonal of
        :attr:`persistence` and ``w_t`` of variance ``1 - R^2`` (parameters of unit variance); a
        received FAP carries an error of variance ``ridge / weight^2`` (weights and ridge as in
        :meth:`solver`, whose estimate is the filter's at persistence 0 and on a frame with no past).
        With a ridge of 0 (cm weights) the FAPs are taken as exact: ``A = 0`` and ``B`` the solver."""
        if self.persistence is None:
            raise InputError("this speaker model has no temporal prior (a version 1 file): build it again with "
                             "faceanim speaker build")
        received = np.asarray(received, dtype=bool)
        if quant is not None and not (np.isfinite(quant) and quant > 0):
            raise ValueError(f"quant must be a positive number, got {quant!r}")
        key = ("filter", received.tobytes(), None if quant is None else float(quant))
        return self._cached(key, lambda: self._filter_gain(received, quant))

    def _filter_gain(self, received: np.ndarray, quant: float | None) -> tuple[np.ndarray, np.ndarray]:
        weight, ridge = self._weights(quant)
        K = self.parameter_count
        if ridge == 0:
            return np.zeros((K, K)), self._solver(received, quant)
        H = self.fap_matrix[received]
        noise = np.diag(ridge / weight[received] ** 2)
        F, Q = np.diag(self.persistence), np.diag(1 - self.persistence**2)
        # the predicted covariance at the steady state (the filter's Riccati equation, dual of control's)
        P = solve_discrete_are(F.T, H.T, Q, noise)
        gain = np.linalg.solve(H @ P @ H.T + noise, H @ P).T  # (K, n), P symmetric
        return (np.eye(K) - gain @ H) @ F, gain

    def _received(self, stream: FapStream) -> np.ndarray:
        if not isinstance(stream, FapStream):
            raise TypeError(f"stream must be a FapStream, got {type(stream).__name__}")
        return stream.mask[:, self.fap_columns]

    def _check_enough(self, stream: FapStream, received: np.ndarray) -> np.ndarray:
        """Frames carrying at least as many of the model's FAPs as it has parameters; a stream in which
        no frame does is refused."""
        counts = received.sum(axis=1)
        enough = counts >= self.parameter_count
        if len(stream) and not enough.any():
            raise self._too_few(stream.name, int(counts.max()))
        return enough

    def _too_few(self, name: str, most: int) -> InputError:
        """The refusal of a stream named ``name`` whose frames carry at most ``most`` of the model's FAPs."""
        carried = "none of the speaker model's FAPs" if most == 0 else (
            f"at most {most} of the speaker model's {len(self.fap_columns)} FAPs on a frame")
        return InputError(f"the FAP stream {name} carries {carried}; its {self.parameter_count} "
                          f"parameters need at least {self.parameter_count} on a frame")

    def _groups(self, received: np.ndarray, enough: np.ndarray):
        """(frames, received mask) for each subset of FAPs that frames with enough FAPs carry."""
        frames = np.flatnonzero(enough)
        bits = np.packbits(received[frames], axis=1, bitorder="little")
        bits = np.pad(bits, ((0, 0), (0, -bits.shape[1] % 8)))
        keys = np.ascontiguousarray(bits).view(np.uint64)  # 64 FAPs to a key
        if keys.shape[1] == 1:
            _, inverse = np.unique(keys[:, 0], return_inverse=True)
        else:
            _, inverse = np.unique(keys, axis=0, return_inverse=True)
        inverse = inverse.reshape(-1)
        order = np.argsort(inverse, kind="stable")
        bounds = np.flatnonzero(np.diff(inverse[order])) + 1
        for group in np.split(order, bounds):
            if len(group):
                yield frames[group], received[frames[group[0]]]

    def to_parameters(self, stream: FapStream, *, quant: float | None = None, temporal: bool = False) -> np.ndarray:
        """(T, K) the parameters that best explain each frame's FAPs (see :meth:`solver`, and there for
        ``quant``); NaN on frames carrying fewer of the model's FAPs than it has parameters. With
        ``temporal``, each frame's FAPs and those of the frames before it, through the temporal prior
        (:meth:`filter_gain`); a frame after one with too few FAPs starts afresh (its own solve).

        Raises
        ------
        InputError
            No frame carries that many (the subset cannot determine the parameters); ``temporal`` on
            a model without a temporal prior.
        """
        received = self._received(stream)
        enough = self._check_enough(stream, received)
        if temporal:
            return self._filtered(stream, received, enough, quant)
        a = np.full((len(stream), self.parameter_count), np.nan)
        values = stream.values[:, self.fap_columns] - self.fap_offset
        for frames, mask in self._groups(received, enough):
            a[frames] = values[np.ix_(frames, np.flatnonzero(mask))] @ self.solver(mask, quant=quant).T
        return a

    def _filtered(self, stream: FapStream, received: np.ndarray, enough: np.ndarray, quant: float | None,
                  state: np.ndarray | None = None) -> np.ndarray:
        """(T, K) the temporal prior's causal estimate, run by run of frames carrying the same FAPs;
        ``state``: the parameters of the frame before the stream's first (None: no past)."""
        return self._filtered_state(stream, received, enough, quant, state)[0]

    def _filtered_state(self, stream: FapStream, received: np.ndarray, enough: np.ndarray, quant: float | None,
                        state: np.ndarray | None) -> tuple[np.ndarray, np.ndarray | None]:
        """:meth:`_filtered` and the filter's state after the stream's last frame (None after a frame
        with too few FAPs)."""
        if self.persistence is None:
            self.filter_gain(received[0] if len(received) else np.ones(len(self.fap_columns), bool), quant=quant)
        a = np.full((len(stream), self.parameter_count), np.nan)
        values = stream.values[:, self.fap_columns] - self.fap_offset
        change = np.ones(len(stream), dtype=bool)
        change[1:] = (received[1:] != received[:-1]).any(axis=1) | (enough[1:] != enough[:-1])
        starts = np.flatnonzero(change)
        for start, end in zip(starts, np.append(starts[1:], len(stream)), strict=True):
            if not enough[start]:
                state = None
                continue
            mask = received[start]
            y = values[start:end][:, mask]
            if state is None:  # no past: the frame's own solve
                state = self.solver(mask, quant=quant) @ y[0]
                a[start] = state
                first = 1
            else:
                first = 0
            A, B = self.filter_gain(mask, quant=quant)
            drive = y[first:] @ B.T
            out = a[start + first:end]
            for t in range(len(drive)):
                state = A @ state + drive[t]
                out[t] = state
        return a, state

    def interpreter(self, *, quant: float | None = None, temporal: bool = False,
                    window: int | None = None) -> Interpreter:
        """:meth:`regularise` a piece of a stream at a time (:class:`Interpreter`), for a decoder that
        gets its frames as they arrive: the temporal prior's state carries from one piece to the next,
        so the pieces come out as the whole stream would."""
        return Interpreter(self, quant=quant, temporal=temporal, window=window)

    def regularise(self, stream: FapStream, *, quant: float | None = None, temporal: bool = False,
                   window: int | None = None) -> FapStream:
        """``stream`` as the model explains it: on each frame carrying at least as many of the model's
        FAPs as it has parameters, every one of the model's FAPs is regenerated from the parameters
        that best explain those received (filled in where absent, denoised where present). Other FAPs
        (eyes, brows, head) pass through as they arrived, and so do frames carrying too few of the
        model's FAPs (a frame without a face carries none). ``quant``: the quantiser scale of a coded
        stream, which weighs each FAP by its step (see :meth:`solver`); default: weighed in cm.
        ``temporal``: the parameters through the temporal prior (causal, see :meth:`to_parameters`).
        ``window`` (with ``temporal``): the temporal prior as a smoother within windows of that many
        frames, counted from the stream's first, each frame estimated from the frames of its window
        after it as well as from those before (a decoder that receives a packet of frames at a time has
        them all at once), and, with ``quant``, kept within the quantiser's cells
        (:mod:`faceanim.speaker.smoother`).

        Raises
        ------
        InputError
            No frame carries as many of the model's FAPs as it has parameters: the subset sent cannot
            determine them (one line, naming the counts).
        """
        received = self._received(stream)
        enough = self._check_enough(stream, received)
        if window is not None:
            if not temporal:
                raise ValueError("window smooths with the temporal prior: give temporal=True with it")
            return self._windowed(stream, received, enough, quant, None, _check_window(window))[0]
        return self._regularised(stream, received, enough, quant, temporal, None)[0]

    def _windowed(self, stream: FapStream, received: np.ndarray, enough: np.ndarray, quant: float | None,
                  state, window: int) -> tuple[FapStream, Any]:
        """:meth:`regularise` with ``window``, for whole windows of ``stream`` (its first frame starts
        one; the last may be short), from the smoother's ``state`` (the mean and covariance of the
        parameters of the frame before the stream's first, or None: no past); returns the stream and
        the state after it."""
        from .smoother import smooth_run

        if self.persistence is None:
            self.filter_gain(np.ones(len(self.fap_columns), bool), quant=quant)  # raises, naming the cause
        weight, noise = self._weights(quant)
        if noise == 0:  # FAPs taken as exact: every frame its own solve
            return self._regularised(stream, received, enough, quant, False, None)[0], None
        F = self.persistence
        # a coded value's cell: half a step, and half a FAPU more, the rounding to whole FAPU that every
        # value of a .fap has had before it was coded (which no model reproduces)
        cells = None if quant is None else weight * (0.5 / weight + CELL_MARGIN)
        values = stream.values[:, self.fap_columns]
        a = np.full((len(stream), self.parameter_count), np.nan)
        for start in range(0, len(stream), window):
            stop = min(len(stream), start + window)
            for run in np.split(np.arange(start, stop), np.flatnonzero(np.diff(enough[start:stop])) + 1):
                if not enough[run[0]]:
                    state = None
                    continue
                if state is None:
                    mean0, cov0 = np.zeros(self.parameter_count), np.eye(self.parameter_count)
                else:
                    mean0, cov0 = F * state[0], F[:, None] * state[1] * F[None, :] + np.diag(1 - F**2)
                a[run], cov = smooth_run(self.fap_matrix, self.fap_offset, values[run], received[run], weight, noise,
                                         F, mean0, cov0, cells=cells)
                state = (a[run[-1]], cov)
        out = stream.values.copy()
        out[np.ix_(enough, self.fap_columns)] = a[enough] @ self.fap_matrix.T + self.fap_offset
        mask = stream.mask.copy()
        mask[np.ix_(enough, self.fap_columns)] = True
        return FapStream(out, mask, stream.fps, frame_numbers=stream.frame_numbers, visemes=stream.visemes,
                         expressions=stream.expressions, name=stream.name), state

    def _regularised(self, stream: FapStream, received: np.ndarray, enough: np.ndarray, quant: float | None,
                     temporal: bool, state: np.ndarray | None) -> tuple[FapStream, np.ndarray | None]:
        """:meth:`regularise` without the check that some frame carries enough FAPs, from the temporal
        prior's ``state``; returns the stream and the state after it."""
        values, mask = stream.values.copy(), stream.mask.copy()
        G = self.fap_matrix
        if temporal:
            a, state = self._filtered_state(stream, received, enough, quant, state)
            values[np.ix_(enough, self.fap_columns)] = a[enough] @ G.T + self.fap_offset
        else:
            measured = stream.values[:, self.fap_columns] - self.fap_offset
            for frames, subset in self._groups(received, enough):
                key = ("regularise", subset.tobytes(), None if quant is None else float(quant))
                operator = self._cached(key, lambda s=subset: G @ self.solver(s, quant=quant))
                result = measured[np.ix_(frames, np.flatnonzero(subset))] @ operator.T + self.fap_offset
                values[np.ix_(frames, self.fap_columns)] = result
        mask[np.ix_(enough, self.fap_columns)] = True
        return FapStream(values, mask, stream.fps, frame_numbers=stream.frame_numbers, visemes=stream.visemes,
                         expressions=stream.expressions, name=stream.name), state

    # ---- points -> parameters

    def fit_points(self, displacements) -> np.ndarray:
        """(T, K) the parameters whose points are nearest (least squares, cm) to the mobile points
        displaced by ``displacements (T, P, 3)`` from :attr:`neutral`; NaN on frames holding NaN.
        Displacements from the neutral carry a face measured in another capture of the speaker."""
        d = as_array(displacements, "displacements", shape=("T", len(self.names), 3), finite=False)
        x = (self.neutral - self.rest + d).reshape(len(d), -1)
        B = self.basis.reshape(self.parameter_count, -1)
        projector = self._cached("fit_points", lambda: np.linalg.pinv(B.T))
        a = x @ projector.T
        a[~np.isfinite(x).all(axis=1)] = np.nan
        return a


def _check_window(window) -> int:
    if isinstance(window, bool) or not isinstance(window, (int, np.integer)) or window < 1:
        raise ValueError(f"window must be a whole number of frames from 1, got {window!r}")
    return int(window)


class Interpreter:
    """A speaker model's :meth:`~SpeakerModel.regularise` of a stream that arrives in pieces: call it on
    each piece in order; with ``temporal``, the temporal prior's state carries over, so the pieces
    joined equal the whole stream regularised at once. With ``window``, a piece's frames come out once
    their window is whole (windows counted from the stream's first frame), the last short window at
    :meth:`finish`; a decoder whose pieces are packets of that many frames loses no delay to it.
    :meth:`finish` refuses, as ``regularise`` does, a stream none of whose frames carried enough of the
    model's FAPs.
    """

    def __init__(self, model: SpeakerModel, *, quant: float | None = None, temporal: bool = False,
                 window: int | None = None):
        if quant is not None and not (np.isfinite(quant) and quant > 0):
            raise ValueError(f"quant must be a positive number, got {quant!r}")
        if window is not None:
            if not temporal:
                raise ValueError("window smooths with the temporal prior: give temporal=True with it")
            window = _check_window(window)
        if temporal and model.persistence is None:
            model.filter_gain(np.ones(len(model.fap_columns), bool))  # raises, naming the cause
        self.model, self.quant, self.temporal, self.window = model, quant, temporal, window
        self._state = None
        self._most = 0  # the most of the model's FAPs a frame has carried
        self._enough = False
        self._name = None
        self._held: list[FapStream] = []  # frames of a window not yet whole

    def __call__(self, piece: FapStream) -> FapStream | None:
        """The frames of ``piece`` (and of earlier pieces held back) that can be given out: all of them,
        or with ``window`` those of the windows now whole; None when there are none."""
        received = self.model._received(piece)
        counts = received.sum(axis=1)
        self._most = max(self._most, int(counts.max(initial=0)))
        self._enough |= bool((counts >= self.model.parameter_count).any())
        self._name = piece.name
        if self.window is None:
            enough = counts >= self.model.parameter_count
            out, self._state = self.model._regularised(piece, received, enough, self.quant, self.temporal,
                                                       self._state)
            return out
        self._held.append(piece)
        held = sum(len(p) for p in self._held)
        whole = held - held % self.window
        return self._release(whole) if whole else None

    def _release(self, count: int) -> FapStream:
        joined = _join(self._held)
        first = _slice(joined, 0, count)
        self._held = [_slice(joined, count, len(joined))] if count < len(joined) else []
        received = self.model._received(first)
        enough = received.sum(axis=1) >= self.model.parameter_count
        out, self._state = self.model._windowed(first, received, enough, self.quant, self._state, self.window)
        return out

    def finish(self) -> FapStream | None:
        """The frames still held (a last window shorter than the others), or None.

        Raises InputError (as :meth:`SpeakerModel.regularise` does) if no frame carried as many of the
        model's FAPs as it has parameters."""
        if self._name is not None and not self._enough:
            raise self.model._too_few(self._name, self._most)
        held = sum(len(p) for p in self._held)
        return self._release(held) if held else None


def _join(pieces: list[FapStream]) -> FapStream:
    if len(pieces) == 1:
        return pieces[0]

    def cat(name):
        parts = [getattr(p, name) for p in pieces]
        return None if any(x is None for x in parts) else np.concatenate(parts)

    first = pieces[0]
    return FapStream(cat("values"), cat("mask"), first.fps, frame_numbers=cat("frame_numbers"),
                     visemes=cat("visemes"), expressions=cat("expressions"), name=first.name)


def _slice(stream: FapStream, start: int, stop: int) -> FapStream:
    def part(x):
        return None if x is None else x[start:stop]

    return FapStream(stream.values[start:stop], stream.mask[start:stop], stream.fps,
                     frame_numbers=stream.frame_numbers[start:stop], visemes=part(stream.visemes),
                     expressions=part(stream.expressions), name=stream.name)
