"""A textured 3D face from one portrait: the tracker's face mesh, opened at the eyes and mouth, smoothly
subdivided, textured from the photo, with eye, mouth and teeth parts behind the openings.

The shape is MediaPipe's 468-point mesh in metric units (centimetres, the canonical face frame: +x the
subject's left, +y up, +z out of the face), recovered from the photo by the same geometry pipeline the
capture uses. Its depth is the tracker's estimate, good for animation from near the front, not a
scan. Vertex ``i < 468`` of the result is (the smoothed) landmark ``i``, so the tracker's points and
the MPEG-4 feature points sit on known vertices and the face is a ready-made animation target.
"""

from __future__ import annotations

import numpy as np

from ..geometry.mesh import Mesh
from ..geometry.topology import boundary_loops
from ..landmarks import FEATURE_POINT_LANDMARK, LIP_INNER
from .metric import canonical_face, metric_geometry

__all__ = ["AVATAR_PARTS", "face_from_landmarks", "avatar_points", "opened_triangles"]

# The openings of the canonical mesh, as MediaPipe's contours of the lid margins and inner lips.
_EYE_OPENINGS = {
    "right": (33, 246, 161, 160, 159, 158, 157, 173, 133, 155, 154, 153, 145, 144, 163, 7),
    "left": (263, 466, 388, 387, 386, 385, 384, 398, 362, 382, 381, 380, 374, 373, 390, 249),
}
_IRIS_CENTRE = {"right": 468, "left": 473}
_MOUTH_OPENING = LIP_INNER

AVATAR_PARTS = ("skin", "eyes", "mouth", "teeth")

# Flat colours for the parts the photo cannot show, painted in a strip under the photo in the texture.
_MOUTH_COLOUR = (70, 22, 28)
_TEETH_COLOUR = (236, 230, 214)
_SWATCH_ROWS = 16

# Depths behind the openings (cm), chosen so that nothing shows through closed lids or lips.
_EYE_RECESS, _EYE_WIDENING = 0.12, 1.12
_MOUTH_RECESS, _MOUTH_WIDENING, _MOUTH_DROP = 1.0, 1.15, 2.0
_TEETH_RECESS, _TEETH_SPAN, _TEETH_WIDTH = 0.35, (0.25, -0.45), 0.8


def face_from_landmarks(landmarks, image: np.ndarray, *, subdivisions: int = 2, max_texture: int = 1024) -> Mesh:
    """The avatar mesh of a portrait from the tracker's landmarks on it.

    Parameters
    ----------
    landmarks : (478, 3) float64
        MediaPipe's normalised landmarks with iris points (x, y in [0, 1] of the image from the top left).
    image : (H, W, 3) uint8
        The portrait they were found on; the texture is cut from it.
    subdivisions : int
        Loop subdivision steps (each multiplies the triangle count by four).
    max_texture : int
        Longest side of the texture, in pixels (the photo is never enlarged).

    Returns
    -------
    Mesh
        In centimetres, canonical face frame; per-vertex UVs and the texture; parts ``AVATAR_PARTS``.
    """
    import trimesh

    height, width = image.shape[:2]
    points = np.asarray(landmarks, dtype=np.float64)
    if points.shape != (478, 3):
        raise ValueError(f"landmarks must have shape (478, 3) (face mesh with irises), got {points.shape}")
    metric, _ = metric_geometry(points, width, height)
    pixels = points[:, :2] * [width, height]

    triangles = opened_triangles(canonical_face().triangles)
    vertices, skin = trimesh.remesh.subdivide_loop(metric[:468], triangles, iterations=subdivisions)
    # Loop subdivision is linear in the vertex values, so subdividing the pixel positions gives each new
    # vertex the photo position that matches its 3D position's smoothing.
    flat = np.column_stack([pixels[:468], np.zeros(468)])
    skin_pixels = trimesh.remesh.subdivide_loop(flat, triangles, iterations=subdivisions)[0][:, :2]

    texture, to_uv, swatch_uv = _texture(image, pixels, max_texture)
    builder = _PartBuilder(vertices, skin, to_uv(skin_pixels))
    loops = boundary_loops(skin)[1:]  # the longest is the face's outline
    for loop in loops:
        centre = vertices[loop].mean(axis=0)
        nearest = min(_IRIS_CENTRE, key=lambda side: np.linalg.norm(metric[_IRIS_CENTRE[side]] - centre))
        if np.linalg.norm(metric[_IRIS_CENTRE[nearest]] - centre) < np.linalg.norm(
                metric[list(_MOUTH_OPENING)].mean(axis=0) - centre):
            iris = _IRIS_CENTRE[nearest]
            builder.cap(loop, metric[iris], to_uv(pixels[iris][None])[0], part=1, recess=_EYE_RECESS,
                        widening=_EYE_WIDENING, uv=to_uv(skin_pixels[loop]))
        else:
            builder.cap(loop, vertices[loop].mean(axis=0), swatch_uv["mouth"], part=2, recess=_MOUTH_RECESS,
                        widening=_MOUTH_WIDENING, drop=_MOUTH_DROP, lined=True)
            builder.teeth(loop, swatch_uv["teeth"], part=3)
    return builder.mesh(texture)


