"""A named rig's file: the morph targets of a ``.glb`` read by name, and their animation written.

:func:`read_rig` reads the main mesh's targets (the mesh with the most names that
:func:`~faceanim.rig.drive.canonical_name` recognises), placed in the scene as the file places them.
:func:`write_rig_animation` writes the animation into a copy of the rig file itself: the meshes, their
morph targets, materials and everything else stay byte for byte as they were; one animation is added
with one key per frame on the weights of every node whose mesh carries a recognised name (a target no
name maps to keeps weight 0), and earlier animations of those weights are dropped.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import FileFormatError, InputError
from ..validation import as_array
from .drive import EXPECTED_NAMES, canonical_name

__all__ = ["NamedRig", "read_rig", "write_rig_animation"]


@dataclass(frozen=True, eq=False)
class NamedRig:
    """The morph targets of a ``.glb``'s main mesh (the one with the most recognised names).

    ``names (S,)``: the targets' names as in the file; ``canonical (S,)``: what each stands for
    (:func:`canonical_name`; None where nothing); ``vertices (N, 3)``: the mesh's vertices, placed in
    the scene, in the units :func:`~faceanim.geometry.read_mesh` reads the file in; ``shapes (S, N,
    3)``: each target's displacement, same units and axes (read-only); ``path``: the file.
    """

    path: Path
    names: tuple[str, ...]
    canonical: tuple[str | None, ...]
    vertices: np.ndarray
    shapes: np.ndarray

    def __post_init__(self):
        vertices = as_array(self.vertices, "vertices", shape=("N", 3), frozen=True)
        shapes = as_array(self.shapes, "shapes", shape=(len(self.names), len(vertices), 3), frozen=True)
        if len(self.canonical) != len(self.names):
            raise ValueError(f"canonical must give one entry per name ({len(self.names)}), got {len(self.canonical)}")
        object.__setattr__(self, "vertices", vertices)
        object.__setattr__(self, "shapes", shapes)

    @property
    def driven(self) -> np.ndarray:
        """Indices of the targets with a recognised name."""
        return np.asarray([j for j, c in enumerate(self.canonical) if c is not None], dtype=np.int64)

    def at(self, points, *, tolerance: float = 1e-4) -> tuple[np.ndarray, np.ndarray]:
        """The rig's vertices nearest to ``points (K, 3)`` (same units): ``(found (K,) bool, ids (K,))``;
        a point farther than ``tolerance`` times the mesh's size from any vertex is not on this mesh."""
        from scipy.spatial import cKDTree

        points = as_array(points, "points", shape=("K", 3))
        distance, ids = cKDTree(self.vertices).query(points)
        size = float(np.ptp(self.vertices, axis=0).max()) or 1.0
        return distance <= tolerance * size, ids


def _load(path: Path):
    import pygltflib as g

    from ..geometry.meshio import read_glb_json

    path = Path(path)
    if path.suffix.lower() != ".glb":
        raise InputError(f"{path}: a rig is a binary glTF (.glb) file with named morph targets")
    if not path.is_file():
        raise InputError(f"{path}: no such file")
    read_glb_json(path)  # a broken header or JSON chunk: one line naming the file
    try:
        gltf = g.GLTF2.load_binary(str(path))
    except Exception as exc:  # pygltflib raises many kinds on broken files
        raise FileFormatError(path, f"cannot be read as glTF ({type(exc).__name__}: {exc})") from None
    if gltf.buffers and gltf.buffers[0].uri is not None:
        raise FileFormatError(path, "keeps its data outside the file (a buffer uri); give a self-contained .glb")
    return gltf


