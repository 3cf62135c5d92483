"""How much of the jaw's turn each skin vertex follows: a harmonic field along the skin."""

from __future__ import annotations

import numpy as np
from scipy import sparse
from scipy.sparse.linalg import spsolve

from ..geometry.mesh import Mesh
from ..geometry.surface import cotangent_laplacian
from ..geometry.topology import component_labels, submesh
from ..target import Target
from .faceparts import _LOWER_LIP, _UPPER_LIP
from .frame import _Frame, _smoothstep


def _skin_jaw_weight(mesh: Mesh, skin: np.ndarray, frame: _Frame, target: Target) -> np.ndarray:
    """``(S,)`` the jaw's share of each skin vertex: harmonic along the skin between the chin (1) and
    the upper lip, the ears and the neck (0)."""
    ids = np.flatnonzero(skin)
    sub, index_of = submesh(mesh, skin)
    tris = sub.triangles
    local = frame.local(mesh.vertices[ids])
    x, y, z = local.T
    chin, mouth, hinge = frame.chin, frame.mouth, frame.hinge_local
    w = frame.mouth_width
    depth = chin[2] - hinge[2]
    # The jaw line runs from the chin back to below the hinge; the neck lies under it. The line the
    # jaw's skin ends at above runs from the lip line at the mouth back to the hinge.
    corners = [frame.local_points[n] for n in ("2.13", "2.14") if n in frame.local_points]
    gonion = np.mean(corners, axis=0) if corners else chin + 0.45 * (hinge - chin)
    slope = (gonion[1] - chin[1]) / max(chin[2] - gonion[2], 0.1 * w)
    under_jaw = chin[1] + slope * (chin[2] - z) - y
    back = np.clip((mouth[2] - z) / (mouth[2] - hinge[2]), 0.0, 1.0)
    above = y - (mouth[1] + (hinge[1] - mouth[1]) * back)
    # Beside the mouth the jaw's full share starts a band below that line; on the lower lip, at it.
    # In the middle the lips themselves are pinned (below); the jaw's full share starts under the lower lip.
    lip_bottom = frame.local_points["8.2"][1] if "8.2" in frame.local_points else mouth[1] - 0.1 * w
    band = np.maximum(0.3 * w * _smoothstep(np.abs(x - mouth[0]) / (0.5 * w)), mouth[1] - lip_bottom)
    fixed = np.full(len(ids), np.nan)
    fixed[(above < -band) & (under_jaw < 0.02 * w) & (z > hinge[2] + 0.25 * depth)] = 1.0
    fixed[above > 0.1 * w] = 0.0  # the upper lip and everything above
    fixed[z < hinge[2]] = 0.0  # the ears and the back of the head
    fixed[under_jaw > 0.8 * w] = 0.0  # the neck, well below the jaw line: the skin between stretches
    # The lips meet at the lip line, so height cannot tell them apart there; their control points can.
    for names, value in ((_UPPER_LIP, 0.0), (_LOWER_LIP, 1.0)):
        pinned = index_of[[target.points[n] for n in names if n in target.points]]
        fixed[pinned[pinned >= 0]] = value
    if not (fixed == 1).any():
        return np.zeros(len(ids))
    if not len(tris):
        return np.nan_to_num(fixed)
    L, _ = cotangent_laplacian(sub)
    # Vertices in no skin triangle, and skin islands with no fixed vertex, hold 0.
    used = np.zeros(len(ids), dtype=bool)
    used[np.unique(tris)] = True
    fixed[~used] = 0.0
    labels = component_labels(sub)
    for k in np.unique(labels):
        island = labels == k
        if np.isnan(fixed[island]).all():
            fixed[island] = 0.0
    free = np.isnan(fixed)
    out = np.nan_to_num(fixed)
    if free.any():
        L = sparse.csr_matrix(L)
        A = L[free][:, free]
        b = -L[free][:, ~free] @ out[~free]
        out[free] = spsolve(A.tocsc(), b)
    return np.clip(out, 0.0, 1.0)
