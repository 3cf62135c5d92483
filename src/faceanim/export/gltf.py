"""glTF 2.0 binary (``.glb``) with morph targets and a weights animation, through pygltflib.

An animation travels as morph targets (shapes added to the rest mesh) and per-frame weights, which
Blender imports as shape keys with an action and three.js as morph targets with an animation clip.
:func:`morphs_from_animation` finds few shapes that reproduce every frame (a truncated SVD of the
displacements, exact to a stated tolerance); named shapes (action units, visemes) can be written
directly for a viewer to drive as sliders.

What real clients play decides two choices:

- **Weights stay within [0, 1].** Blender's importer gives a shape key the slider range [0, 1],
  widened only by the first keyframe's weight, and clamps every other weight into it; so a signed
  SVD mode is written as two targets, its positive part and its negated negative part
  (``shape03+``, ``shape03-``), each with weights in [0, 1]. :class:`MorphSet` refuses weights
  outside [0, 1].
- **Positions are in metres**, as glTF says. :func:`write_glb` takes the model's unit
  (``metres_per_unit``; see :func:`faceanim.mpeg4.metres_per_unit` to tell it from a face's size),
  scales positions and targets into metres and records the unit in the mesh's
  ``extras["faceanim"]["metres_per_unit"]``. :func:`faceanim.geometry.read_mesh` divides it out again,
  so a faceanim ``.glb`` reads back in the model's own units (to float32 precision), with its part
  labels (``extras["faceanim"]["parts"]``: part names and run-length encoded per-triangle labels).
"""

from __future__ import annotations

import io
import math
from dataclasses import dataclass, field

import numpy as np

from ..atomic import atomic_output
from ..geometry.animation import Animation
from ..geometry.mesh import Mesh
from ..geometry.meshio import PARTS_EXTRA, SOURCE_VERTEX_ATTRIBUTE, UNIT_EXTRA
from ..validation import as_array

__all__ = ["MorphSet", "morphs_from_animation", "write_glb"]

_ARRAY_BUFFER, _ELEMENT_ARRAY_BUFFER = 34962, 34963
_FLOAT, _UNSIGNED_INT = 5126, 5125
_WEIGHT_SLACK = 1e-9  # weights this far outside [0, 1] are rounding, and are clipped
_BLOCK = 3 * 512  # displacement columns (3 per vertex) handled at once: memory stays bounded by T x _BLOCK


@dataclass(frozen=True, eq=False)
class MorphSet:
    """Morph targets of a mesh and, optionally, their weights over time.

    ``targets (K, V, 3)`` displacements (model units), ``names`` (K,), ``weights (T, K)`` within
    [0, 1] or None (a still mesh with sliders), ``fps`` for the weights, ``default_weights (K,)``
    within [0, 1], the weights a viewer shows without animation (zeros when not given: the rest
    shape). Weights outside [0, 1] are refused: glTF clients clamp them (Blender's importer to the
    slider range [0, 1]), so they would not play as written.
    """

    targets: np.ndarray
    names: tuple[str, ...]
    weights: np.ndarray | None = None
    fps: float = 25.0
    max_error: float = field(default=0.0)
    default_weights: np.ndarray | None = None

    def __post_init__(self):
        targets = as_array(self.targets, "targets", shape=("K", "V", 3))
        names = tuple(self.names)
        if len(names) != len(targets):
            raise ValueError(f"names must give one name per target ({len(targets)}), got {len(names)}")
        if self.weights is not None:
            weights = as_array(self.weights, "weights", shape=("T", len(targets)), min_length=1)
            object.__setattr__(self, "weights", _unit_interval(weights, "weights", names))
        if self.default_weights is not None:
            weights = as_array(self.default_weights, "default_weights", shape=(len(targets),))
            object.__setattr__(self, "default_weights", _unit_interval(weights, "default_weights", names))
        object.__setattr__(self, "targets", targets)
        object.__setattr__(self, "names", names)


def _unit_interval(weights: np.ndarray, name: str, names: tuple[str, ...]) -> np.ndarray:
    """``weights`` clipped to [0, 1] when they are outside it by rounding only; else a ValueError that
    names the first weight outside."""
    outside = (weights < -_WEIGHT_SLACK) | (weights > 1 + _WEIGHT_SLACK)
    if outside.any():
        at = np.argwhere(outside)[0]
        where = f"frame {at[0]}, target {names[at[-1]]!r}" if weights.ndim == 2 else f"target {names[at[0]]!r}"
        raise ValueError(f"{name} must lie within [0, 1] (glTF clients clamp morph weights), got "
                         f"{weights[tuple(at)]:g} at {where}; split a signed shape into two (see "
                         "morphs_from_animation)")
    return np.clip(weights, 0.0, 1.0)


