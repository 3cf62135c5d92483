"""The mouth's inside, where a head model's skin runs on past the lips into a closed bag.

Some heads (ICT-FaceKit's among them) have no opening at the mouth: the skin turns in at the lips'
inner rims and runs back into a bag that joins the upper lip's lining to the lower's behind the teeth
(ICT's runs on into the throat). Along the surface the two lips are then neighbours through the bag,
and whatever is smoothed along the skin passes from one lip to the other through it: the jaw's raise
against folding, the fold fill, the spread of the motion. On the ICT round trip's widest jawOpen
(``benchmarks/roundtrip_ict.py``, pair 100, no video) folds in the lining behind the lower lip had
the fold fill put 1,700 vertices on the jaw's turn, raised through the bag past the upper lip's rim:
the upper lip's lining hung 1.9 cm down over the open mouth (the truth: 0.4) and the lower lip's rim
stopped 0.4 cm short of its control point. In a smile the bag drew the upper lip's middle down into
a point (pair 3).

So the skin beyond the inner rims is told apart: the rims' control points joined by shortest paths
along the skin make a closed loop, and the skin the loop cuts off from the face, reaching well behind
the lips, is the mouth's inside. It is given the role of a socket, which hangs between the lips' inner
edge and the gums (:mod:`faceanim.retarget.deform`), and the lips meet only at the mouth's corners,
as on a head whose mouth is open. A head whose lips open onto a hole, or one with a separate socket,
has nothing cut off and keeps its skin as it is.
"""

from __future__ import annotations

import numpy as np
from scipy import sparse
from scipy.sparse import csgraph

from ..geometry.mesh import Mesh
from ..geometry.surface import edge_graph
from ..geometry.topology import submesh
from ..landmarks import LIP_INNER, landmark_names
from ..target import Target

__all__ = ["RIM_LOOP", "mouth_inside"]

_NAMES = landmark_names(478)
#: The inner rims' control points in order round the mouth, by the names placement gives them (MPEG-4's
#: 2.2-2.9 where they are among MediaPipe's, so a target with MPEG-4's points alone has a coarser loop
#: round the same rims).
RIM_LOOP = tuple(_NAMES[i] for i in LIP_INNER)
_LEAST_POINTS = 6  # rim points a loop needs, both corners among them
_LARGEST = 0.5  # a cut-off part bigger than this share of the face is no mouth (the loop leaked)
_DEEP = 0.2  # of the mouth's width: how far behind the rims a mouth's inside reaches, at least
_REACH = 4.0  # a path between neighbouring rim points is at most this many times as long as the gap


def mouth_inside(mesh: Mesh, skin: np.ndarray, target: Target, forward: np.ndarray, width: float) -> np.ndarray:
    """``(V,) bool``: the skin ``skin (V,) bool`` that the loop through the lips' inner rims cuts off
    from the face and that reaches more than :data:`_DEEP` of the mouth's ``width`` (8.3 to 8.4) behind
    the loop along ``forward`` (the face's +z). Nothing where the target has fewer than
    :data:`_LEAST_POINTS` of :data:`RIM_LOOP`'s points or lacks a corner (2.4, 2.5), where one is off
    the skin, or where nothing deep is cut off. The points are taken in :data:`RIM_LOOP`'s order
    round the mouth, as placement names them."""
    none = np.zeros(len(mesh.vertices), dtype=bool)
    names = [n for n in RIM_LOOP if n in target.points]
    if len(names) < _LEAST_POINTS or not {"2.4", "2.5"} <= set(names):
        return none
    sub, index = submesh(mesh, skin)
    rim = index[[target.points[n] for n in names]]
    if (rim < 0).any():
        return none
    loop = _closed_loop(sub, rim)
    if loop is None:
        return none
    kept = np.ones(len(sub.vertices), dtype=bool)
    kept[loop] = False
    edges = sub.edges
    V = len(sub.vertices)
    inside_edges = edges[kept[edges].all(axis=1)]
    graph = sparse.coo_matrix((np.ones(len(inside_edges)), (inside_edges[:, 0], inside_edges[:, 1])), shape=(V, V))
    _, labels = csgraph.connected_components(graph, directed=False)
    touching = np.zeros(V, dtype=bool)
    touching[edges[~kept[edges[:, 0]], 1]] = True
    touching[edges[~kept[edges[:, 1]], 0]] = True
    parts = np.unique(labels[touching & kept])
    if len(parts) < 2:
        return none  # the loop cuts nothing off (or holds the whole skin)
    sizes = np.array([(labels == p).sum() for p in parts])
    face = parts[np.argmax(sizes)]  # the largest part the loop touches: the face round the mouth
    # What the loop cuts off between itself and a hole's edge (where a shortest path leaves the edge
    # of a mouth that opens) is a sliver in front of or level with the rims: the inside of a mouth
    # reaches well behind them.
    forward = np.asarray(forward, dtype=np.float64)
    behind = (sub.vertices[loop] @ forward).mean() - sub.vertices @ forward
    deep = [p for p in parts if p != face and behind[labels == p].max() > _DEEP * width]
    cut_off = kept & np.isin(labels, deep)
    if cut_off.sum() > _LARGEST * sizes.max():
        return none  # the loop leaked: no mouth is that large
    out = none.copy()
    out[np.flatnonzero(skin)[cut_off]] = True
    return out


def _closed_loop(mesh: Mesh, points: np.ndarray) -> np.ndarray | None:
    """The vertices of the shortest paths along ``mesh``'s edges joining ``points`` in turn and the
    last back to the first; None if two of them are not joined."""
    graph = edge_graph(mesh)
    loop = []
    for a, b in zip(points, np.roll(points, -1), strict=True):
        # Neighbouring rim points are a few edges apart along the lip: the search stops well past that,
        # unless it has to go round (placement can put an upper and a lower rim point on one vertex of
        # lips that meet, and the path between their neighbours then runs along the other lip).
        reach = _REACH * np.linalg.norm(mesh.vertices[a] - mesh.vertices[b]) + 1e-9
        distance, previous = csgraph.dijkstra(graph, indices=a, return_predecessors=True, limit=reach)
        if not np.isfinite(distance[b]):
            distance, previous = csgraph.dijkstra(graph, indices=a, return_predecessors=True)
        if not np.isfinite(distance[b]):
            return None
        at = b
        while at != a:
            loop.append(at)
            at = previous[at]
        loop.append(a)
    return np.unique(loop)
