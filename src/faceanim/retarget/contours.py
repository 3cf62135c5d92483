"""Face contours matched as curves: the lips, eyelids, brows, nose and jaw line between control points.

A dense registration anchored only at its control points slides along the surface between them,
and where the motion changes fast across a short distance (the two lips touching, the eyelids) a
target vertex then takes its motion from the other side of the contour. The control points of a
known layout say where the face's contours run: the iBUG / Multi-PIE 68 points trace the inner and
outer lip lines, each eyelid, the brows and the nose; the thesis' 16 MPEG-4 points trace
the outer lips and the upper eyelids. On each mesh a contour is the shortest path along its edges
through its control points, in order; the two paths are matched by arc length between consecutive
control points, which gives every source vertex on a contour a point on the target's contour.
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import csgraph

from ..geometry.mesh import Mesh
from ..geometry.surface import edge_graph
from ..mpeg4.multipie import THESIS_16

__all__ = ["LAYOUTS", "LAYOUT_SIZES", "LANDMARK_WEIGHTS", "contour_paths", "matched_contours"]

# The jaw line (points 0-16) is left out: it is a silhouette, not a line on the skin, and the paths
# through it differ between faces by up to 0.7 cm on ICT-FaceKit's identities.
_IBUG68 = (
    tuple(range(17, 22)), tuple(range(22, 27)),  # brows
    tuple(range(27, 31)), tuple(range(31, 36)),  # nose bridge, nose base
    (36, 37, 38, 39), (39, 40, 41, 36),      # right eye: upper, lower lid
    (42, 43, 44, 45), (45, 46, 47, 42),      # left eye: upper, lower lid
    tuple(range(48, 55)), (54, 55, 56, 57, 58, 59, 48),  # outer lips: upper, lower
    (60, 61, 62, 63, 64), (64, 65, 66, 67, 60),          # inner lips: upper, lower
)


def _thesis16() -> tuple:
    at = {name: i for i, name in enumerate(THESIS_16)}
    return (
        (at["8.4"], at["8.1"], at["8.3"]), (at["8.3"], at["8.2"], at["8.4"]),  # outer lips: upper, lower
        (at["3.12"], at["3.2"], at["3.8"]), (at["3.11"], at["3.1"], at["3.7"]),  # upper eyelids
    )


#: Contours of each known control-point layout, as positions in the control-point list.
LAYOUTS: dict[str, tuple] = {"ibug68": _IBUG68, "thesis16": _thesis16()}
#: Weight of each control point of a layout as a landmark of the registration (1 where not listed): the
#: iBUG jaw-line points (0-16, the chin 8 apart) follow the silhouette, not fixed places on the skin.
LANDMARK_WEIGHTS: dict[str, dict[int, float]] = {"ibug68": {k: 0.1 for k in range(17) if k != 8}}
#: How many control points each layout has.
LAYOUT_SIZES: dict[str, int] = {"ibug68": 68, "thesis16": len(THESIS_16)}


def contour_paths(mesh: Mesh, control_vertices, layout: str) -> list[list[np.ndarray]]:
    """Per contour of ``layout``, per stretch between consecutive control points, the vertex ids of the
    shortest edge path (both ends included)."""
    if layout not in LAYOUTS:
        raise ValueError(f"layout must be one of {', '.join(LAYOUTS)}, got {layout!r}")
    ids = np.asarray(control_vertices, dtype=np.int64)
    graph = edge_graph(mesh)
    needed = sorted({k for curve in LAYOUTS[layout] for k in curve[:-1]})
    _, predecessors = csgraph.dijkstra(graph, directed=False, indices=ids[needed], return_predecessors=True)
    row = {k: i for i, k in enumerate(needed)}
    paths = []
    for curve in LAYOUTS[layout]:
        stretches = []
        for a, b in zip(curve[:-1], curve[1:], strict=True):
            pred = predecessors[row[a]]
            path = [ids[b]]
            while path[-1] != ids[a]:
                nxt = pred[path[-1]]
                if nxt < 0:
                    raise ValueError(f"control points {a} and {b} of the {layout} layout lie on parts of the "
                                     "mesh that do not connect")
                path.append(nxt)
            stretches.append(np.asarray(path[::-1], dtype=np.int64))
        paths.append(stretches)
    return paths


def _arc_parameter(points: np.ndarray) -> np.ndarray:
    steps = np.linalg.norm(np.diff(points, axis=0), axis=1)
    s = np.r_[0.0, np.cumsum(steps)]
    return s / s[-1] if s[-1] > 0 else np.linspace(0.0, 1.0, len(points))


def matched_contours(source: Mesh, target: Mesh, source_ids, target_ids, layout: str,
                     *, target_vertices=None) -> tuple[np.ndarray, np.ndarray]:
    """Source vertices on the layout's contours and where each lands on the target's contour.

    Parameters
    ----------
    source, target : Mesh
    source_ids, target_ids : (K,) int64
        The control points, in the layout's order.
    layout : {"ibug68", "thesis16"}
    target_vertices : (Vt, 3) float64, optional
        Target positions to read the landing points from (default: the target's own).

    Returns
    -------
    vertices : (N,) int64
        Source vertex ids strictly between control points (each once).
    points : (N, 3) float64
        The target contour's point at the same fraction of arc length between the same two control
        points.
    """
    tv = target.vertices if target_vertices is None else target_vertices
    found: dict[int, np.ndarray] = {}
    control = set(np.asarray(source_ids).tolist())
    for src_curve, dst_curve in zip(contour_paths(source, source_ids, layout),
                                    contour_paths(target, target_ids, layout), strict=True):
        for s_path, t_path in zip(src_curve, dst_curve, strict=True):
            if len(s_path) < 3:
                continue
            u = _arc_parameter(source.vertices[s_path])[1:-1]
            tp = tv[t_path]
            tu = _arc_parameter(tp)
            landing = np.stack([np.interp(u, tu, tp[:, c]) for c in range(3)], axis=1)
            for v, p in zip(s_path[1:-1].tolist(), landing, strict=True):
                if v not in control and v not in found:
                    found[v] = p
    vertices = np.fromiter(found.keys(), dtype=np.int64, count=len(found))
    points = np.array(list(found.values())).reshape(-1, 3)
    return vertices, points
