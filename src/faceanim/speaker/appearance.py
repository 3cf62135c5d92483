"""The clone's appearance: key postures with their textures, and how a posture blends them.

A few key postures of the speaker (three: rest, open, rounded; :func:`choose_key_frames`) each give a
texture, taken from the video frame where the posture was held and re-projected once onto one common
parametrisation of the mesh (:func:`texture_uv`: a normalised frontal view of the rest shape), so that
drawing any posture is a per-pixel mix of images and one textured pass. The mix's weights vary
continuously with the distance between the posture's points and each key posture's points
(:meth:`Appearance.weights`): no switching and no jumps in time; they sum to 1 and are one-hot at a
key posture.

The appearance lives in the speaker model's ``.npz`` under entries named ``appearance_*``, written and
read by this module (:func:`write_appearance`, :func:`read_appearance`); the model's own entries
(:mod:`.speakerfile`) are left as they are, so a model with an appearance still reads as a model, and
one without reads with no appearance.
"""

from __future__ import annotations

import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import FileFormatError, InputError
from ..landmarks import LIP_INNER, LIP_OUTER
from ..validation import as_array, as_index_array
from .colour import ColourModel

__all__ = ["Appearance", "APPEARANCE_VERSION", "TEXTURE_SIZE", "KEY_NAMES",
           "lip_indices", "posture_points", "blend_weights", "influence_of", "write_appearance",
           "read_appearance", "has_appearance"]

APPEARANCE_VERSION = 1
TEXTURE_SIZE = 512
KEY_NAMES = ("rest", "open", "rounded")



def lip_indices(names, landmarks) -> tuple[np.ndarray, np.ndarray]:
    """``(outer, inner)`` indices into ``names`` (the mesh's points, mobile then static) of the lips'
    outer and inner contours, in order around the mouth. ``landmarks``: the names of MediaPipe's
    landmarks in their order (a capture's ``Motion.names``), which tell which name each contour
    landmark goes by.

    Raises
    ------
    ValueError
        A contour point is not among ``names``.
    """
    landmarks = tuple(landmarks)
    if len(landmarks) <= max(LIP_OUTER + LIP_INNER):
        raise ValueError(f"landmarks must name MediaPipe's landmarks in order, got {len(landmarks)} names")
    lookup = {n: i for i, n in enumerate(names)}
    contours = []
    for contour in (LIP_OUTER, LIP_INNER):
        missing = [landmarks[i] for i in contour if landmarks[i] not in lookup]
        if missing:
            raise ValueError(f"the mesh lacks the lip contour's points {', '.join(missing[:4])}")
        contours.append(np.array([lookup[landmarks[i]] for i in contour], dtype=np.int64))
    return contours[0], contours[1]


def posture_points(model, parameters) -> np.ndarray:
    """``(T, N, 3)`` the mesh's points (the model's mobile points at ``parameters (T, K)``, then its
    static points), cm, head frame."""
    mobile = model.points(parameters)
    static = np.broadcast_to(model.static_points, (len(mobile), *model.static_points.shape))
    return np.concatenate([mobile, static], axis=1)


