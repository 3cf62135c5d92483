"""Analysis by synthesis with the speaker's clone: render its mouth, compare with the frame, move the
articulatory parameters (the ICP platform's tracker, Elisei, Odisio and Bailly 2001).

Per frame, a small box around the mouth (1.5 x 0.85 mouth widths, about 64 box pixels across, each
``factor x factor`` frame pixels) of the frame is compared with the clone drawn in the same box. Under
each box pixel the frame's middle pixel is compared (or, with ``supersample``, the mean of all of
them), against the clone's textures read at those pixels' centres, as the clone's renderer reads them
for those pixels (:mod:`.lipraster`). Two comparisons:

* ``"colour"`` (the default): the clone's key textures (RGB) mixed with the appearance's blending
  weights and drawn on the synthesis mesh's own triangles around the mouth (:func:`.mouthmesh.mouth_mesh`: the
  surface the clone's renderer draws there, same vertices, UV and triangles), against the frame's
  colours after a least-squares gain and offset per channel (a change of lighting or white balance
  costs nothing); the difference is the share of the box's colour variance the clone leaves
  unexplained. On frames the clone itself drew the minimum lies at the true parameters.
* ``"probability"`` (the original's): the frame's lip-probability image (the appearance's colour
  model, adapted to the video's lighting) against the key postures' lip-probability textures drawn on
  the reduced :class:`~.mouthmesh.AnalysisMesh` (:func:`.mouthmesh.analysis_mesh`, at most 50
  triangles), after a gain and an offset. The colour-to-probability map is not linear, so a blurred
  frame and a mix of probability textures are differently shaped images: the minimum lies away from the
  truth even on the clone's own frames (``benchmarks/results/clone_tracking.md`` of the previous round).

The difference is minimised over the 6 articulatory parameters by the simplex method (Nelder-Mead,
7 vertices), from the previous frame's answer, with a cap on evaluations; optionally over the rigid
motion too (6 more: a rotation about the mouth and a translation, on top of the tracker's head pose).
With ``"colour"`` the simplex is shaped first (:meth:`CloneAnalyser._shaped_simplex`): the residual's
finite differences give a Gauss-Newton Hessian, one damped Gauss-Newton step is tried, and the first
vertices lie along the Hessian's eigenvectors, as long as the valley is wide in each, so correlated
parameters do not stall the simplex.

The meshes the two comparisons draw are :mod:`.mouthmesh`'s.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize

from ..errors import InputError
from ..validation import as_array
from .camera import project_posed, rigid_transform
from .lipraster import RASTERS, GlLipRaster, NumpyLipRaster, prefilter, prefilter_block
from .model import SpeakerModel
from .mouthmesh import analysis_mesh, mouth_mesh

__all__ = ["CloneAnalyser", "FrameAnswer", "DEFAULT_MAX_EVALS", "DEFAULT_PRIOR", "COMPARES"]

DEFAULT_MAX_EVALS = 150

_BOX = (1.5, 0.85)  # the box around the mouth, in mouth widths: the lips and their surroundings, not the nostrils
# The box's width in its own pixels. On the clone's own frames (benchmarks/clone_tracking.py (a)) the
# cost's minimum lies off the truth wherever the clone drawn in the box misses the frame's pixels
# there: with the frame averaged over each box pixel and the textures blurred to a box pixel's scale
# (one isotropic blur, where the texture map stretches differently from triangle to triangle), 0.17 of
# a parameter's spread on a median draw (tracked: 0.16); with the frame's middle pixel under each box
# pixel and the textures read at its centre through the triangle covering it (the default now, at the
# same speed: 12.5-13.0 frames/s on the speech clips, goal 10), 0.06 (tracked: 0.063; read through the
# triangle under the box pixel's centre instead, 0.08 and 0.103); with all of them averaged
# (``supersample``), 0.09 (tracked: 0.079) at 6.0 / 9.5 frames/s (benchmarks/results/clone_tracking.md,
# 2026-11-24). At 96 the box itself went 0.35 / 0.17 / 0.11 / 0.14 -> 0.16 / 0.19 / 0.08 / 0.06 on the
# first folds' draws (one Gauss-Newton round, the box-scale blur), but speech_woman (mouth 74 pixels:
# the box at full size) ran at 8.6-9.4 frames/s against 14-16; kept at 64.
_BOX_PIXELS = 64
# The prior on the articulatory parameters (unit variance over the build frames): ``prior x mean(a^2)``
# is added to the difference, holding what the image cannot see near the speaker's usual range.
# Lip probability: chosen on the build frames of the speech clips (tuning), not on the held-out frames
# the benchmark reports. Colour: none; on the build frames its weight (0, 2e-4, 2e-3) left the lip
# opening's and width's correlation with MediaPipe within 0.03 of each other, while any pull toward 0
# biases the shallow parameters (lower lip, corners) by a third of a standard deviation on the clone's
# own frames.
DEFAULT_PRIOR = 1e-2
DEFAULT_COLOUR_PRIOR = 0.0
# The pull toward the frame's own landmark-based reading (the tracker's reading, ``analyse(reading=)``):
# a Gaussian prior about it, ``w |a - reading|^2`` added to the difference, whose weight ``w`` is this
# share of the image's mean curvature on the frame (the trace of the colour difference's Gauss-Newton
# Hessian over the articulatory parameters, measured by the shaped simplex, over K): a MAP estimate in
# which the image decides along the directions it sees sharply and the reading along those where the
# difference is flat (on real frames a change of 0.007/255 in edge pixels moved the plain simplex 4.8
# spreads along them at equal cost). Without a measured curvature (no shaped simplex) ``w`` is this
# weight itself, per squared standard deviation. Chosen on the speech clips' build frames (tuning: 4
# segments of each fold's build frames, both clips, the head registered): lip opening / width
# correlation with MediaPipe, median (worst), at 0: 0.64 (-0.11) / 0.81 (0.46); 0.1: 0.70 / 0.81;
# 0.3: 0.79 / 0.85; 1: 0.89 (0.73) / 0.92 (0.68); 3: 0.96 (0.89) / 0.97 (0.79). 1 weighs the image and
# the reading alike at the image's mean curvature; 3 would reach the goal on the build frames, but the
# answer there mostly repeats the reading (the image decides only its sharpest directions).
DEFAULT_ANCHOR = 1.0
# The pull toward the previous frame's answer (``analyse(previous=)``), weighted as the reading's (this
# share of the image's mean curvature); with both, the answer is pulled toward their weighted mean with
# the sum of the weights. Chosen on the speech clips' build frames (tuning: 4 segments of each fold's
# build frames, both clips, 16 segments, the reading at DEFAULT_ANCHOR): lip opening / width correlation
# with MediaPipe, median (worst), at 0: 0.89 (0.73) / 0.93 (0.68); 0.5: 0.92 (0.77) / 0.95 (0.68);
# 1: 0.93 (0.78) / 0.97 (0.69); 2: 0.91 (0.77) / 0.95 (0.68). At 1 the answer stays about as far from
# the reading as at 0 (RMS difference over the reading's spread, per segment: 0.24-0.60 against
# 0.12-0.68 on the first folds), where doubling the reading's weight instead (0.94 (0.83) / 0.95 (0.75))
# brings it to 0.08-0.43: the gain is the frames' agreement with each other, not more of the reading.
# Without a reading it only makes the answer lag (the clone's own frames tracked from the image alone:
# worst parameter's error 0.35 -> 1.9 of its spread on speech_man), so ``speaker track`` gives both.
DEFAULT_CONTINUITY = 1.0
# The damped Gauss-Newton rounds before the simplex (:meth:`CloneAnalyser._shaped_simplex`). Chosen on
# the clone's own frames at build postures (tuning: 4 segments of 20 build frames per fold, both clips,
# 16 draws, tracked from the image alone as benchmarks/clone_tracking.py (a) does on the held-out frames):
# worst parameter's RMS error over its spread, median (worst), with the frame's middle pixel under each
# box pixel read through the triangle under the box pixel's centre (a first cut of today's default,
# 2026-11-24), 1 round: 0.198 (1.02); 2: 0.099 (0.86); 3: 0.104 (0.88); 5: 0.100 (1.31), against a floor
# of 0.093 (0.22) (each frame from its truth, 600 evaluations); through the triangle covering the pixel
# (the default), 3 rounds: 0.062 (0.24), floor 0.062 (0.13); with every pixel (supersampled) 1: 0.237
# (0.69), 2: 0.115 (0.92), 3: 0.106 (0.77), 5: 0.112 (0.73), floor 0.084; with the box-scale blur (the
# default before) 1: 0.227 (0.95), 3: 0.166 (0.92). On real build frames, with the reading's and the
# previous answer's pulls, the lip opening's and width's correlation with MediaPipe moved by under 0.01.
# (One round was kept while the textures' blur was too wide: then more rounds were mixed.) More than one
# round also lets each round retry a step that does not lower the cost (_LM_TRIES, each damped 4x
# more); the figures above are of that pairing, which is what the default runs.
DEFAULT_ROUNDS = 3
# The shaped simplex (CloneAnalyser._shaped_simplex): finite differences over this share of a first step;
# the Gauss-Newton step's damping (Levenberg-Marquardt, on the Hessian's diagonal) and its longest move in
# first steps; the cost each edge of the simplex raises, as a share of the start's.
_DIFFERENCE = 0.25
# The walls beyond the model's parameter ranges (CloneAnalyser._beyond): their weight per squared standard
# deviation and how far beyond the build frames' range (in standard deviations) they begin. On the build
# frames of the speech clips (tuning) walls lifted the lip opening's correlation with MediaPipe from 0.38
# to 0.75 (speech_woman; speech_man's width 0.66 to 0.78); beginning 2 std out rather than 1 changed
# those by under 0.03 and pulls less on postures beyond the build frames' range. That was before the
# reading's and the previous answer's pulls: with them (DEFAULT_ANCHOR, DEFAULT_CONTINUITY) the walls
# change no figure on the build frames (lip opening / width correlation identical to two decimals on the
# 16 tuning segments; the clone's own frames drawn at build postures tracked to the same answers), and
# they only pull postures beyond the range back, where the held-out frames of speech_man's last fold lie
# (up to 10 std out): there, from each frame's own truth with 600 evaluations, the worst parameter came
# back 2.18 of its spread off with walls and 0.81 without. Off by default; ``walls=`` gives them back.
DEFAULT_WALLS = 0.0
_RANGE_MARGIN = 2.0
# The clone's shift in the image (shift=True): the simplex's first step and where its wall begins, box pixels.
_STEP_SHIFT = 0.5
_MAX_SHIFT = 4.0
_DAMPING = 0.1
_LM_TRIES = 3  # a Gauss-Newton round's tries, each damped 4x more, before the rounds end
_MAX_MOVE = 4.0
_SIMPLEX_RISE = 0.5
_UNCOVERED = -1.0
COMPARES = ("colour", "probability")
# The simplex's first steps: articulatory parameters in their standard deviations over the build
# frames; the rigid correction in degrees and centimetres.
_STEP_ARTICULATORY = 0.5
_STEP_ROTATION = 1.0
_STEP_TRANSLATION = 0.1
_RIGID_STEPS = np.array([_STEP_ROTATION] * 3 + [_STEP_TRANSLATION] * 3)


@dataclass(frozen=True, eq=False)
class FrameAnswer:
    """One frame's analysis: ``parameters (K,)``, the rigid ``correction (6,)`` (zeros without
    ``rigid``), the ``pose (4, 4)`` it gives, the ``evaluations`` spent, the final ``cost`` (the
    difference) and the clone's ``shift (2,)`` in box pixels (zeros without ``shift``)."""

    parameters: np.ndarray
    correction: np.ndarray
    pose: np.ndarray
    evaluations: int
    cost: float
    shift: np.ndarray | None = None