def morphs_from_animation(animation: Animation, *, max_modes: int = 64, tolerance: float = 1e-4) -> MorphSet:
    """Few morph targets, with weights in [0, 1], that replay ``animation`` (its mesh's vertices are the rest).

    The displacements of all frames, a ``(T, 3V)`` matrix ``D``, are factorised once, through the
    eigenvectors of the smaller of its two Gram matrices (``D D^T`` or ``D^T D``): the first ``k``
    modes replay ``D`` as its orthogonal projection onto them (the truncated SVD). The number of
    modes ``k`` (at most ``max_modes``) is found by bisection on the worst per-vertex error over all
    frames, evaluated exactly for each candidate: ``k`` modes keep it within ``tolerance`` times the
    mesh's size (the largest side of its bounding box) and, unless ``k`` is 1, ``k - 1`` do not; or
    ``k = max_modes`` when even that many do not. (The error need not fall at every added mode, so
    a smaller count passing may exist below a failing one; bisection does not look there.) Each mode
    is written as up to two targets, its positive part and its negated negative part (``shape03+``,
    ``shape03-``), with weights ``max(w, 0)`` and ``max(-w, 0)``
    scaled to peak at 1; a mode whose weights never change sign gives one.

    Returns
    -------
    MorphSet
        ``targets`` in model units, ``weights (T, K)`` within [0, 1]; ``max_error`` is the worst
        distance (model units), over every frame and vertex, between the animation and what these
        targets replay (in float64; the file's float32 adds about 1e-7 of the mesh's size).

    Examples
    --------
    >>> from faceanim.geometry import Mesh
    >>> mesh = Mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]])
    >>> lift = np.sin(np.arange(20) / 3)[:, None, None] * [[0, 0, 0], [0, 0, 0], [0, 0, 0.5]]
    >>> morphs = morphs_from_animation(Animation(mesh, mesh.vertices + lift, 25.0))
    >>> morphs.names, float(morphs.weights.min()), float(morphs.weights.max())
    (('shape00+', 'shape00-'), 0.0, 1.0)
    """
    if int(max_modes) != max_modes or max_modes < 1:
        raise ValueError(f"max_modes must be a whole number of at least 1, got {max_modes}")
    if not np.isfinite(tolerance) or tolerance < 0:
        raise ValueError(f"tolerance must be a non-negative number, got {tolerance}")
    rest = animation.mesh.vertices.ravel()
    frames = animation.positions.reshape(len(animation), -1)
    size = np.ptp(animation.mesh.vertices, axis=0).max() or 1.0
    curves, shapes = _modes(frames, rest, int(max_modes))
    if not len(shapes):
        return MorphSet(np.zeros((0, len(rest) // 3, 3)), (), np.zeros((len(frames), 0)), animation.fps)
    errors = {}

    def error(k: int) -> float:
        if k not in errors:
            errors[k] = _worst_error(frames, rest, curves[:, :k], shapes[:k])
        return errors[k]

    limit = tolerance * size
    low, high = 0, len(shapes)  # error(high) is within the limit (or high is every mode there is)
    if error(high) <= limit:
        while high - low > 1:
            middle = (low + high) // 2
            low, high = (low, middle) if error(middle) <= limit else (middle, high)
    targets, weights, names = [], [], []
    for j in range(high):
        for sign, suffix in ((1.0, "+"), (-1.0, "-")):
            part = np.maximum(sign * curves[:, j], 0.0)
            peak = part.max()
            if peak > 0:
                targets.append(sign * peak * shapes[j])
                weights.append(part / peak)
                names.append(f"shape{j:02d}{suffix}")
    return MorphSet(np.reshape(targets, (len(targets), -1, 3)), tuple(names), np.transpose(weights), animation.fps,
                    error(high))


def _column_blocks(n: int):
    return (slice(start, min(start + _BLOCK, n)) for start in range(0, n, _BLOCK))


def _modes(frames: np.ndarray, rest: np.ndarray, count: int) -> tuple[np.ndarray, np.ndarray]:
    """Time curves ``(T, K)`` and shapes ``(K, 3V)`` of the first ``K <= count`` SVD modes of the
    displacements ``frames - rest``, strongest first; ``curves @ shapes`` is the displacements'
    projection onto the modes. Modes of numerically zero strength are left out. Curve values at
    rounding level (1e-9 of the curve's peak: frames at rest) are set to zero, so that their sign
    does not split a mode; the error is measured after that."""
    T, n = frames.shape
    if T <= n:  # the T x T Gram matrix, accumulated over column blocks
        gram = np.zeros((T, T))
        for block in _column_blocks(n):
            d = frames[:, block] - rest[block]
            gram += d @ d.T
    else:
        d = frames - rest
        gram = d.T @ d
    strength, vectors = np.linalg.eigh(gram)
    strength, vectors = strength[::-1], vectors[:, ::-1]
    kept = min(count, int(np.sum(strength > max(strength[0], 0.0) * max(T, n) * np.finfo(float).eps)))
    vectors = np.ascontiguousarray(vectors[:, :kept])
    if T <= n:
        curves = vectors
        shapes = np.empty((kept, n))
        for block in _column_blocks(n):
            shapes[:, block] = vectors.T @ (frames[:, block] - rest[block])
    else:
        curves, shapes = d @ vectors, np.ascontiguousarray(vectors.T)
    peak = np.abs(curves).max(axis=0, initial=0.0)
    curves = np.where(np.abs(curves) <= 1e-9 * peak, 0.0, curves)
    return curves, shapes


def _worst_error(frames: np.ndarray, rest: np.ndarray, curves: np.ndarray, shapes: np.ndarray) -> float:
    """The largest per-vertex distance, over all frames, between ``frames`` and ``rest + curves @ shapes``."""
    worst = 0.0
    for block in _column_blocks(frames.shape[1]):
        residual = frames[:, block] - rest[block]
        if len(shapes):
            residual -= curves @ shapes[:, block]
        residual *= residual
        squared = residual[:, 0::3] + residual[:, 1::3] + residual[:, 2::3]
        worst = max(worst, float(squared.max()))
    return math.sqrt(worst)


class _Buffer:
    """Collects binary data and the glTF views and accessors that point into it."""

    def __init__(self, gltf):
        self.gltf = gltf
        self.data = io.BytesIO()

    def add(self, array: np.ndarray, *, kind: str, component: int, target: int | None = None,
            with_bounds: bool = False) -> int:
        import pygltflib as g

        raw = np.ascontiguousarray(array, dtype=np.uint32 if component == _UNSIGNED_INT else np.float32)
        while self.data.tell() % 4:
            self.data.write(b"\0")
        offset = self.data.tell()
        self.data.write(raw.tobytes())
        self.gltf.bufferViews.append(g.BufferView(buffer=0, byteOffset=offset, byteLength=raw.nbytes, target=target))
        accessor = g.Accessor(bufferView=len(self.gltf.bufferViews) - 1, componentType=component,
                              count=len(raw) if kind != "SCALAR" or raw.ndim == 1 else raw.size, type=kind)
        if with_bounds:
            flat = raw.reshape(len(raw), -1)
            accessor.min, accessor.max = flat.min(axis=0).tolist(), flat.max(axis=0).tolist()
        self.gltf.accessors.append(accessor)
        return len(self.gltf.accessors) - 1

    def add_bytes(self, blob: bytes) -> int:
        import pygltflib as g

        while self.data.tell() % 4:
            self.data.write(b"\0")
        offset = self.data.tell()
        self.data.write(blob)
        self.gltf.bufferViews.append(g.BufferView(buffer=0, byteOffset=offset, byteLength=len(blob)))
        return len(self.gltf.bufferViews) - 1


def write_glb(path, mesh: Mesh, morphs: MorphSet | None = None, *, name: str = "face",
              extras: dict | None = None, metres_per_unit: float = 1.0) -> None:
    """Write ``mesh`` (with its texture, and ``morphs`` if given) as a ``.glb``, complete or not at all.

    Positions and morph targets are written in metres: ``metres_per_unit`` is the model's unit (0.01
    for a mesh in centimetres; :func:`faceanim.mpeg4.metres_per_unit` tells it from a face's FAPU).
    The default, 1.0, takes the model to be in metres already.

    UV seams are split (glTF has one UV per vertex); every split copy carries its original vertex's
    morph displacement, so seams never open, and its original index in the attribute
    ``_SOURCE_VERTEX``, so :func:`~faceanim.geometry.read_mesh` restores the mesh exactly. ``extras``
    (JSON-able) is stored in the glTF mesh's ``extras`` under ``"faceanim"``, beside the unit
    (``"metres_per_unit"``) and the mesh's part labels (``"parts"``), which ``read_mesh`` uses.
    """
    try:
        import pygltflib as g
    except ImportError:
        raise ImportError("glTF export needs pygltflib: pip install pygltflib") from None
    if not isinstance(metres_per_unit, (int, float)) or not math.isfinite(metres_per_unit) or metres_per_unit <= 0:
        raise ValueError(f"metres_per_unit must be a positive number, got {metres_per_unit!r}")
    reserved = {UNIT_EXTRA, PARTS_EXTRA} & set(extras or {})
    if reserved:
        raise ValueError(f"extras must not hold {', '.join(sorted(reserved))}: write_glb writes them itself")
    if morphs is not None and morphs.targets.shape[1] != len(mesh.vertices):
        raise ValueError(f"morph targets have {morphs.targets.shape[1]} vertices, the mesh {len(mesh.vertices)}")
    carried = {**(extras or {}), UNIT_EXTRA: float(metres_per_unit)}
    if mesh.parts is not None:
        carried[PARTS_EXTRA] = _part_runs(mesh)
    split = mesh.split_at_seams()
    gltf = g.GLTF2(asset=g.Asset(generator="faceanim", version="2.0"))
    gltf.scene = 0
    buffer = _Buffer(gltf)
    normals = mesh.vertex_normals[split.source_vertex]
    normals[np.linalg.norm(normals, axis=1) == 0] = [0, 0, 1]
    attributes = g.Attributes(
        POSITION=buffer.add(split.vertices * metres_per_unit, kind="VEC3", component=_FLOAT, target=_ARRAY_BUFFER,
                            with_bounds=True),
        NORMAL=buffer.add(normals, kind="VEC3", component=_FLOAT, target=_ARRAY_BUFFER))
    setattr(attributes, SOURCE_VERTEX_ATTRIBUTE, buffer.add(split.source_vertex.astype(np.float32), kind="SCALAR",
                                                      component=_FLOAT, target=_ARRAY_BUFFER))
    if split.uv is not None:
        uv = split.uv * [1, -1] + [0, 1]  # glTF's UV origin is the image's top left
        attributes.TEXCOORD_0 = buffer.add(uv, kind="VEC2", component=_FLOAT, target=_ARRAY_BUFFER)
    indices = buffer.add(split.triangles.ravel(), kind="SCALAR", component=_UNSIGNED_INT,
                         target=_ELEMENT_ARRAY_BUFFER)
    primitive = g.Primitive(attributes=attributes, indices=indices, material=0)
    material = g.Material(name="skin", doubleSided=True,
                          pbrMetallicRoughness=g.PbrMetallicRoughness(metallicFactor=0.0, roughnessFactor=0.8))
    if mesh.texture is not None and split.uv is not None:
        from PIL import Image

        png = io.BytesIO()
        Image.fromarray(mesh.texture).save(png, format="PNG")
        gltf.images.append(g.Image(bufferView=buffer.add_bytes(png.getvalue()), mimeType="image/png"))
        gltf.samplers.append(g.Sampler(magFilter=9729, minFilter=9987, wrapS=33071, wrapT=33071))
        gltf.textures.append(g.Texture(source=0, sampler=0))
        material.pbrMetallicRoughness.baseColorTexture = g.TextureInfo(index=0)
    gltf.materials.append(material)
    gltf_mesh = g.Mesh(name=name, primitives=[primitive], extras={"faceanim": carried})
    if morphs is not None and len(morphs.names):
        for target in morphs.targets:
            accessor = buffer.add(target[split.source_vertex] * metres_per_unit, kind="VEC3", component=_FLOAT,
                                  target=_ARRAY_BUFFER, with_bounds=True)
            primitive.targets.append({"POSITION": accessor})
        rest = morphs.default_weights
        gltf_mesh.weights = [0.0] * len(morphs.names) if rest is None else [float(w) for w in rest]
        gltf_mesh.extras["targetNames"] = list(morphs.names)
    gltf.meshes.append(gltf_mesh)
    gltf.nodes.append(g.Node(mesh=0, name=name))
    gltf.scenes.append(g.Scene(nodes=[0]))
    if morphs is not None and morphs.weights is not None and len(morphs.names):
        times = np.arange(len(morphs.weights), dtype=np.float64) / morphs.fps
        sampler = g.AnimationSampler(
            input=buffer.add(times, kind="SCALAR", component=_FLOAT, with_bounds=True),
            output=buffer.add(morphs.weights.ravel(), kind="SCALAR", component=_FLOAT), interpolation="LINEAR")
        gltf.animations.append(g.Animation(name="performance", samplers=[sampler], channels=[
            g.AnimationChannel(sampler=0, target=g.AnimationChannelTarget(node=0, path="weights"))]))
    blob = buffer.data.getvalue()
    gltf.buffers.append(g.Buffer(byteLength=len(blob)))
    gltf.set_binary_blob(blob)
    with atomic_output(path, suffix=".glb") as tmp:
        gltf.save_binary(str(tmp))


def _part_runs(mesh: Mesh) -> dict:
    """The per-triangle part labels, run-length encoded in triangle order: ``{"part_names": [...],
    "part_runs": [[label, count], ...]}``."""
    labels = mesh.parts
    starts = np.flatnonzero(np.r_[True, labels[1:] != labels[:-1]])
    counts = np.diff(np.r_[starts, len(labels)])
    return {"part_names": list(mesh.part_names),
            "part_runs": [[int(labels[a]), int(c)] for a, c in zip(starts, counts, strict=True)]}
