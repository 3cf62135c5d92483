"""Automatic placement of control points on any mesh: render it, find the face, cast the points back.

The mesh is rendered shaded (no texture needed) from the front, MediaPipe's face mesh runs on the
picture, and each of its 478 points is cast back onto the surface through the depth buffer and the
camera, then snapped to the nearest vertex. A first pass finds the face; a second, framed tightly on
it, places the points. The lids' points are moved onto the lid margins the skin's depth buffer shows
(MediaPipe reads some untextured faces' eyes as half shut). A result that is not left-right consistent
is refused.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..geometry.mesh import Mesh
from ..geometry.project import project_points
from ..geometry.topology import component_labels
from ..landmarks import FEATURE_POINT_LANDMARK, LIP_INNER
from ..render.camera import front_camera
from ..target import Target, measure_fapu

__all__ = ["place_landmarks", "auto_target"]

# Light from above and in front, as a room lights a face: the brow ridge, lids and lips cast the shading
# the tracker expects. Lit from the camera, an untextured face has flat eye sockets, and MediaPipe
# placed the ICT neutral's brows and upper lids 0.9 cm too low (benchmarks/placement_ict.py).
_LIGHT = (0.0, 1.0, 1.0)
_UPPER_INNER_LIP = LIP_INNER[1:10]  # between the corners 78 and 308
_LOWER_INNER_LIP = LIP_INNER[11:]
_IRIS_START = 468  # 468-472 and 473-477: the irises
# Mirror pairs seen face-on, for the left-right check. Not the face's outline (234 / 454 by the ears): there the
# skin runs along the line of sight, and the point cast back slides centimetres back or forth with a pixel (ICT
# identities with 0.6 cm between the sides' outlines and well-placed eyes and lips were refused).
_MIRROR_PAIRS = ((33, 263), (133, 362), (61, 291), (70, 300), (50, 280), (159, 386), (145, 374))
# Each eye's lid points between its corners (MediaPipe's eye contours): (outer corner, inner corner, upper lid,
# lower lid), the subject's right eye first.
_EYE_LIDS = ((33, 133, (246, 161, 160, 159, 158, 157, 173), (7, 163, 144, 145, 153, 154, 155)),
             (263, 362, (466, 388, 387, 386, 385, 384, 398), (249, 390, 373, 374, 380, 381, 382)))


def _track_render(mesh, camera, renderer, tracker):
    """The face MediaPipe finds in a render: pixels ``(478, 2)``, its relative depths ``(478,)`` in
    pixels (MediaPipe's z, which shares the x axis's scale), and the render's depth buffer."""
    image, depth = renderer.render(mesh, camera, depth=True, light=_LIGHT)
    faces = tracker.all_faces(image)
    if not faces:
        return None
    face = max(faces, key=lambda f: np.prod(np.ptp(f[:, :2], axis=0)))
    return face[:, :2] * [camera.width, camera.height], face[:, 2] * camera.width, depth


def _surface_points(pixels, relative, depth, camera):
    """World points behind landmark pixels.

    Most points take the depth buffer's distance. A point on the face's outline (the jaw, the cheek
    by the ear) sits where the surface turns away, and the buffer there gives the ear, the neck or
    nothing; such a point takes the distance MediaPipe's own depth predicts instead (a line fitted
    from its relative depths to the buffer's over the points where the two agree).
    """
    H, W = depth.shape
    cols = np.clip(np.round(pixels[:, 0] - 0.5).astype(int), 0, W - 1)
    rows = np.clip(np.round(pixels[:, 1] - 0.5).astype(int), 0, H - 1)
    seen = depth[rows, cols]
    usable = np.isfinite(seen)
    if usable.sum() < 0.5 * len(seen):
        raise InputError("automatic placement: the face points found do not lie on the mesh")
    # distance = a + b * relative, with b the world size of a pixel at the face over the focal
    # length's worth of pixels; refit without the points that disagree (outline points).
    for _ in range(3):
        b, a = np.polyfit(relative[usable], seen[usable], 1)
        residual = np.where(np.isfinite(seen), np.abs(seen - (a + b * relative)), np.inf)
        spread = 1.4826 * np.median(residual[usable])
        usable = residual <= max(3.0 * spread, 1e-9)
    predicted = a + b * relative
    tolerance = 4.0 * max(spread, 1e-9)
    distance = np.where(residual <= tolerance, seen, predicted)
    return camera.unproject(pixels, distance)