class _Spent(Exception):
    pass


class CloneAnalyser:
    """The analysis by synthesis of one video's frames with one speaker's clone; holds the analysis
    mesh, the box, the rasteriser (a GL context for ``raster="gl"``) and the colour model adapted to
    the video. A context manager.

    Parameters
    ----------
    model : SpeakerModel
    appearance : Appearance
        The clone's appearance (:mod:`faceanim.speaker.appearance`): ``uv``, ``lip_textures``,
        ``weights(points)``, ``colour``, ``camera``.
    width, height : int
        The frames' size in pixels (one field's rows with ``field``).
    mouth_width : float
        The mouth's width in the frames, pixels (sets the box: 1.5 x 0.85 mouth widths).
    max_evals : int
        The cap on evaluations of the difference per frame (the simplex's first 7 included).
    rigid : bool
        Also analyse a rigid correction of the head pose (6 more parameters).
    raster : {None, "gl", "numpy"}
        The lip-probability renderer (:mod:`.lipraster`); None (default): GL where a context can be
        made (faster in ``benchmarks/clone_tracking.py``), else numpy.
    field : {None, "top", "bottom"}
        The frames are one field of interlaced footage: rows 0, 2, ... (top) or 1, 3, ... (bottom) of
        the frames the camera was fitted on.
    camera : (3, 4) float64, optional
        The video's camera (:mod:`.camera`); default the appearance's (the video it was made from).
    prior : float, optional
        Weight of the parameters' prior (see :data:`DEFAULT_PRIOR`); default :data:`DEFAULT_PRIOR` for
        lip probability, :data:`DEFAULT_COLOUR_PRIOR` (none) for colour.
    photometric : bool
        Compare after fitting the clone's probabilities to the frame's by a gain and an offset
        (default); False: the plain mean squared difference.
    blur : float
        Compare both images blurred by a Gaussian of this many box pixels (0: not blurred).
    compare : {"colour", "probability"}
        What is compared (see the module's docstring): ``"colour"`` (default), the clone's colours drawn
        on the synthesis mesh around the mouth against the frame's, after a gain and an offset per
        channel; ``"probability"``, the lip probabilities on the reduced mesh.
    precondition : bool
        Shape the simplex by the cost first (colour only; :meth:`_shaped_simplex`); False: the plain
        simplex of first steps along each parameter.
    open_mouth : bool
        Leave out the triangles spanning the mouth's opening (colour only; :func:`mouth_mesh`): the
        opening is then compared as a region of its own colour. Off by default: on the build frames it
        helped one speaker's lip opening and hurt the other's.
    walls : float
        Weight of the walls beyond the speaker's parameter ranges (:data:`DEFAULT_WALLS`).
    box_pixels : int, optional
        The box's width in its own pixels (default 64).
    xatol, fatol : float
        The simplex's stopping tolerances (parameters, difference); the cap usually comes first.
    shift : bool
        Also analyse a shift of the clone in the image (2 more parameters, box pixels; walls beyond 4):
        room for the head pose's and camera's misregistration. Off by default: on the build frames it
        helped one speaker's lip width and hurt the other's.
    anchor : float, optional
        Weight of the pull toward the frame's landmark-based reading (:meth:`analyse`'s ``reading``),
        relative to the image's curvature (see :data:`DEFAULT_ANCHOR`); default :data:`DEFAULT_ANCHOR`.
    rounds : int
        Damped Gauss-Newton rounds before the simplex (colour, shaped simplex; :data:`DEFAULT_ROUNDS`).
    continuity : float, optional
        Weight of the pull toward the previous frame's answer (:meth:`analyse`'s ``previous``), as
        ``anchor``'s (see :data:`DEFAULT_CONTINUITY`); default :data:`DEFAULT_CONTINUITY`.
    supersample : bool, optional
        Compare the mean of every frame pixel under a box pixel with the mean of the clone's textures
        read at each of their centres (``factor x factor`` reads); False: the middle frame pixel with
        one read at its centre. The textures are blurred to a frame pixel's scale either way where they
        are finer than it (:func:`.lipraster.prefilter`: over 1.73 texels a pixel; a camera's pixel
        integrates its area). Default: False for colour (see :data:`_BOX_PIXELS`), True for lip
        probability (its reduced mesh and smooth textures want every pixel: on the tests' synthetic
        clone its worst parameter tracked 0.12 std off with the middle pixel alone, 0.04 with all).
    """

    def __init__(self, model: SpeakerModel, appearance, *, width: int, height: int, mouth_width: float,
                 max_evals: int = DEFAULT_MAX_EVALS, rigid: bool = False, raster: str | None = None, field=None,
                 camera=None, prior: float | None = None, photometric: bool = True, blur: float = 0.0,
                 compare: str = "colour", precondition: bool = True, open_mouth: bool = False,
                 walls: float = DEFAULT_WALLS, box_pixels: int | None = None, xatol: float = 1e-3,
                 fatol: float = 1e-7, shift: bool = False, anchor: float | None = None,
                 rounds: int = DEFAULT_ROUNDS, continuity: float | None = None, supersample: bool | None = None):
        if raster is not None and raster not in RASTERS:
            raise ValueError(f"raster must be None or one of {', '.join(RASTERS)}, got {raster!r}")
        if compare not in COMPARES:
            raise ValueError(f"compare must be one of {', '.join(COMPARES)}, got {compare!r}")
        if prior is None:
            prior = DEFAULT_PRIOR if compare == "probability" else DEFAULT_COLOUR_PRIOR
        if field not in (None, "top", "bottom"):
            raise ValueError(f"field must be None, top or bottom, got {field!r}")
        K = model.parameter_count
        if isinstance(max_evals, bool) or not isinstance(max_evals, (int, np.integer)) or max_evals < K + 1:
            raise ValueError(f"max_evals must be a whole number from {K + 1} (the simplex's vertices), "
                             f"got {max_evals!r}")
        self.model, self.appearance, self.compare = model, appearance, compare
        self.open_mouth = bool(open_mouth)
        self.mesh = analysis_mesh(model) if compare == "probability" else mouth_mesh(
            model, appearance.triangles, appearance.lip_inner if open_mouth else None)
        self.rigid, self.max_evals, self.field, self.prior = bool(rigid), int(max_evals), field, float(prior)
        self.photometric, self.blur, self.precondition = bool(photometric), float(blur), bool(precondition)
        self.walls, self.shift = float(walls), bool(shift)
        self.anchor = DEFAULT_ANCHOR if anchor is None else float(anchor)
        if not np.isfinite(self.anchor) or self.anchor < 0:
            raise ValueError(f"anchor must be a finite weight >= 0, got {anchor!r}")
        self.continuity = DEFAULT_CONTINUITY if continuity is None else float(continuity)
        if not np.isfinite(self.continuity) or self.continuity < 0:
            raise ValueError(f"continuity must be a finite weight >= 0, got {continuity!r}")
        if supersample is None:
            supersample = compare == "probability"
        if not isinstance(supersample, (bool, np.bool_)):
            raise ValueError(f"supersample must be True or False, got {supersample!r}")
        if isinstance(rounds, bool) or not isinstance(rounds, (int, np.integer)) or rounds < 1:
            raise ValueError(f"rounds must be a whole number from 1, got {rounds!r}")
        self.rounds = int(rounds)
        self._xatol, self._fatol = float(xatol), float(fatol)
        ranges = np.asarray(model.ranges, dtype=np.float64)
        self._ranges = (ranges[:, 0] - _RANGE_MARGIN, ranges[:, 1] + _RANGE_MARGIN)
        self.width, self.height = int(width), int(height)
        P = len(model.names)
        N = P + len(model.static_names)
        self._rest = np.vstack([model.rest, model.static_points])  # (N, 3)
        self._basis = np.zeros((K, N, 3))
        self._basis[:, :P] = model.basis
        self._sub_rest = self._rest[self.mesh.points]
        self._sub_basis = self._basis[:, self.mesh.points]
        self._centre = self._sub_rest[self.mesh.outer].mean(axis=0)
        offsets = np.asarray(appearance.key_points, dtype=np.float64) - self._rest  # (Q, N, 3): c_q
        flat = self._basis.reshape(K, -1)
        self._gram = flat @ flat.T / N
        self._key_cross = offsets.reshape(len(offsets), -1) @ flat.T / N
        self._key_square = (offsets.reshape(len(offsets), -1) ** 2).sum(axis=1) / N
        self._influence = np.asarray(appearance.influence, dtype=np.float64)
        self._camera = as_array(appearance.camera if camera is None else camera, "camera", shape=(3, 4))
        self._rows = 0.5 if field else 1.0
        # the box: its size fixed for the video, its place following the mouth
        self.factor = max(1, int(round(_BOX[0] * mouth_width / (box_pixels or _BOX_PIXELS))))
        self.box_width = int(np.ceil(_BOX[0] * mouth_width / self.factor))
        self.box_height = max(4, int(np.ceil(_BOX[1] * mouth_width * self._rows / self.factor)))
        # the frame pixels compared under each box pixel, (x, y) within its factor x factor: the middle
        # one, or all of them; the clone's textures are read at the same pixels' centres. One pixel off
        # the box pixel's centre (an even factor): the mesh is moved by the opposite, so the raster reads
        # at its pixels' centres, each through the triangle that covers the frame pixel's centre, which
        # also decides whether it is covered, as the clone's renderer decides (a read moved within the
        # box pixel goes through the map of the triangle under its centre)
        f = self.factor
        along = np.arange(f) if supersample else np.array([f // 2])
        self.supersample = len(along)
        self._picks = np.stack(np.meshgrid(along, along), axis=-1).reshape(-1, 2)
        offsets = (self._picks + 0.5) / f - 0.5  # (n, 2) box pixels from the box pixel's centre
        self._nudge = offsets[0] if len(offsets) == 1 else np.zeros(2)
        uv = np.asarray(appearance.uv, dtype=np.float64)[self.mesh.points]
        if compare == "probability":
            textures = np.asarray(appearance.lip_textures, dtype=np.float32)
        else:
            textures = np.asarray(appearance.textures, dtype=np.float32)
        S = textures.shape[1]
        corners = uv[self.mesh.outer]
        texels = S * np.ptp(corners[:, 0]) / max(mouth_width, 1e-9)  # a frame pixel's footprint
        filtered = prefilter(textures, texels)
        # only the texels under the analysis mesh (and a margin): the part of the textures read
        s = filtered.shape[1]
        at = uv * S / prefilter_block(texels)  # in the filtered texture's texels (its texel J spans k of S's)
        # the margin: a bilinear read's reach, and up to half a box pixel more (reads off a pixel's centre;
        # with a field, a box pixel spans twice as many of the frame's rows)
        margin = 2 + int(np.ceil(0.5 * texels * f * (2 if field else 1) / prefilter_block(texels)))
        lo = np.maximum(np.floor(at.min(axis=0)) - margin, 0).astype(int)
        hi = np.minimum(np.ceil(at.max(axis=0)) + margin, s).astype(int)
        part = np.ascontiguousarray(filtered[:, lo[1]:hi[1], lo[0]:hi[0]])
        uv = (at - lo) / (hi - lo)
        # colours: -1 where the mesh does not reach (the mouth's opening), a value no texel has
        options = dict(width=self.box_width, height=self.box_height, offsets=None if len(offsets) == 1 else offsets,
                       background=0.0 if compare == "probability" else _UNCOVERED)
        if raster == "numpy":
            self.raster = NumpyLipRaster(self.mesh.triangles, uv, part, **options)
        elif raster == "gl":
            self.raster = GlLipRaster(self.mesh.triangles, uv, part, **options)
        else:
            try:
                self.raster = GlLipRaster(self.mesh.triangles, uv, part, **options)
            except (ImportError, RuntimeError):  # no moderngl, or no EGL here
                self.raster = NumpyLipRaster(self.mesh.triangles, uv, part, **options)
        self.colour = appearance.colour

    # ---- geometry

    def full_points(self, parameters) -> np.ndarray:
        """(N, 3) the mobile then static points at ``parameters (K,)`` (cm, head frame)."""
        return self._rest + np.tensordot(parameters, self._basis, axes=1)

    def pixels(self, points, pose) -> np.ndarray:
        """(N, 2) the frames' pixel coordinates (x right, y down; one field's rows with ``field``) of
        head-frame ``points`` under ``pose``."""
        xy = project_posed(self._camera, pose, points) * [self.width, self.height / self._rows]
        if self.field:
            xy[:, 1] = (xy[:, 1] - (self.field == "bottom") + 0.5) / 2.0
        return xy

    def box_origin(self, parameters, pose) -> tuple[int, int]:
        """The box's top-left frame pixel for the mouth at ``parameters`` and ``pose`` (it may lie
        outside the frame: see :meth:`box_inside`)."""
        lips = self.pixels(self._sub_rest[self.mesh.outer] + np.tensordot(
            parameters, self._sub_basis[:, self.mesh.outer], axes=1), pose)
        centre = lips.mean(axis=0)
        return (int(round(centre[0] - 0.5 * self.box_width * self.factor)),
                int(round(centre[1] - 0.5 * self.box_height * self.factor)))

    def box_inside(self, origin) -> bool:
        x0, y0 = origin
        return (x0 >= 0 and y0 >= 0 and x0 + self.box_width * self.factor <= self.width
                and y0 + self.box_height * self.factor <= self.height)

    def pose_of(self, base_pose, correction) -> np.ndarray:
        return base_pose if not self.rigid else base_pose @ rigid_transform(correction, self._centre)

    # ---- images

    def frame_image(self, image, origin) -> np.ndarray:
        """``(box_height, box_width) float32`` (``compare="probability"``: the lip probability of
        ``image``) or ``(box_height, box_width, 3) float32`` (``"colour"``: its RGB) over the box at
        ``origin``: under each box pixel the frame's middle pixel (with ``supersample``, the mean of all
        of them)."""
        x0, y0 = origin
        f = self.factor
        crop = np.ascontiguousarray(image[y0:y0 + self.box_height * f, x0:x0 + self.box_width * f])
        if self.compare != "colour":
            crop = np.asarray(self.colour.probability(crop), dtype=np.float32)[..., None]
        blocks = crop.reshape(self.box_height, f, self.box_width, f, -1)
        if len(self._picks) < f * f:  # (n, box_height, box_width, C): the picked pixels, averaged
            mean = blocks[:, self._picks[:, 1], :, self._picks[:, 0]].mean(axis=0, dtype=np.float32)
        else:
            mean = blocks.mean(axis=(1, 3), dtype=np.float32)
        return mean if self.compare == "colour" else mean[..., 0]

    def weights(self, parameters) -> np.ndarray:
        """``(Q,)`` the appearance's blending weights at ``parameters (K,)``: ``Appearance.weights`` of
        the posture's points, its RMS distances to the key postures written as a quadratic form of the
        parameters (``|c_q - B a|^2 / N``), a K x K product instead of N points."""
        from .appearance import blend_weights

        a = np.asarray(parameters, dtype=np.float64)
        square = self._key_square - 2.0 * self._key_cross @ a + a @ self._gram @ a
        if square.min() > 1e-18:  # away from a key posture: c_q / d_q normalised, blend_weights' ratio
            share = self._influence / np.sqrt(square)
            return share / share.sum()
        return blend_weights(np.sqrt(np.maximum(square, 0.0)), self.appearance.influence)

    def clone_image(self, parameters, pose, origin, shift=(0.0, 0.0)) -> np.ndarray:
        """``(box_height, box_width) float32``: the clone's lip probability over the box at ``origin``
        (``(box_height, box_width, 3)``, its colours, -1 where the mesh does not reach, for ``"colour"``),
        moved by ``shift (2,)`` box pixels."""
        return self._draw(np.asarray(parameters, dtype=np.float64), self._projector(pose, origin), shift)

    def _projector(self, pose, origin) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """What places the analysis mesh in the box under ``pose`` with the box at ``origin``, once a
        frame: the mesh's homogeneous image coordinates are ``h0 + a @ hb`` (``(V, 3)``, ``(K, 3 V)``:
        the camera and the pose folded into the rest shape and the basis), its box pixels
        ``h[:, :2] / h[:, 2] * scale + offset`` (:meth:`pixels`, less ``origin``, over ``factor``, less the
        compared frame pixel's place in its box pixel when it is one off the centre)."""
        P = self._camera[:, :3] @ pose[:3, :3]
        p = self._camera[:, :3] @ pose[:3, 3] + self._camera[:, 3]
        h0 = self._sub_rest @ P.T + p
        hb = (self._sub_basis @ P.T).reshape(len(self._sub_basis), -1)
        x0, y0 = origin
        if self.field:  # one field's rows: (y - bottom + 0.5) / 2
            scale = np.array([self.width, self.height / self._rows / 2.0]) / self.factor
            offset = np.array([-x0, (0.5 - (self.field == "bottom")) / 2.0 - y0]) / self.factor
        else:
            scale = np.array([self.width, self.height / self._rows]) / self.factor
            offset = np.array([-x0, -y0], dtype=np.float64) / self.factor
        return h0, hb, scale, offset - self._nudge

    def _draw(self, parameters: np.ndarray, projector, shift=None) -> np.ndarray:
        """:meth:`clone_image` with the frame's :meth:`_projector`."""
        h0, hb, scale, offset = projector
        h = h0 + (parameters @ hb).reshape(h0.shape)
        xy = h[:, :2] / h[:, 2:3] * scale + offset
        if shift is not None:
            xy += shift
        return self.raster(xy, self.weights(parameters))

    def lip_mask(self, parameters, pose, origin, shape) -> np.ndarray:
        """(h, w) bool: the frame's pixels (from ``origin``, ``shape``) between the clone's outer and
        inner lip contours at ``parameters`` and ``pose`` (a pixel's centre inside the polygon)."""
        import cv2

        # cv2 fills about integer coordinates as pixel centres; ours lie at j + 0.5
        xy = self.pixels(self.full_points(parameters)[self.mesh.points], pose) - origin - 0.5
        mask = np.zeros(shape, np.uint8)
        cv2.fillPoly(mask, [np.round(xy[self.mesh.outer] * 16).astype(np.int32)], 1, shift=4)
        cv2.fillPoly(mask, [np.round(xy[self.mesh.inner] * 16).astype(np.int32)], 0, shift=4)
        return mask.astype(bool)

    def adapt(self, images, parameters, poses) -> None:
        """Adapt the colour model to the video's lighting from its first frames: ``images`` (a few
        frames), the clone's ``parameters`` and ``poses`` on them (the landmark-based analysis) giving
        each frame's lip pixels."""
        crops, masks = [], []
        for image, a, pose in zip(images, parameters, poses, strict=True):
            origin = self.box_origin(a, pose)
            if not self.box_inside(origin):
                continue
            h, w = self.box_height * self.factor, self.box_width * self.factor
            crops.append(image[origin[1]:origin[1] + h, origin[0]:origin[0] + w])
            masks.append(self.lip_mask(a, pose, origin, (h, w)))
        if crops and np.concatenate(masks).any():
            self.colour = self.appearance.colour.adapted(np.ascontiguousarray(np.concatenate(crops)),
                                                         np.concatenate(masks))

    # ---- the simplex

    def _colour_residual(self, clone: np.ndarray) -> np.ndarray:
        """``(3 n,)``: what :meth:`_colour_difference` sums the squares of (before dividing by the
        frame's variance), pixel by pixel: the frame's centred colours less the clone's, gained, where
        the mesh reaches; the frame's colours less their mean elsewhere."""
        t = self._target[0]
        m = clone[..., 0].reshape(-1) > _UNCOVERED
        c = clone.reshape(-1, 3).astype(np.float64)
        r = np.empty_like(t)
        if m.any():
            cm, tm = c[m] - c[m].mean(axis=0), t[m] - t[m].mean(axis=0)
            cc, ct = (cm * cm).sum(axis=0), (cm * tm).sum(axis=0)
            gain = np.where((cc > 0) & (ct > 0), ct / np.where(cc > 0, cc, 1.0), 0.0)
            r[m] = tm - gain * cm
        if not m.all():
            r[~m] = t[~m] - t[~m].mean(axis=0)
        return r.reshape(-1)

    def _set_target(self, target: np.ndarray) -> None:
        """Keep the frame's box image's sums for :meth:`_colour_difference`, and its colour variance over
        the box (the colour comparison's unit, never 0)."""
        if self.compare != "colour":
            return
        t = np.ascontiguousarray(target, dtype=np.float64).reshape(-1, 3)
        self._square = t * t
        self._target = (t, self._square.sum(axis=0), t.sum(axis=0), float(len(t)))
        self._sums = np.hstack([np.ones((len(t), 1)), t, self._square])  # (n, 7): 1, colours, their squares
        self._features = np.empty((4, len(t)))
        self._scale = max(float(((t - t.mean(axis=0)) ** 2).sum()), 1e-6)

    def _colour_difference(self, clone: np.ndarray, target: np.ndarray) -> float:
        """The share of the frame's colour variance over the box that the clone leaves unexplained: per
        channel, over the pixels the mesh covers, the frame's colours against ``g * clone + b`` with the
        least-squares gain ``g >= 0`` and offset ``b`` (a change of lighting, exact for the clone's own
        frames under a tinted gain); over the pixels it leaves (the mouth's opening, what the textures do
        not hold), against their own mean colour. 0: the clone explains the box exactly."""
        t, tt_all, t_all, n_all = self._target  # the frame's pixels (n, 3), and its sums of squares, sums, count
        f = self._features  # (4, n): covered (0 or 1), then the clone's colours where covered, 0 elsewhere
        f[1:] = clone.reshape(-1, 3).T
        np.greater(f[1], _UNCOVERED, out=f[0])
        f[1:] *= f[0]
        ff, ft = f @ f.T, f @ self._sums  # the sums over the covered pixels, two small products
        n = ff[0, 0]
        if n == 0:
            return float((tt_all - t_all * t_all / n_all).sum()) / self._scale
        sc, st, stt = ff[0, 1:], ft[0, 1:4], ft[0, 4:]
        scc, sct = ff.diagonal()[1:], ft[1:, 1:4].diagonal()
        cc, ct, tt = scc - sc * sc / n, sct - sc * st / n, stt - st * st / n  # centred, over the covered pixels
        explained = np.where((cc > 0) & (ct > 0), ct * ct / np.where(cc > 0, cc, 1.0), 0.0)
        left = float((tt - explained).sum())
        if n < n_all:  # the rest about its own mean
            su, suu = t_all - st, tt_all - stt
            left += float((suu - su * su / (n_all - n)).sum())
        return left / self._scale

    def _difference(self, clone: np.ndarray, target: np.ndarray) -> float:
        """Mean squared difference of ``target`` and ``clone`` once the clone's probabilities are put on
        the frame's scale: ``g * clone + b`` with the least-squares gain ``g >= 0`` and offset ``b``. The
        textures' probabilities (learnt on the key frames, read through a blur) and the frame's (the
        adapted colour model, at the frame's sharpness) differ in contrast; the shape is what counts."""
        if self.blur:
            import cv2

            clone = cv2.GaussianBlur(clone, (0, 0), self.blur)
        if self.compare == "colour":
            return self._colour_difference(clone, target)
        c = clone.reshape(-1) - clone.mean()
        t = target.reshape(-1) - target.mean()
        if not self.photometric:
            return float(np.mean((clone - target) ** 2))
        cc = float(c @ c)
        gain = max(float(c @ t) / cc, 0.0) if cc > 0 else 0.0
        return float(np.mean((t - gain * c) ** 2))

    def _beyond(self, parameters: np.ndarray) -> float:
        """The walls on the parameters: ``walls x`` the squared distance (in standard deviations) beyond
        the model's ranges widened by :data:`_RANGE_MARGIN`, 0 inside; no pull within the speaker's
        range (the prior's), but no wandering far beyond it where the image cannot tell."""
        lo, hi = self._ranges
        out = np.maximum(parameters - hi, 0.0) + np.maximum(lo - parameters, 0.0)
        return self.walls * float(out @ out)

    def _prior_hessian(self, dimension: int) -> np.ndarray:
        """(D,) the diagonal of the prior's Hessian over the simplex's D coordinates."""
        K = self.model.parameter_count
        h = np.full(dimension, 2.0 * self.prior / K)
        if self.rigid:
            h[K:K + 6] = 2.0 * self.prior / 6.0 / _RIGID_STEPS ** 2
        if self.shift:
            h[-2:] = 0.0
        return h

    def _shaped_simplex(self, x0: np.ndarray, evaluate, anchored=None, toward=None,
                        strength: float = 0.0) -> np.ndarray:
        """The simplex's first vertices shaped by the cost around ``x0``, after :attr:`rounds` damped
        Gauss-Newton (Levenberg-Marquardt) steps: the colour residual's Jacobian by finite differences
        (D evaluations a round, D + 1 the first) gives a Gauss-Newton Hessian ``H`` (the prior's, the
        walls' and the reading's pull added); a damped step is tried (one evaluation; a step that does
        not lower the cost is tried again more damped, up to :data:`_LM_TRIES` times, and the rounds end
        there); the simplex then starts from the best point, its edges along the last ``H``'s
        eigenvectors, each as long as raises the cost by :data:`_SIMPLEX_RISE` of the start's (between
        0.02 and 1 of a first step). Nelder-Mead's moves are affine, so a simplex shaped like the valley
        searches it as a round one searches a round valley: correlated parameters (the jaw against the
        lower lip) no longer stall it.

        With ``toward`` (the weighted mean of :meth:`analyse`'s reading and previous answer), the pull's
        weight is ``strength`` times the measured curvature, set on the first round
        (:data:`DEFAULT_ANCHOR`): ``anchored(weight, x0)`` sets it and returns the cost at ``x0`` with
        it; the steps and the simplex's shape then include it."""
        D, K = len(x0), self.model.parameter_count
        steps = self._simplex(x0)[1:].diagonal() - x0  # the plain first steps: the differences' scale
        prior = self._prior_hessian(D)
        lo, hi = self._ranges
        x, (value, r) = x0, evaluate(x0, residual=True)
        weight, damping = 0.0, _DAMPING
        for round_ in range(self.rounds):
            J = np.empty((len(r), D))
            for i in range(D):
                y = x.copy()
                y[i] += _DIFFERENCE * steps[i]
                J[:, i] = (evaluate(y, residual=True)[1] - r) / (_DIFFERENCE * steps[i])
            gradient = 2.0 * J.T @ r / self._scale + prior * x
            H = 2.0 * J.T @ J / self._scale + np.diag(prior)
            if round_ == 0 and toward is not None and strength > 0:  # the pull, scaled by the image's curvature
                weight = strength * float(np.trace(H[:K, :K])) / K
                value = anchored(weight, x)
            a = x[:K]
            outside = (a > hi) | (a < lo)  # the walls, quadratic beyond the ranges
            gradient[:K] += 2.0 * self.walls * (np.maximum(a - hi, 0.0) - np.maximum(lo - a, 0.0))
            H[:K, :K] += np.diag(2.0 * self.walls * outside)
            if weight > 0:
                gradient[:K] += 2.0 * weight * (a - toward)
                H[:K, :K] += 2.0 * weight * np.eye(K)
            improved = False
            for _ in range(_LM_TRIES if self.rounds > 1 else 1):
                damped = H + damping * np.diag(np.diag(H))
                move = -np.linalg.lstsq(damped, gradient, rcond=None)[0]  # lstsq: a parameter the box does not see
                reach = np.max(np.abs(move) / steps)
                if reach > _MAX_MOVE:  # at most a few first steps in any coordinate
                    move *= _MAX_MOVE / reach
                tried, r_tried = evaluate(x + move, residual=True)
                if tried < value:
                    x, value, r, improved = x + move, tried, r_tried, True
                    damping = max(damping / 3.0, 1e-3)
                    break
                damping *= 4.0
            if not improved:
                break
        e, V = np.linalg.eigh(H)
        scale = np.linalg.norm(V * steps[:, None], axis=0)  # a first step along each eigenvector
        length = np.sqrt(_SIMPLEX_RISE * value / np.maximum(e, 1e-12))
        length = np.clip(length, 0.02 * scale, scale)
        return np.vstack([x, x + (V * length).T])

    def _simplex(self, x0: np.ndarray) -> np.ndarray:
        K = self.model.parameter_count
        steps = np.full(len(x0), _STEP_ARTICULATORY)
        if self.rigid:
            steps[K:K + 3], steps[K + 3:K + 6] = _STEP_ROTATION, _STEP_TRANSLATION
        if self.shift:
            steps[-2:] = _STEP_SHIFT
        return np.vstack([x0, x0 + np.diag(steps)])

    def _unpack(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The simplex's coordinates as (parameters (K,), rigid correction (6,), shift (2,))."""
        K = self.model.parameter_count
        correction = x[K:K + 6] if self.rigid else np.zeros(6)
        shift = x[len(x) - 2:] if self.shift else np.zeros(2)
        return x[:K], correction, shift

    def _pack(self, parameters, correction, shift) -> np.ndarray:
        return np.concatenate([parameters, *([correction] if self.rigid else []), *([shift] if self.shift else [])])

    def analyse(self, image, start, base_pose, correction=None, *, also=None, shift=None,
                reading=None, previous=None) -> FrameAnswer:
        """One frame: the parameters (and with ``rigid`` the correction, with ``shift`` the clone's
        shift in the image) minimising the difference, from ``start (K,)`` (and ``correction (6,)``,
        ``shift (2,)``); the box placed at the start. ``also (M, K)``: other starts (the landmark-based
        analysis of the frame), each costing one evaluation; the simplex starts from the best of them.

        ``image``: ``(height, width, 3) uint8`` (one field's rows with ``field``); ``base_pose (4, 4)``:
        the tracker's head pose on that frame; ``reading (K,)``: the frame's landmark-based analysis (the
        tracker's own reading of the lips), toward which the answer is pulled where the image is flat
        (:data:`DEFAULT_ANCHOR`; None: no pull); ``previous (K,)``: the previous frame's answer, toward
        which it is pulled likewise (:data:`DEFAULT_CONTINUITY`; None: no pull). With both, one pull
        toward their weighted mean."""
        K = self.model.parameter_count
        start = as_array(start, "start", shape=(K,))
        reading = None if reading is None else as_array(reading, "reading", shape=(K,))
        previous = None if previous is None else as_array(previous, "previous", shape=(K,))
        # the pulls toward the reading and the previous answer, as one toward their weighted mean
        shares = [(w, at) for w, at in ((self.anchor, reading), (self.continuity, previous))
                  if at is not None and w > 0]
        strength = sum(w for w, _ in shares)
        toward = sum(w * at for w, at in shares) / strength if shares else None
        correction = np.zeros(6) if correction is None else as_array(correction, "correction", shape=(6,))
        shift = np.zeros(2) if shift is None or not self.shift else as_array(shift, "shift", shape=(2,))
        base_pose = as_array(base_pose, "base_pose", shape=(4, 4))
        origin = self.box_origin(start, self.pose_of(base_pose, correction))
        if not self.box_inside(origin):
            raise InputError("the mouth leaves the frame")
        target = self.frame_image(image, origin)
        if self.blur:
            import cv2

            target = cv2.GaussianBlur(target, (0, 0), self.blur)
        self._set_target(target)
        count = 0
        best = [np.inf, None]
        projector = self._projector(base_pose, origin)  # the pose fixed: the mesh's projection folded once
        seen = []  # (cost without the reading's pull, x): the best is chosen again when the pull is set
        pull = [0.0 if self.precondition and self.compare == "colour" else strength]

        def pulled(x) -> float:
            if toward is None or pull[0] == 0.0:
                return 0.0
            d = x[:K] - toward
            return pull[0] * float(d @ d)

        def anchored(weight, x):
            pull[0] = weight
            values = [v + pulled(y) for v, y in seen]
            i = int(np.argmin(values))
            best[0], best[1] = values[i], seen[i][1].copy()
            same = [v for v, y in seen if np.array_equal(y, x)]
            return same[0] + pulled(x) if same else evaluate(x)

        def evaluate(x, residual=False):
            nonlocal count
            if count >= self.max_evals:
                raise _Spent
            count += 1
            a, c, moved = self._unpack(x)
            clone = self._draw(a, self._projector(self.pose_of(base_pose, c), origin) if self.rigid else projector,
                               moved if self.shift else None)
            if residual:
                r = self._colour_residual(clone)
                value = float(r @ r) / self._scale
            else:
                value = self._difference(clone, target)
            value += self._beyond(a)
            if self.prior:
                value += self.prior * float(a @ a) / len(a)
            if self.rigid:  # the correction held near the tracker's pose: one simplex step costs as one std
                value += self.prior * np.mean((c / _RIGID_STEPS) ** 2)
            if self.shift:  # the shift held within a few pixels of the tracker's place
                value += self.walls * float(np.sum(np.maximum(np.abs(moved) - _MAX_SHIFT, 0.0) ** 2))
            if toward is not None:
                seen.append((value, x.copy()))
                value += pulled(x)
            if value < best[0]:
                best[0], best[1] = value, x.copy()
            return (value, r) if residual else value

        x0 = self._pack(start, correction, shift)
        try:
            if also is not None:
                evaluate(x0)
                for other in np.asarray(also, dtype=np.float64).reshape(-1, K):
                    if np.isfinite(other).all():
                        evaluate(self._pack(other, correction, shift))
                x0 = best[1].copy()
            simplex = self._simplex(x0)
            if self.compare == "colour" and self.precondition:
                simplex = self._shaped_simplex(x0, evaluate, anchored, toward, strength)
            minimize(evaluate, simplex[0], method="Nelder-Mead",
                     options={"initial_simplex": simplex, "maxfev": self.max_evals, "xatol": self._xatol,
                              "fatol": self._fatol})
        except _Spent:
            pass
        a, found, moved = self._unpack(best[1])
        return FrameAnswer(a, found, self.pose_of(base_pose, found), count, best[0], moved)

    def close(self):
        self.raster.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