def _accessor(gltf, blob: bytes, index: int, path) -> np.ndarray:
    """A float accessor as ``(count, components)`` float64 (with its sparse part applied)."""
    sizes = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}
    types = {5126: np.float32, 5125: np.uint32, 5123: np.uint16, 5121: np.uint8}
    try:
        accessor = gltf.accessors[index]
        width = sizes[accessor.type]
        out = np.zeros((accessor.count, width))
        if accessor.bufferView is not None:
            if accessor.componentType != 5126:
                raise FileFormatError(path, f"accessor {index} is not float (quantised positions are not read)")
            view = gltf.bufferViews[accessor.bufferView]
            start = (view.byteOffset or 0) + (accessor.byteOffset or 0)
            stride = view.byteStride or 4 * width
            raw = np.frombuffer(blob, dtype=np.uint8, count=stride * (accessor.count - 1) + 4 * width, offset=start)
            rows = np.lib.stride_tricks.as_strided(raw, shape=(accessor.count, 4 * width), strides=(stride, 1))
            out = np.ascontiguousarray(rows).view(np.float32).reshape(accessor.count, width).astype(np.float64)
        if accessor.sparse is not None:
            sparse = accessor.sparse
            iview = gltf.bufferViews[sparse.indices.bufferView]
            ids = np.frombuffer(blob, dtype=types[sparse.indices.componentType], count=sparse.count,
                                offset=(iview.byteOffset or 0) + (sparse.indices.byteOffset or 0))
            vview = gltf.bufferViews[sparse.values.bufferView]
            values = np.frombuffer(blob, dtype=np.float32, count=sparse.count * width,
                                   offset=(vview.byteOffset or 0) + (sparse.values.byteOffset or 0))
            out[ids.astype(np.int64)] = values.reshape(-1, width)
    except FileFormatError:
        raise
    except (IndexError, KeyError, ValueError, TypeError, AttributeError) as exc:
        raise FileFormatError(path, f"accessor {index} cannot be read ({exc})") from None
    return out


def _target_names(mesh) -> list[str]:
    extras = mesh.extras if isinstance(mesh.extras, dict) else {}
    names = extras.get("targetNames")
    count = max((len(p.targets or []) for p in mesh.primitives), default=0)
    if not isinstance(names, list) or len(names) != count:
        return [f"target{k}" for k in range(count)]
    return [str(n) for n in names]