def place_landmarks(mesh: Mesh, *, size: int = 512, yaws=(0.0, -12.0, 12.0)) -> np.ndarray:
    """Vertex ids ``(478,)`` of MediaPipe's face-mesh points on ``mesh`` (a face looking along +z, +y up);
    -1 for an iris on a face without eyeballs.

    Raises
    ------
    InputError
        No face is found in the renders (also slightly turned), or the points found are not
        left-right consistent.
    """
    from ..capture.tracker import FaceTracker, TrackerOptions
    from ..render.rasterizer import Renderer

    with Renderer(size, size) as renderer, FaceTracker(TrackerOptions(static=True, max_faces=1)) as tracker:
        found = None
        for yaw in yaws:
            camera = front_camera(mesh.vertices, size, size, vertical_fov=20.0, margin=1.05, yaw=yaw)
            found = _track_render(mesh, camera, renderer, tracker)
            if found is not None:
                break
        if found is None:
            raise InputError("automatic placement found no face on the rendered mesh (it should face +z with +y "
                             "up); give the control points as a JSON or .fdp file")
        rough = _surface_points(*found, camera)
        # Second pass: frame the face itself, so it fills the picture.
        camera = front_camera(rough, size, size, vertical_fov=20.0, margin=1.25, yaw=yaw)
        found = _track_render(mesh, camera, renderer, tracker)
        if found is None:
            raise InputError("automatic placement lost the face when framing it closely")
        points = _surface_points(*found, camera)
        first, on_skin, skin_mesh = _find_skin(mesh, points)
        skin_depth = found[2]
        if len(skin_mesh.triangles) < len(mesh.triangles):
            _, skin_depth = renderer.render(skin_mesh, camera, depth=True, light=_LIGHT)
            if not on_skin[:_IRIS_START].all():
                # Lashes, brows or hair in front of the skin caught some points: cast those through the skin alone.
                points[:_IRIS_START] = _surface_points(found[0], found[1], skin_depth, camera)[:_IRIS_START]
        lids, pixels, distance = _lid_margins(found[0], skin_depth, camera.focal)
        points[lids] = camera.unproject(pixels, distance)
    ids = _snap(points, first, on_skin, skin_mesh)
    _check_symmetry(mesh.vertices[ids])
    return ids