def avatar_points(mesh: Mesh) -> dict:
    """The control points of a :func:`face_from_landmarks` mesh: ``mp<i>`` for the tracker's 468 mesh
    points and every MPEG-4 feature point MediaPipe observes (pupils: the centres of the eye parts)."""
    points = {f"mp{i}": i for i in range(468)}
    for name, landmark in FEATURE_POINT_LANDMARK.items():
        if landmark < 468:
            points[name] = landmark
    eyes = np.flatnonzero(np.isin(np.arange(len(mesh.vertices)), mesh.triangles[mesh.parts == 1]))
    for name, side in (("3.5", +1), ("3.6", -1)):  # 3.5 is the left pupil (+x)
        ids = eyes[np.sign(mesh.vertices[eyes, 0]) == side]
        if len(ids):
            points[name] = int(ids.max())  # each eye cap's centre is its last vertex
    return points


def opened_triangles(triangles: np.ndarray) -> np.ndarray:
    """The canonical triangles without those spanning the eye and mouth openings."""
    keep = np.ones(len(triangles), dtype=bool)
    for contour in (*_EYE_OPENINGS.values(), _MOUTH_OPENING):
        keep &= ~np.isin(triangles, contour).all(axis=1)
    opened = triangles[keep]
    if len(boundary_loops(opened)) != 4:  # outline, two eyes, mouth: a changed canonical mesh would break this
        raise RuntimeError("the canonical face did not open into an outline, two eyes and a mouth")
    return opened


def _texture(image: np.ndarray, pixels: np.ndarray, max_texture: int):
    """The face cut from the photo with a strip of part colours beneath; maps from pixels to UVs."""
    from PIL import Image

    height, width = image.shape[:2]
    low, high = pixels.min(axis=0), pixels.max(axis=0)
    margin = 0.25 * (high - low)
    left, top = np.maximum(np.floor(low - margin), 0).astype(int)
    right, bottom = np.minimum(np.ceil(high + margin), [width, height]).astype(int)
    crop = image[top:bottom, left:right, :3]
    scale = min(1.0, max_texture / max(crop.shape[:2]))
    size = (max(1, round(crop.shape[1] * scale)), max(1, round(crop.shape[0] * scale)))
    face = np.asarray(Image.fromarray(crop).resize(size, Image.LANCZOS)) if scale < 1 else crop
    strip = np.empty((_SWATCH_ROWS, face.shape[1], 3), np.uint8)
    half = face.shape[1] // 2
    strip[:, :half], strip[:, half:] = _MOUTH_COLOUR, _TEETH_COLOUR
    texture = np.vstack([face, strip])
    rows = texture.shape[0]
    # UVs are fractions of the image, so resizing to powers of two (which every GPU path mipmaps) moves nothing.
    power = [min(max_texture, 2 ** int(np.ceil(np.log2(n)))) for n in texture.shape[1::-1]]
    texture = np.asarray(Image.fromarray(texture).resize(tuple(power), Image.LANCZOS))

    def to_uv(p):
        p = np.asarray(p, dtype=np.float64)
        u = (p[:, 0] - left) / (right - left)
        v = 1.0 - (p[:, 1] - top) / (bottom - top) * face.shape[0] / rows
        return np.column_stack([u, v])

    middle = 1.0 - (face.shape[0] + 0.5 * _SWATCH_ROWS) / rows
    return texture, to_uv, {"mouth": (0.25, middle), "teeth": (0.75, middle)}


