"""glTF 2.0 binary (``.glb``) with morph targets and a weights animation, through pygltflib.

An animation travels as morph targets (shapes added to the rest mesh) and per-frame weights, which
Blender imports as shape keys with an action and three.js as morph targets with an animation clip.
:func:`~faceanim.export.morphs.morphs_from_animation` finds few shapes that reproduce every frame
(principal shapes of the displacements, exact to a stated tolerance); named shapes (action units,
visemes) can be written directly for a viewer to drive as sliders.

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

import numpy as np

from ..atomic import atomic_output
from ..geometry.mesh import Mesh
from ..geometry.meshio import PARTS_EXTRA, SOURCE_VERTEX_ATTRIBUTE, UNIT_EXTRA
from .morphs import MorphSet

__all__ = ["write_glb"]

_ARRAY_BUFFER, _ELEMENT_ARRAY_BUFFER = 34962, 34963
_FLOAT, _UNSIGNED_INT = 5126, 5125
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