def _lid_margins(pixels: np.ndarray, depth: np.ndarray, focal: float, *, jump: float = 0.3, reach: float = 0.6,
                 front: float = 0.25):
    """Each eye's lid points moved onto the lid margins seen in the skin's depth buffer: ``(ids, pixels (n, 2),
    distances (n,))`` for the lid points moved.

    MediaPipe reads the eyes of some untextured faces as half shut and puts the upper lid's points on the
    eyeball, whose nearest skin is then the lower lid. The skin's own depth buffer (distances along the view
    axis, a camera of focal length ``focal`` pixels) shows the opening: within ``reach`` eye widths above and
    below the eye's points (0.2 beside), the pixels more than ``jump`` eye widths deeper than both the nearest
    skin within a third of an eye width and the median skin there, or with no skin at all (a hole), holes
    filled; of those regions, the one holding the most of the eye's points. Each lid point then takes, in its
    own pixel column and its run of opening pixels nearest the point, the lid's rim: the skin pixel before the
    greatest step in depth between the run's top (upper lid; its bottom for the lower lid) and its middle, and
    that pixel's depth; unless that is more than half an eye width from the point, or more than ``front`` eye
    widths nearer the camera than the median skin round the eye (a deep-set eye's upper lid hidden under the
    brow: the rim seen is the brow's, 1.7-1.9 cm in front of the lid on ICT's sigma-2.5 seed 18, where the
    point cast back landed on the brow 1.7 cm from the lid's margin). A column the opening does
    not reach, or an eye with no opening (closed lids), keeps its points as they were. (Taking the depth of the
    lid's front just outside the rim instead, 0.3-0.6 cm nearer, put the eyes' points further from ICT's
    landmarks: median over the tuning identities 0.185 -> 0.211 cm, ``benchmarks/placement_ict.py``.)
    """
    from scipy import ndimage

    H, W = depth.shape
    far = np.where(np.isfinite(depth), depth, np.inf)
    moved_ids, moved_px, moved_d = [], [], []
    for outer, inner, upper, lower in _EYE_LIDS:
        eye = pixels[[outer, inner, *upper, *lower]]
        width = float(np.linalg.norm(pixels[inner] - pixels[outer]))
        if width < 4:
            continue
        lo = np.floor(eye.min(axis=0) - [0.2 * width, reach * width]).astype(int)
        hi = np.ceil(eye.max(axis=0) + [0.2 * width, reach * width]).astype(int)
        lo, hi = np.maximum(lo, 0), np.minimum(hi, [W, H])
        box = far[lo[1]:hi[1], lo[0]:hi[0]]
        seen = np.isfinite(box)
        if seen.sum() < 0.5 * box.size:
            continue
        # The eye's width in world units: a pixel at distance d along the view axis spans d / focal.
        round_eye = float(np.median(box[seen]))
        eye_width = width * round_eye / focal
        step_down = jump * eye_width
        nearest_rim = round_eye - front * eye_width
        size = max(int(round(width / 3)), 3)
        nearest_skin = ndimage.minimum_filter(np.where(seen, box, np.inf), size=size, mode="nearest")
        # Deeper than the skin nearby and than the skin round the eye as a whole (the side of the nose and the
        # brow ridge stand in front of the skin beside them, which the first alone would take for an opening).
        opening = ~seen | ((box > nearest_skin + step_down) & (box > round_eye + step_down))
        opening = ndimage.binary_fill_holes(opening)
        label, count = ndimage.label(opening)
        if not count:
            continue
        inside = eye - lo
        rows = np.clip(np.floor(inside[:, 1]).astype(int), 0, box.shape[0] - 1)
        columns = np.clip(np.floor(inside[:, 0]).astype(int), 0, box.shape[1] - 1)
        votes = np.bincount(label[rows, columns], minlength=count + 1)[1:]
        if votes.max() == 0:
            continue
        hole = label == 1 + int(votes.argmax())
        for ids, step in ((upper, -1), (lower, 1)):
            for i in ids:
                c = int(np.floor(pixels[i, 0])) - lo[0]
                if not 0 <= c < box.shape[1] or not hole[:, c].any():
                    continue
                # The run of opening pixels in this column nearest the point's own row.
                r = np.flatnonzero(hole[:, c])
                row = int(np.floor(pixels[i, 1])) - lo[1]
                runs = np.split(r, np.flatnonzero(np.diff(r) > 1) + 1)
                r = min(runs, key=lambda run: 0 if run[0] <= row <= run[-1] else min(abs(run[0] - row),
                                                                                      abs(run[-1] - row)))
                middle = (r.min() + r.max()) // 2
                # The rim: the greatest step in depth between the opening's edge (two pixels out) and its middle.
                span = np.arange(max(r.min() - 2, 0), middle + 1) if step < 0 else \
                    np.arange(middle, min(r.max() + 3, box.shape[0]))[::-1]
                if len(span) < 2:
                    continue
                d = np.minimum(box[span, c], 1e30)
                edge = span[int(np.argmax(d[1:] - d[:-1]))]
                if not seen[edge, c] or abs(edge - row) > 0.5 * width or box[edge, c] < nearest_rim:
                    continue
                moved_ids.append(i)
                moved_px.append([pixels[i, 0], lo[1] + edge + 0.5])
                moved_d.append(box[edge, c])
    return np.asarray(moved_ids, dtype=np.int64), np.asarray(moved_px, dtype=np.float64).reshape(-1, 2), \
        np.asarray(moved_d, dtype=np.float64)