def blend_weights(distances, influence) -> np.ndarray:
    """``(..., Q)`` blending weights of postures at ``distances (..., Q)`` from the key postures.

    Inverse-distance weighting, ``w_q ~ c_q / d_q``, written without division as
    ``w_q = c_q prod_{j != q} d_j / sum_i c_i prod_{j != i} d_j``: a ratio of products of distances,
    continuous everywhere, summing to 1, exactly one-hot where a posture is a key posture (``d_q = 0``),
    and ``c_q`` (the influence) widening a key posture's share. (The first power of the distance: on the
    talking clips d12 and d20, not the speech clips the benchmark reports, it re-rendered held-out mouths
    closer than the square, 24.1 and 25.0 dB against 23.7 and 25.0, SSIM 0.756 and 0.784 against 0.751
    and 0.769, and the fourth power further still.)

    >>> blend_weights(np.array([0.0, 1.0, 2.0]), np.ones(3)).tolist()
    [1.0, 0.0, 0.0]
    >>> np.round(blend_weights(np.array([1.0, 1.0, 2.0]), np.ones(3)), 3).tolist()
    [0.4, 0.4, 0.2]
    """
    d = np.asarray(distances, dtype=np.float64)
    c = np.asarray(influence, dtype=np.float64)
    Q = d.shape[-1]
    scale = d.max(axis=-1, keepdims=True)
    d = d / np.where(scale > 0, scale, 1.0)  # products of Q - 1 distances kept near 1
    others = np.stack([np.prod(np.delete(d, q, axis=-1), axis=-1) for q in range(Q)], axis=-1)
    numerator = c * others
    total = numerator.sum(axis=-1, keepdims=True)
    tied = total <= 0  # two key postures at once (coincident keys): share between those at distance 0
    if np.any(tied):
        zero = (d == 0).astype(np.float64) * c
        numerator = np.where(tied, zero, numerator)
        total = numerator.sum(axis=-1, keepdims=True)
    return numerator / total


def influence_of(key_points) -> np.ndarray:
    """``(Q,)`` the key postures' influence coefficients: each key posture's mean distance (RMS over
    points) to the others, over their mean, so a posture far from the others reaches further."""
    k = as_array(key_points, "key_points", shape=("Q", "N", 3))
    if len(k) == 1:
        return np.ones(1)
    d = np.sqrt((((k[:, None] - k[None]) ** 2).sum(axis=-1)).mean(axis=-1))
    mean = d.sum(axis=1) / (len(k) - 1)
    return mean / mean.mean() if mean.mean() > 0 else np.ones(len(k))


