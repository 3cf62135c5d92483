"""Cross-identity expression transfer on ICT-FaceKit with exact ground truth.

Identities A (source) and B (target) get identity weights from N(0, 1.5^2). The linear model makes
expression ``j`` on B exactly ``B + expression_deltas[j]``. The target is B's face region, re-made
so that nothing can be copied by index: its quads are split along the other diagonal, every
triangle is split in four at its edge midpoints, and the vertices are shuffled. A sparse matrix
``S (Vt, 26719)`` says what each target vertex is (a vertex of B or the midpoint of two), so the truth
for any expression is ``S @ (B + delta)``.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy import sparse

from faceanim.geometry.mesh import Mesh
from faceanim.mpeg4.multipie import MULTIPIE68_OF_FEATURE_POINT, THESIS_16

ICT = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "ict_facekit"
FACE_VERTICES = 9409  # ICT's "full face area" is vertices 0-9408


def ict_available() -> bool:
    return (ICT / "ict_deltas_full.npz").exists()


def ict_missing() -> bool:
    """True, after saying so, when the ICT data is absent and a benchmark must skip."""
    if ict_available():
        return False
    print("skipped: needs ../shared/data/ict_facekit (the shared data folder beside the checkout)")
    return True


@dataclass(frozen=True, eq=False)
class IctModel:
    neutral: np.ndarray            # (26719, 3)
    expression_names: tuple
    expression_deltas: np.ndarray  # (53, 26719, 3)
    identity_deltas: np.ndarray    # (100, 26719, 3)
    polygons: list                 # OBJ faces (vertex id lists), in file order
    landmarks: np.ndarray          # (68,) Multi-PIE vertex ids

    def identity(self, weights) -> np.ndarray:
        return self.neutral + np.tensordot(weights, self.identity_deltas, axes=1)

    def random_identities(self, rng, count: int = 2, spread: float = 1.5) -> list[np.ndarray]:
        """``count`` faces with identity weights drawn from N(0, spread^2), in order from ``rng``."""
        return [self.identity(rng.normal(scale=spread, size=len(self.identity_deltas))) for _ in range(count)]

    def mesh(self, vertices) -> Mesh:
        tris = [(p[0], p[k], p[k + 1]) for p in self.polygons for k in range(1, len(p) - 1)]
        return Mesh(vertices, np.asarray(tris))


def load_ict() -> IctModel:
    data = np.load(ICT / "ict_deltas_full.npz")
    polygons = []
    with open(ICT / "obj" / "generic_neutral_mesh.obj") as handle:
        for line in handle:
            if line.startswith("f "):
                polygons.append([int(t.split("/")[0]) - 1 for t in line.split()[1:]])
    landmarks = np.asarray(json.loads((ICT / "landmarks_multipie68.json").read_text())["multi_pie_68"])
    return IctModel(data["neutral"].astype(np.float64), tuple(str(n) for n in data["expression_names"]),
                    data["expression_deltas"].astype(np.float64), data["identity_deltas"].astype(np.float64),
                    polygons, landmarks)


@dataclass(frozen=True, eq=False)
class Target:
    mesh: Mesh                 # B's re-made face region, at rest
    from_ict: sparse.csr_matrix  # (Vt, 26719): target vertex = row @ ICT vertices
    index_of: np.ndarray       # (26719,) target index of each ICT vertex, -1 where none


def remade_face(model: IctModel, vertices: np.ndarray, rng) -> Target:
    """B's face region with another triangulation, midpoint subdivision and shuffled vertices."""
    tris = []
    for p in model.polygons:
        if max(p) >= FACE_VERTICES:
            continue
        if len(p) == 4:  # the other diagonal than a fan from corner 0
            tris += [(p[1], p[2], p[3]), (p[1], p[3], p[0])]
        else:
            tris += [(p[0], p[k], p[k + 1]) for k in range(1, len(p) - 1)]
    tris = np.asarray(tris)
    edges = np.sort(tris[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    unique_edges, edge_of = np.unique(edges, axis=0, return_inverse=True)
    edge_of = edge_of.reshape(-1, 3)
    V = FACE_VERTICES
    m01, m12, m20 = (V + edge_of[:, i] for i in range(3))
    a, b, c = tris.T
    fine = np.concatenate([np.stack(t, 1) for t in ((a, m01, m20), (m01, b, m12), (m20, m12, c), (m01, m12, m20))])
    rows = np.r_[np.arange(V), np.repeat(V + np.arange(len(unique_edges)), 2)]
    cols = np.r_[np.arange(V), unique_edges.ravel()]
    vals = np.r_[np.ones(V), np.full(2 * len(unique_edges), 0.5)]
    count = V + len(unique_edges)
    S = sparse.csr_matrix((vals, (rows, cols)), shape=(count, len(vertices)))
    order = rng.permutation(count)          # new position i holds old vertex order[i]
    new_index = np.empty(count, dtype=np.int64)
    new_index[order] = np.arange(count)
    S = S[order]
    index_of = np.full(len(vertices), -1)
    index_of[:V] = new_index[:V]
    return Target(Mesh(S @ vertices, new_index[fine]), S, index_of)


def control_sets(model: IctModel, source_vertices: np.ndarray) -> dict[str, np.ndarray]:
    """ICT vertex ids of the three control sets: thesis 16, Multi-PIE 68, ~500 dense."""
    lm = model.landmarks
    thesis = lm[[MULTIPIE68_OF_FEATURE_POINT[name] for name in THESIS_16]]
    return {"16 FDP": thesis, "68 landmarks": lm, "~500 dense": _farthest_points(source_vertices, lm, 500)}


def _farthest_points(vertices, seeds, count):
    """Farthest-point sampling over ICT's narrow face area (vertices 0-6705), seeded with ``seeds``."""
    pool = np.arange(6706)
    chosen = list(seeds)
    d = np.min(np.linalg.norm(vertices[pool, None] - vertices[np.asarray(chosen)][None], axis=2), axis=1)
    while len(chosen) < count:
        nxt = int(np.argmax(d))
        chosen.append(pool[nxt])
        d = np.minimum(d, np.linalg.norm(vertices[pool] - vertices[pool[nxt]], axis=1))
    return np.asarray(chosen)


def relative_error(out: np.ndarray, truth: np.ndarray, rest: np.ndarray, where=None) -> np.ndarray:
    """rms(|out - truth|) / rms(|truth - rest|), per frame; ``where`` restricts to some vertices."""
    if where is not None:
        out, truth, rest = out[..., where, :], truth[..., where, :], rest[where]
    num = np.sqrt(((out - truth) ** 2).sum(-1).mean(-1))
    den = np.sqrt(((truth - rest) ** 2).sum(-1).mean(-1))
    return num / np.maximum(den, 1e-12)
