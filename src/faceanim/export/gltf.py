"""glTF 2.0 binary (``.glb``) with morph targets and a weights animation, through pygltflib.

An animation travels as morph targets (shapes added to the rest mesh) and per-frame weights, which
Blender imports as shape keys with an action and three.js as morph targets with an animation clip.
:func:`morphs_from_animation` finds few shapes that reproduce every frame (a truncated SVD of the
displacements, exact to a stated tolerance); named shapes (action units, visemes) can be written
directly for a viewer to drive as sliders.
"""

from __future__ import annotations

import io
from dataclasses import dataclass, field

import numpy as np

from ..atomic import atomic_output
from ..geometry.animation import Animation
from ..geometry.mesh import Mesh
from ..geometry.meshio import SOURCE_VERTEX_ATTRIBUTE
from ..validation import as_array

__all__ = ["MorphSet", "morphs_from_animation", "write_glb"]

_ARRAY_BUFFER, _ELEMENT_ARRAY_BUFFER = 34962, 34963
_FLOAT, _UNSIGNED_INT = 5126, 5125


@dataclass(frozen=True, eq=False)
class MorphSet:
    """Morph targets of a mesh and, optionally, their weights over time.

    ``targets (K, V, 3)`` displacements, ``names`` (K,), ``weights (T, K)`` or None (a still mesh with
    sliders), ``fps`` for the weights, ``default_weights (K,)`` the weights a viewer shows without
    animation (zeros when not given: the rest shape).
    """

    targets: np.ndarray
    names: tuple[str, ...]
    weights: np.ndarray | None = None
    fps: float = 25.0
    max_error: float = field(default=0.0)
    default_weights: np.ndarray | None = None

    def __post_init__(self):
        targets = as_array(self.targets, "targets", shape=("K", "V", 3))
        if len(self.names) != len(targets):
            raise ValueError(f"names must give one name per target ({len(targets)}), got {len(self.names)}")
        if self.weights is not None:
            weights = as_array(self.weights, "weights", shape=("T", len(targets)), min_length=1)
            object.__setattr__(self, "weights", weights)
        if self.default_weights is not None:
            object.__setattr__(self, "default_weights",
                               as_array(self.default_weights, "default_weights", shape=(len(targets),)))
        object.__setattr__(self, "targets", targets)
        object.__setattr__(self, "names", tuple(self.names))


def morphs_from_animation(animation: Animation, *, max_targets: int = 64, tolerance: float = 1e-4) -> MorphSet:
    """Few morph targets and weights that replay ``animation`` (its mesh's vertices are the rest).

    The displacements of all frames are factorised by SVD; the fewest components whose worst
    per-vertex error over all frames is below ``tolerance`` times the mesh's size are kept, at most
    ``max_targets``. ``MorphSet.max_error`` says what error (model units) the chosen count leaves.
    """
    rest = animation.mesh.vertices
    d = (animation.positions - rest).reshape(len(animation), -1)
    size = np.ptp(rest, axis=0).max() or 1.0
    if not d.any():
        return MorphSet(np.zeros((0, len(rest), 3)), (), np.zeros((len(animation), 0)), animation.fps)
    U, S, Vt = np.linalg.svd(d, full_matrices=False)
    error = 0.0
    for k in range(1, min(max_targets, len(S)) + 1):
        approx = (U[:, :k] * S[:k]) @ Vt[:k]
        error = float(np.linalg.norm((approx - d).reshape(len(d), -1, 3), axis=2).max())
        if error <= tolerance * size:
            break
    # Scale each shape so its weights stay within [-1, 1]: viewers expect weights of that size.
    weights = U[:, :k] * S[:k]
    scale = np.abs(weights).max(axis=0)
    scale[scale == 0] = 1.0
    targets = (Vt[:k] * scale[:, None]).reshape(k, len(rest), 3)
    return MorphSet(targets, tuple(f"shape{i:02d}" for i in range(k)), weights / scale, animation.fps, error)


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
              extras: dict | None = None) -> None:
    """Write ``mesh`` (with its texture, and ``morphs`` if given) as a ``.glb``, complete or not at all.

    UV seams are split (glTF has one UV per vertex); every split copy carries its original vertex's
    morph displacement, so seams never open, and its original index in the attribute
    ``_SOURCE_VERTEX``, so :func:`~faceanim.geometry.read_mesh` restores the mesh exactly. ``extras``
    (JSON-able) is stored in the glTF mesh's ``extras`` under ``"faceanim"``.
    """
    try:
        import pygltflib as g
    except ImportError:
        raise ImportError("glTF export needs pygltflib: pip install pygltflib") from None
    split = mesh.split_at_seams()
    gltf = g.GLTF2(asset=g.Asset(generator="faceanim", version="2.0"))
    gltf.scene = 0
    buffer = _Buffer(gltf)
    normals = mesh.vertex_normals[split.source_vertex]
    normals[np.linalg.norm(normals, axis=1) == 0] = [0, 0, 1]
    attributes = g.Attributes(
        POSITION=buffer.add(split.vertices, kind="VEC3", component=_FLOAT, target=_ARRAY_BUFFER, with_bounds=True),
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
    gltf_mesh = g.Mesh(name=name, primitives=[primitive], extras={"faceanim": extras} if extras else {})
    if morphs is not None and len(morphs.names):
        if morphs.targets.shape[1] != len(mesh.vertices):
            raise ValueError(f"morph targets have {morphs.targets.shape[1]} vertices, the mesh {len(mesh.vertices)}")
        for target in morphs.targets:
            accessor = buffer.add(target[split.source_vertex], kind="VEC3", component=_FLOAT, target=_ARRAY_BUFFER,
                                  with_bounds=True)
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