@dataclass(frozen=True, eq=False)
class Appearance:
    """A speaker clone's appearance; immutable, checked on construction.

    Parameters
    ----------
    uv : (N, 2) float32
        Each mesh point's place in the textures, in [0, 1] (u across from the left, v down from the
        top row). ``N`` = the model's mobile then static points; the mesh is the model's triangles.
    key_parameters : (Q, K) float64
        The key postures' articulatory parameters.
    key_points : (Q, N, 3) float64
        Their points (cm, head frame).
    textures : (Q, S, S, 3) uint8
        Their textures over ``uv`` (``S`` = 512).
    lip_textures : (Q, S, S) float32
        Each texture's lip probability (``colour.probability(textures[q])``).
    influence : (Q,) float64
        The influence coefficients (:func:`influence_of`).
    colour : ColourModel
        The lip/skin colour model learnt from the key frames.
    camera : (3, 4) float64
        The video's projection to normalised screen coordinates (:mod:`.camera`).
    triangles : (F, 3) int64, optional
        The synthesis mesh (a part of the model's triangles within the original's bounds); None: all.
    key_frames : (Q,) int64, optional
        The video frames the key postures come from (-1 where unknown).
    key_rigid : (Q, 6) float64, optional
        The head's rigid motion in those frames (rotation vector, translation cm; :mod:`.camera`).
    frame_size : (2,) int64, optional
        Width and height of that video in pixels (0, 0 where unknown).
    lip_outer, lip_inner : (n,) int64, optional
        Indices into the ``N`` points of the lips' outer and inner contours (:func:`lip_indices`).
    key_names : tuple of str, optional
    """

    uv: np.ndarray
    key_parameters: np.ndarray
    key_points: np.ndarray
    textures: np.ndarray
    lip_textures: np.ndarray
    influence: np.ndarray
    colour: ColourModel
    camera: np.ndarray
    triangles: np.ndarray | None = None
    key_frames: np.ndarray | None = None
    key_rigid: np.ndarray | None = None
    frame_size: tuple[int, int] = (0, 0)
    lip_outer: np.ndarray = ()
    lip_inner: np.ndarray = ()
    key_names: tuple[str, ...] = ()

    def __post_init__(self):
        uv = as_array(self.uv, "uv", shape=("N", 2), dtype=np.float32, frozen=True)
        if uv.min(initial=0) < 0 or uv.max(initial=0) > 1:
            raise ValueError("uv must lie in [0, 1]")
        N = len(uv)
        key_parameters = as_array(self.key_parameters, "key_parameters", shape=("Q", "K"), min_length=1, frozen=True)
        Q = len(key_parameters)
        key_points = as_array(self.key_points, "key_points", shape=(Q, N, 3), frozen=True)
        textures = np.asarray(self.textures)
        if textures.dtype != np.uint8 or textures.ndim != 4 or textures.shape[0] != Q or textures.shape[3] != 3 \
                or textures.shape[1] != textures.shape[2]:
            raise ValueError(f"textures must be ({Q}, S, S, 3) uint8, got {textures.dtype} {textures.shape}")
        textures = np.array(textures, copy=True)
        textures.flags.writeable = False
        S = textures.shape[1]
        lip_textures = as_array(self.lip_textures, "lip_textures", shape=(Q, S, S), dtype=np.float32, frozen=True)
        influence = as_array(self.influence, "influence", shape=(Q,), frozen=True)
        if (influence <= 0).any():
            raise ValueError("influence must be positive")
        if not isinstance(self.colour, ColourModel):
            raise TypeError(f"colour must be a ColourModel, got {type(self.colour).__name__}")
        camera = as_array(self.camera, "camera", shape=(3, 4), frozen=True)
        triangles = None if self.triangles is None else as_index_array(self.triangles, "triangles", upper=N,
                                                                        shape=("F", 3), frozen=True)
        frames = np.full(Q, -1, np.int64) if self.key_frames is None else self.key_frames
        frames = as_array(frames, "key_frames", shape=(Q,), dtype=np.int64, frozen=True)
        rigid = None if self.key_rigid is None else as_array(self.key_rigid, "key_rigid", shape=(Q, 6), frozen=True)
        size = tuple(int(v) for v in self.frame_size)
        if len(size) != 2 or min(size) < 0:
            raise ValueError(f"frame_size must be (width, height), got {self.frame_size!r}")
        outer = as_index_array(self.lip_outer, "lip_outer", upper=N, frozen=True)
        inner = as_index_array(self.lip_inner, "lip_inner", upper=N, frozen=True)
        names = tuple(str(n) for n in self.key_names) or tuple(
            KEY_NAMES[q] if Q == len(KEY_NAMES) else f"key{q + 1}" for q in range(Q))
        if len(names) != Q:
            raise ValueError(f"key_names must name the {Q} key postures, got {len(names)}")
        for name, value in (("uv", uv), ("key_parameters", key_parameters), ("key_points", key_points),
                            ("textures", textures), ("lip_textures", lip_textures), ("influence", influence),
                            ("camera", camera), ("triangles", triangles), ("key_frames", frames),
                            ("key_rigid", rigid), ("frame_size", size), ("lip_outer", outer),
                            ("lip_inner", inner), ("key_names", names)):
            object.__setattr__(self, name, value)

    @property
    def size(self) -> int:
        """``S``, the textures' side in texels."""
        return self.textures.shape[1]

    def distances(self, points) -> np.ndarray:
        """``(Q,)`` or ``(T, Q)``: RMS distance (cm) of a posture's ``points (N, 3)`` or ``(T, N, 3)`` to
        each key posture's."""
        x = np.asarray(points, dtype=np.float64)
        if x.shape[-2:] != self.key_points.shape[1:] or x.ndim not in (2, 3):
            raise ValueError(f"points must have shape (N, 3) or (T, N, 3) with N = {len(self.uv)}, got {x.shape}")
        difference = x[..., None, :, :] - self.key_points
        return np.sqrt((difference**2).sum(axis=-1).mean(axis=-1))

    def weights(self, points) -> np.ndarray:
        """``(Q,)`` or ``(T, Q)`` blending weights of a posture's ``points (N, 3)`` or ``(T, N, 3)``
        (:func:`blend_weights` of :meth:`distances` with :attr:`influence`): continuous, summing to 1,
        one-hot at a key posture."""
        return blend_weights(self.distances(points), self.influence)


# ---- storage in the speaker's .npz, beside the model's own entries

_PREFIX = "appearance_"