class _PartBuilder:
    """Collects the skin and the parts added behind its openings into one mesh."""

    def __init__(self, vertices, triangles, uv):
        self.vertices, self.triangles, self.uv = [vertices], [triangles], [uv]
        self.parts = [np.zeros(len(triangles), dtype=np.int64)]
        self.count = len(vertices)

    def _add(self, vertices, triangles, uv, part):
        triangles = np.asarray(triangles, dtype=np.int64)
        normals = np.cross(vertices[triangles[:, 1]] - vertices[triangles[:, 0]],
                           vertices[triangles[:, 2]] - vertices[triangles[:, 0]])
        if normals[:, 2].sum() < 0:  # every part faces out of the face (+z)
            triangles = triangles[:, ::-1]
        self.vertices.append(vertices)
        self.triangles.append(triangles + self.count)
        self.uv.append(np.broadcast_to(np.asarray(uv, dtype=np.float64), (len(vertices), 2)))
        self.parts.append(np.full(len(triangles), part, dtype=np.int64))
        self.count += len(vertices)

    def cap(self, loop, centre, centre_uv, *, part, recess, widening, drop=0.0, uv=None, lined=False):
        """A fan over an opening, widened about its centre, set back, and its lower half let down by
        ``drop`` (for a jaw that opens), so the rim never shows a gap. ``lined``: with a band from the
        opening's edge back to the fan's rim (a separate piece, so both its edges ride on the opening's
        edge as the rim does), since a view from the side into an opening set this far back passes
        between the two and out through the back of the mask."""
        rim = self.vertices[0][loop].copy()
        rim[:, :2] = centre[:2] + widening * (rim[:, :2] - centre[:2])
        rim[:, 2] -= recess
        lower = np.clip((centre[1] - rim[:, 1]) / max(np.ptp(rim[:, 1]), 1e-9) * 4, 0, 1)
        rim[:, 1:] -= drop * lower[:, None]  # down and as far back: the floor of the mouth, behind the chin
        tip = np.asarray(centre, dtype=np.float64) - [0.0, 0.0, recess]
        n = len(loop)
        fan = [(i, (i + 1) % n, n) for i in range(n)]
        corners_uv = centre_uv if uv is None else np.vstack([uv, centre_uv])
        self._add(np.vstack([rim, tip]), fan, corners_uv, part)
        if lined:
            after = (np.arange(n) + 1) % n
            band = np.r_[np.c_[np.arange(n), after, n + after], np.c_[np.arange(n), n + after, n + np.arange(n)]]
            self._add(np.vstack([self.vertices[0][loop], rim]), band, centre_uv, part)

    def teeth(self, mouth_loop, colour_uv, *, part):
        """A band behind the upper inner lip: hidden with the lips closed, seen when they part."""
        lip = self.vertices[0][mouth_loop]
        a, b = sorted((int(lip[:, 0].argmin()), int(lip[:, 0].argmax())))  # the mouth corners
        chains = lip[a:b + 1], np.vstack([lip[b:], lip[:a + 1]])  # the two lips, corner to corner
        upper = max(chains, key=lambda chain: chain[:, 1].mean())
        upper = upper[np.argsort(upper[:, 0])]
        # Narrower than the lips, so the corners drawn in ("oh") do not push through to the teeth.
        middle = 0.5 * (upper[0, 0] + upper[-1, 0])
        upper[:, 0] = middle + _TEETH_WIDTH * (upper[:, 0] - middle)
        top = upper + [0.0, _TEETH_SPAN[0], -_TEETH_RECESS]
        bottom = upper + [0.0, _TEETH_SPAN[1], -_TEETH_RECESS]
        n = len(upper)
        quads = [(i, i + 1, n + i + 1) for i in range(n - 1)] + [(i, n + i + 1, n + i) for i in range(n - 1)]
        self._add(np.vstack([top, bottom]), quads, colour_uv, part)

    def mesh(self, texture) -> Mesh:
        return Mesh(np.vstack(self.vertices), np.vstack(self.triangles), uv=np.vstack(self.uv), texture=texture,
                    parts=np.concatenate(self.parts), part_names=AVATAR_PARTS)