def _node_matrices(gltf) -> dict[int, np.ndarray]:
    """Each node's placement in the scene, ``(4, 4)``."""
    def local(node) -> np.ndarray:
        if node.matrix:
            return np.asarray(node.matrix, dtype=np.float64).reshape(4, 4).T
        m = np.eye(4)
        if node.rotation:
            x, y, z, w = node.rotation
            m[:3, :3] = [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                         [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                         [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]
        if node.scale:
            m[:3, :3] = m[:3, :3] * np.asarray(node.scale)
        if node.translation:
            m[:3, 3] = node.translation
        return m

    placed: dict[int, np.ndarray] = {}

    def walk(index: int, parent: np.ndarray, depth: int = 0) -> None:
        if index in placed or depth > 64:
            return
        placed[index] = parent @ local(gltf.nodes[index])
        for child in gltf.nodes[index].children or []:
            walk(child, placed[index], depth + 1)

    children = {c for n in gltf.nodes for c in (n.children or [])}
    for index in range(len(gltf.nodes)):
        if index not in children:
            walk(index, np.eye(4))
    return placed


def _rig_meshes(gltf) -> dict[int, list[str | None]]:
    """Mesh index -> the canonical names of its targets, for meshes with at least one recognised name."""
    found = {}
    for m, mesh in enumerate(gltf.meshes):
        canonical = [canonical_name(n) for n in _target_names(mesh)]
        if any(c is not None for c in canonical):
            found[m] = canonical
    return found


def read_rig(path) -> NamedRig:
    """The named morph targets of the ``.glb`` at ``path`` (see :class:`NamedRig`).

    Raises
    ------
    InputError
        Not a ``.glb``, missing, or no morph target with an ARKit or FACS AU name (the message says
        which names are expected).
    FileFormatError
        A broken file, or target data that cannot be read.
    """
    from ..geometry.meshio import UNIT_EXTRA, glb_extras

    path = Path(path)
    gltf = _load(path)
    meshes = _rig_meshes(gltf)
    if not meshes:
        names = [n for mesh in gltf.meshes for n in _target_names(mesh)]
        held = (f"its {len(names)} morph targets ({', '.join(names[:4])}{', ...' if len(names) > 4 else ''})"
                if names else "no morph targets")
        raise InputError(f"{path}: holds {held} and none has a rig name; expected {EXPECTED_NAMES}")
    main = max(meshes, key=lambda m: (sum(c is not None for c in meshes[m]), -m))
    mesh = gltf.meshes[main]
    blob = gltf.binary_blob() or b""
    vertices, shapes = [], []
    for primitive in mesh.primitives:
        if primitive.attributes.POSITION is None:
            continue
        vertices.append(_accessor(gltf, blob, primitive.attributes.POSITION, path))
        targets = primitive.targets or []
        if len(targets) != len(meshes[main]):
            raise FileFormatError(path, f"mesh {main}'s primitives carry {len(targets)} morph targets, its names "
                                        f"{len(meshes[main])}")
        shapes.append([_accessor(gltf, blob, t["POSITION"], path) if t.get("POSITION") is not None
                       else np.zeros_like(vertices[-1]) for t in targets])
    if not vertices:
        raise FileFormatError(path, f"mesh {main} has no positions")
    vertices = np.concatenate(vertices)
    shapes = np.concatenate([np.stack(s) for s in shapes], axis=1)
    placement = next((m for n, m in _node_matrices(gltf).items() if gltf.nodes[n].mesh == main), np.eye(4))
    vertices = vertices @ placement[:3, :3].T + placement[:3, 3]
    shapes = shapes @ placement[:3, :3].T
    unit = glb_extras(path).get(UNIT_EXTRA) if main == 0 else None
    if isinstance(unit, (int, float)) and not isinstance(unit, bool) and unit > 0:
        vertices, shapes = vertices / unit, shapes / unit  # a faceanim .glb reads back in its model's units
    return NamedRig(path, tuple(_target_names(mesh)), tuple(meshes[main]), vertices, shapes)


def write_rig_animation(rig_path, output, canonical_weights: dict, fps: float) -> int:
    """Copy the ``.glb`` at ``rig_path`` to ``output`` with one animation added: for every node whose
    mesh has recognised names, one weight curve per morph target (a key per frame, linear), the weight
    of its canonical name in ``canonical_weights`` (``{canonical name: (T,)}`` in [0, 1]), 0 for a
    target nothing drives. Returns the number of targets driven (over all meshes)."""
    import pygltflib as g

    from ..atomic import atomic_output

    path = Path(rig_path)
    gltf = _load(path)
    meshes = _rig_meshes(gltf)
    if not meshes:
        raise InputError(f"{path}: no morph target has a rig name; expected {EXPECTED_NAMES}")
    lengths = {len(np.asarray(v)) for v in canonical_weights.values()}
    if len(lengths) > 1:
        raise ValueError(f"every weight curve must have one length, got {sorted(lengths)}")
    frames = lengths.pop() if lengths else 1
    blob = bytearray(gltf.binary_blob() or b"")

    def append(array: np.ndarray, with_bounds: bool = False) -> int:
        raw = np.ascontiguousarray(array, dtype=np.float32)
        blob.extend(b"\0" * (-len(blob) % 4))
        gltf.bufferViews.append(g.BufferView(buffer=0, byteOffset=len(blob), byteLength=raw.nbytes))
        blob.extend(raw.tobytes())
        accessor = g.Accessor(bufferView=len(gltf.bufferViews) - 1, componentType=5126, count=raw.size,
                              type="SCALAR")
        if with_bounds:
            accessor.min, accessor.max = [float(raw.min())], [float(raw.max())]
        gltf.accessors.append(accessor)
        return len(gltf.accessors) - 1

    times = append(np.arange(frames, dtype=np.float64) / float(fps), with_bounds=True)
    animation = g.Animation(name="performance", samplers=[], channels=[])
    nodes = [n for n, node in enumerate(gltf.nodes) if node.mesh in meshes]
    driven = 0
    for mesh_index, canonical in meshes.items():
        weights = np.zeros((frames, len(canonical)))
        for j, name in enumerate(canonical):
            if name in canonical_weights:
                weights[:, j] = np.clip(canonical_weights[name], 0.0, 1.0)
                driven += 1
        output_accessor = append(weights.ravel())
        animation.samplers.append(g.AnimationSampler(input=times, output=output_accessor, interpolation="LINEAR"))
        for n in nodes:
            if gltf.nodes[n].mesh == mesh_index:
                animation.channels.append(g.AnimationChannel(
                    sampler=len(animation.samplers) - 1, target=g.AnimationChannelTarget(node=n, path="weights")))
    kept = []
    for old in gltf.animations:  # earlier curves of these weights would fight the new ones
        old.channels = [c for c in old.channels if not (c.target.path == "weights" and c.target.node in nodes)]
        if old.channels:
            kept.append(old)
    gltf.animations = [*kept, animation]
    if not gltf.buffers:
        gltf.buffers.append(g.Buffer(byteLength=0))
    blob.extend(b"\0" * (-len(blob) % 4))
    gltf.buffers[0].byteLength = len(blob)
    gltf.set_binary_blob(bytes(blob))
    with atomic_output(Path(output), suffix=".glb") as tmp:
        gltf.save_binary(str(tmp))
    return driven