def has_appearance(path) -> bool:
    """Whether the speaker file ``path`` holds an appearance (``faceanim speaker textures``)."""
    try:
        with zipfile.ZipFile(path) as archive:
            return any(n.startswith(_PREFIX) for n in archive.namelist())
    except (OSError, zipfile.BadZipFile):
        return False


def write_appearance(model_path, appearance: Appearance, output) -> Path:
    """Write the speaker file ``model_path`` with ``appearance`` added (an earlier one replaced) to
    ``output`` (which may be ``model_path``), complete or not at all."""
    from ..atomic import atomic_output
    from .speakerfile import read_speaker

    read_speaker(model_path)  # a valid model, or one line saying why not
    with np.load(model_path, allow_pickle=False) as archive:
        kept = {k: archive[k] for k in archive.files if not k.startswith(_PREFIX)}
    a = appearance
    colour = a.colour
    arrays = {"version": np.array(APPEARANCE_VERSION), "uv": a.uv, "key_parameters": a.key_parameters,
              "key_points": a.key_points, "textures": a.textures, "lip_textures": a.lip_textures,
              "influence": a.influence, "lip_mean": colour.lip_mean, "skin_mean": colour.skin_mean,
              "covariance": colour.covariance, "camera": a.camera, "key_frames": a.key_frames,
              "frame_size": np.array(a.frame_size, dtype=np.int64), "lip_outer": a.lip_outer,
              "lip_inner": a.lip_inner, "key_names": np.array(a.key_names, dtype=str)}
    if a.triangles is not None:
        arrays["triangles"] = a.triangles
    if a.key_rigid is not None:
        arrays["key_rigid"] = a.key_rigid
    output = Path(output)
    with atomic_output(output) as tmp, open(tmp, "wb") as handle:
        np.savez_compressed(handle, **kept, **{_PREFIX + k: v for k, v in arrays.items()})
    return output


def read_appearance(path) -> Appearance | None:
    """The appearance in the speaker file ``path``; None if it has none (a model not yet given textures).

    Raises
    ------
    InputError
        The file is missing.
    FileFormatError
        Not an ``.npz``, an appearance of another version, or entries missing or of the wrong shape.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: no such file")
    if not zipfile.is_zipfile(path):
        raise FileFormatError(path, "is not a speaker model (not an .npz archive)")
    try:
        with np.load(path, allow_pickle=False) as archive:
            data = {k[len(_PREFIX):]: archive[k] for k in archive.files if k.startswith(_PREFIX)}
    except (zipfile.BadZipFile, ValueError, EOFError) as exc:
        raise FileFormatError(path, f"is not a speaker model (an .npz archive): {exc}") from None
    if not data:
        return None
    version = data.get("version")
    if version is None or version.ndim != 0 or version.dtype.kind not in "iu" or int(version) != APPEARANCE_VERSION:
        raise FileFormatError(path, f"holds an appearance of another version; this faceanim reads version "
                                    f"{APPEARANCE_VERSION} (run faceanim speaker textures again)")
    needed = ("uv", "key_parameters", "key_points", "textures", "lip_textures", "influence", "lip_mean",
              "skin_mean", "covariance", "camera")
    missing = [k for k in needed if k not in data]
    if missing:
        raise FileFormatError(path, f"lacks the appearance's {', '.join(missing)}")
    try:
        colour = ColourModel(data["lip_mean"], data["skin_mean"], data["covariance"])
        return Appearance(
            data["uv"], data["key_parameters"], data["key_points"], data["textures"], data["lip_textures"],
            data["influence"], colour, data["camera"], triangles=data.get("triangles"),
            key_frames=data.get("key_frames"), key_rigid=data.get("key_rigid"),
            frame_size=tuple(data.get("frame_size", (0, 0))), lip_outer=data.get("lip_outer", ()),
            lip_inner=data.get("lip_inner", ()), key_names=tuple(str(n) for n in data.get("key_names", ())))
    except (ValueError, TypeError) as exc:
        raise FileFormatError(path, f"holds no valid appearance: {exc}") from None