def _find_skin(mesh: Mesh, points: np.ndarray):
    """Where the cast-back points land: the hits on the whole mesh, whether each is on the skin, and the
    skin as a mesh of its own.

    The skin is the part of the mesh (connected component) most points land on; others are eyeballs,
    teeth, lashes, seen through the eye or mouth opening or in front of the skin.
    """
    part = component_labels(mesh)
    first = project_points(mesh, points)
    landed = part[first.corner_vertices[:, 0]]
    skin = np.bincount(landed).argmax()
    skin_mesh = Mesh(mesh.vertices, mesh.triangles[part[mesh.triangles[:, 0]] == skin])
    return first, landed == skin, skin_mesh


def _snap(points: np.ndarray, first, on_skin: np.ndarray, skin_mesh: Mesh) -> np.ndarray:
    """Vertex ids of the cast-back points: on the skin, inner lips on their own lip, irises on the eyeball.

    ``first``: the points' hits on the whole mesh; ``on_skin``: whether each hit is on the skin. On a
    closed mouth the upper and lower inner-lip points fall on the same line, so each takes its own
    lip's side of the seam: the nearest skin facing down (upper lip) or up (lower lip). An iris point
    keeps the part it landed on when that is not the skin (an eyeball, or a film over it), or is left
    out (-1) where the eye is a hole: pinned to the lid, it would hold the lid still.
    """
    ids = _nearest_corner(project_points(skin_mesh, points))
    for lip, up in ((_UPPER_INNER_LIP, -1.0), (_LOWER_INNER_LIP, 1.0)):
        lip = np.asarray(lip)
        facing = np.tile([0.0, up, 0.0], (len(lip), 1))
        ids[lip] = _nearest_corner(project_points(skin_mesh, points[lip], normals=facing, max_angle=75.0))
    iris = slice(_IRIS_START, len(points))
    ids[iris] = np.where(~on_skin[iris], _nearest_corner(first)[iris], -1)
    return ids


def _nearest_corner(hit) -> np.ndarray:
    return hit.corner_vertices[np.arange(len(hit.triangles)), hit.barycentric.argmax(axis=1)]


def _check_symmetry(points: np.ndarray) -> None:
    """Mirror pairs must sit at similar distances from the face's midline plane."""
    left, right = points[[b for _, b in _MIRROR_PAIRS]], points[[a for a, _ in _MIRROR_PAIRS]]
    axis = (left - right).mean(axis=0)
    axis /= np.linalg.norm(axis)
    middle = points[[1, 4, 6, 168, 152, 0, 17]] @ axis  # nose, bridge, chin and lip middles
    plane = np.median(middle)
    scale = np.linalg.norm(points[263] - points[33])
    offsets = np.abs((left @ axis - plane) - (plane - right @ axis)) / scale
    if offsets.max() > 0.15:  # a good placement (ICT neutral) stays under 0.07
        raise InputError(f"automatic placement found an asymmetric face (left and right points differ by up to "
                         f"{offsets.max():.0%} of the eye width); give the control points as a JSON or .fdp file")


def auto_target(mesh: Mesh) -> Target:
    """A Target whose control points are placed automatically: every MPEG-4 feature point MediaPipe
    observes (by number) and all 478 of its points (``mp<i>``)."""
    ids = place_landmarks(mesh)
    points = {f"mp{i}": int(v) for i, v in enumerate(ids) if v >= 0}
    points.update({name: int(ids[i]) for name, i in FEATURE_POINT_LANDMARK.items() if ids[i] >= 0})
    return Target(mesh, points, measure_fapu(mesh, points, source="automatic placement"))
