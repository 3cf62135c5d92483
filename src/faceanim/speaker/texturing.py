"""Making a clone's appearance from its speech video: the synthesis mesh, the key postures, their
textures over one common parametrisation, and the colour model learnt from them.

* The synthesis mesh (:func:`synthesis_triangles`): the model's triangles over its mobile points and
  the static points nearest the mouth, as many as the original's bounds allow (200 static points,
  700 triangles); the model's own triangulation covers the whole face (some 300 static points and
  900 triangles for MediaPipe's landmarks), more than the original drew.
* The parametrisation (:func:`texture_uv`): a frontal projection of the rest shape, normalised over
  the synthesis mesh's box (points outside it are clamped to the edge).
* The key postures (:func:`choose_key_frames`), read from the model's points at each build frame's
  parameters: *rest*, the frame nearest the neutral face (RMS over the mobile points); *open*, the
  widest gap between the inner lips' middles (2.2, 2.3); *rounded*, the narrowest mouth (corners 8.3,
  8.4) among the other frames. On the talking clips d12 and d20 (not the speech clips the benchmark
  reports) this rule re-rendered held-out mouths better (PSNR 23.7 and 25.0 dB) than a closed mouth for
  rest with the widest jaw for open (24.2, 23.0) or farthest-point sampling of the postures (24.0, 21.2).
* A key texture (:func:`key_texture`): every texel of the synthesis mesh's triangles in UV is sent
  through the same triangle's corners projected into the key frame (the key points moved by the
  frame's rigid motion, through the camera) and sampled bilinearly; texels outside the mesh take the
  nearest texel inside, so that filtering at the mesh's border draws no black.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from .appearance import KEY_NAMES, TEXTURE_SIZE, Appearance, influence_of, lip_indices, posture_points
from .camera import moved, project
from .colour import ColourModel, lip_and_skin

__all__ = ["synthesis_triangles", "texture_uv", "texel_map", "choose_key_frames", "key_texture", "uv_polygon_mask",
           "lip_mask_uv", "lip_mask_frame", "build_appearance", "appearance_from_runs", "MAX_MOBILE", "MAX_STATIC",
           "MAX_TRIANGLES"]

MAX_MOBILE, MAX_STATIC, MAX_TRIANGLES = 250, 200, 700  # the original's bounds for synthesis
_MARGIN = 0.02  # of the box, around the mesh in UV


def synthesis_triangles(model, *, max_static: int = MAX_STATIC, max_triangles: int = MAX_TRIANGLES) -> np.ndarray:
    """``(F, 3)`` the model's triangles over its mobile points and the static points nearest the mouth
    (frontal distance at rest to the lips' centre: feature points 2.2, 2.3, 8.3, 8.4), as many static
    points as keep within ``max_static`` and ``max_triangles``."""
    P = len(model.names)
    mobile = model.rest
    corners = [model.names.index(n) for n in ("2.2", "2.3", "8.3", "8.4") if n in model.names]
    centre = mobile[corners].mean(axis=0) if corners else mobile.mean(axis=0)
    order = np.argsort(np.linalg.norm(model.static_points[:, :2] - centre[:2], axis=1))
    triangles = model.triangles
    for count in range(min(max_static, len(order)), -1, -1):
        keep = np.zeros(P + len(order), dtype=bool)
        keep[:P] = True
        keep[P + order[:count]] = True
        chosen = triangles[keep[triangles].all(axis=1)]
        if len(chosen) <= max_triangles:
            return chosen
    return triangles[(triangles < P).all(axis=1)][:max_triangles]


def texture_uv(points, triangles) -> np.ndarray:
    """``(N, 2)`` float32 UV of ``points (N, 3)`` (the rest shape, head frame): x across, y up, normalised
    over the box of the points ``triangles`` use, with a small margin, and clamped to [0, 1]."""
    p = np.asarray(points, dtype=np.float64)
    used = p[np.unique(triangles)]
    low, high = used[:, :2].min(axis=0), used[:, :2].max(axis=0)
    span = high - low
    low, span = low - _MARGIN * span, span * (1 + 2 * _MARGIN)
    u = (p[:, 0] - low[0]) / span[0]
    v = (low[1] + span[1] - p[:, 1]) / span[1]  # v down from the top row, as images are stored
    return np.clip(np.c_[u, v], 0.0, 1.0).astype(np.float32)


def texel_map(uv, triangles, size: int = TEXTURE_SIZE) -> tuple[np.ndarray, np.ndarray]:
    """Which triangle covers each texel's centre and where: ``(face (S, S) int64, -1 where none;
    barycentric (S, S, 3) float64)``. Texel ``(row, column)`` sits at ``uv = ((column + 0.5) / S,
    (row + 0.5) / S)``."""
    corners = np.asarray(uv, dtype=np.float64)[np.asarray(triangles)] * size - 0.5  # texel coordinates
    face = np.full((size, size), -1, dtype=np.int64)
    bary = np.zeros((size, size, 3))
    for f, (a, b, c) in enumerate(corners):
        low = np.maximum(np.floor(np.minimum(np.minimum(a, b), c)).astype(int), 0)
        high = np.minimum(np.ceil(np.maximum(np.maximum(a, b), c)).astype(int), size - 1)
        if (high < low).any():
            continue
        x, y = np.meshgrid(np.arange(low[0], high[0] + 1), np.arange(low[1], high[1] + 1))
        area = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
        if abs(area) < 1e-12:
            continue
        w1 = ((x - a[0]) * (c[1] - a[1]) - (y - a[1]) * (c[0] - a[0])) / area
        w2 = ((b[0] - a[0]) * (y - a[1]) - (b[1] - a[1]) * (x - a[0])) / area
        w0 = 1.0 - w1 - w2
        inside = (w0 >= -1e-9) & (w1 >= -1e-9) & (w2 >= -1e-9)
        face[y[inside], x[inside]] = f
        bary[y[inside], x[inside]] = np.stack([w0[inside], w1[inside], w2[inside]], axis=-1)
    return face, bary


def _fill_outside(image: np.ndarray, covered: np.ndarray) -> np.ndarray:
    """``image`` with the texels outside ``covered`` given the nearest covered texel's value."""
    if covered.all() or not covered.any():
        return image
    _, (rows, columns) = ndimage.distance_transform_edt(~covered, return_indices=True)
    return image[rows, columns]


def key_texture(frame, pixels, triangles, face, bary) -> np.ndarray:
    """``(S, S, 3)`` uint8 texture of ``frame (H, W, 3)`` whose mesh points sit at ``pixels (N, 2)``
    (image coordinates, pixel centres at whole numbers), over the texel map ``face``, ``bary``."""
    frame = np.asarray(frame)
    covered = face >= 0
    at = np.einsum("sk,skc->sc", bary[covered], pixels[triangles[face[covered]]])  # (n, 2) x, y
    texture = np.zeros((*face.shape, 3), dtype=np.uint8)
    for channel in range(3):
        values = ndimage.map_coordinates(frame[..., channel].astype(np.float32), [at[:, 1], at[:, 0]], order=1,
                                         mode="nearest")
        texture[..., channel][covered] = np.clip(np.rint(values), 0, 255).astype(np.uint8)
    return _fill_outside(texture, covered)


def uv_polygon_mask(uv, contour, size: int = TEXTURE_SIZE) -> np.ndarray:
    """``(S, S)`` bool: the texels inside the polygon of ``uv[contour]``."""
    from skimage.draw import polygon2mask

    corners = np.asarray(uv, dtype=np.float64)[np.asarray(contour)] * size - 0.5  # texel coordinates (x, y)
    return polygon2mask((size, size), corners[:, ::-1])


def lip_mask_uv(uv, outer, inner, size: int = TEXTURE_SIZE) -> np.ndarray:
    """``(S, S)`` bool: the lips in the textures, between the outer and the inner contour."""
    return uv_polygon_mask(uv, outer, size) & ~uv_polygon_mask(uv, inner, size)


def lip_mask_frame(appearance, points, rigid, width: int, height: int, *, camera=None) -> np.ndarray:
    """``(height, width)`` bool: the lips (between the outer and the inner contour) of a frame in which
    the mesh's head-frame ``points (N, 3)`` sit at ``rigid (6,)`` seen by ``camera`` (default the
    appearance's): the region to adapt the colour model on (:meth:`.ColourModel.adapted`)."""
    from skimage.draw import polygon2mask

    P = appearance.camera if camera is None else camera
    scale = np.array([width, height], dtype=np.float64)
    at = project(P, moved(np.asarray(points, dtype=np.float64), rigid)) * scale - 0.5
    outer = polygon2mask((height, width), at[appearance.lip_outer][:, ::-1])
    inner = polygon2mask((height, width), at[appearance.lip_inner][:, ::-1])
    return outer & ~inner


def _point(names, name: str) -> int:
    try:
        return names.index(name)
    except ValueError:
        raise ValueError(f"the speaker model lacks feature point {name}, which key postures are read from") from None


def choose_key_frames(model, parameters, frames) -> np.ndarray:
    """``(3,)`` frame numbers (of ``frames``) of the rest, open and rounded key postures, read from
    the model's points at ``parameters (T, K)`` (see the module's docstring); frames with NaN
    parameters are skipped.

    Raises
    ------
    ValueError
        Fewer than 3 usable frames.
    """
    frames = np.asarray(frames, dtype=np.int64)
    a = np.asarray(parameters, dtype=np.float64)[frames]
    usable = np.isfinite(a).all(axis=1)
    frames, a = frames[usable], a[usable]
    if len(frames) < 3:
        raise ValueError(f"{len(frames)} frames with a face are too few for 3 key postures")
    names = list(model.names)
    x = model.points(a)
    gap = x[:, _point(names, "2.2"), 1] - x[:, _point(names, "2.3"), 1]
    width = np.abs(x[:, _point(names, "8.4"), 0] - x[:, _point(names, "8.3"), 0])
    rest = int(np.argmin(np.sqrt(((x - model.neutral) ** 2).sum(axis=-1).mean(axis=-1))))
    gap_order = np.argsort(-gap)
    opened = int(next(i for i in gap_order if i != rest))
    width_order = np.argsort(width)
    rounded = int(next(i for i in width_order if i not in (rest, opened)))
    return frames[[rest, opened, rounded]]


def build_appearance(model, *, names, points, landmarks, pose, valid, width: int, height: int, read_frames, frames=None,
                     size: int = TEXTURE_SIZE) -> tuple[Appearance, object]:
    """The appearance of ``model`` from its video's capture.

    Parameters
    ----------
    model : SpeakerModel
    names : sequence of str, (L,)
        The capture's point names, in MediaPipe's landmark order (its ``Motion.names``).
    points : (T, L, 3) float64
        The capture's head-frame points (the motion's neutral plus displacements), every landmark.
    landmarks : (T, L, 2)
        The tracked landmarks (normalised image coordinates).
    pose : (T, 4, 4), valid : (T,) bool
        The capture's head pose and which frames had a face.
    width, height : int
        The frames' size.
    read_frames : callable
        ``read_frames(indices) -> list of (H, W, 3) uint8``: those frames of the video.
    frames : indices, optional
        The frames to choose from and to fit the camera on (default: all); the model's build frames.

    Returns
    -------
    appearance : Appearance
    fit : :class:`~faceanim.speaker.camera.CameraFit`
        The camera fit, with its rigid motion of every frame and its reprojection error.
    """
    points = np.asarray(points)
    landmarks = np.asarray(landmarks)
    return appearance_from_runs(model, names=names, runs=lambda: iter([(0, points, landmarks)]), pose=pose, valid=valid,
                                width=width, height=height, read_frames=read_frames, frames=frames, size=size)


def appearance_from_runs(model, *, names, runs, pose, valid, width: int, height: int, read_frames, frames=None,
                         size: int = TEXTURE_SIZE) -> tuple[Appearance, object]:
    """:func:`build_appearance` from a capture read in runs of frames, one run held at a time (``faceanim
    speaker textures`` on a streamed capture: memory does not grow with the video's length beyond a
    few numbers a frame); the same answer.

    ``runs()`` gives an iterator of ``(start, points (n, L, 3), landmarks (n, L, 2))``, the capture's
    head-frame points and tracked landmarks of frames ``start .. start + n``, over the video in order;
    it is called a few times (the camera fit's passes, the landmark-based parameters). The other
    arguments are :func:`build_appearance`'s."""
    from .camera import fit_video_camera_runs

    everything = tuple(names)
    mesh_names = model.names + model.static_names
    lookup = {n: i for i, n in enumerate(everything)}
    missing = [n for n in mesh_names if n not in lookup]
    if missing:
        raise ValueError(f"the capture lacks the model's points {', '.join(missing[:4])}")
    index = np.array([lookup[n] for n in mesh_names])

    def mesh_runs():
        for start, points, landmarks in runs():
            if np.shape(points)[1] != len(everything):
                raise ValueError(f"names must name the capture's {np.shape(points)[1]} points, got {len(everything)}")
            yield start, np.asarray(points)[:, index], np.asarray(landmarks)[:, index, :2]

    ok = np.asarray(valid, dtype=bool)
    T = len(ok)
    frames = np.arange(T) if frames is None else np.asarray(frames)
    P = len(model.names)
    fit = fit_video_camera_runs(mesh_runs, pose, ok, width, height, frames=frames,
                                register=np.arange(P, len(mesh_names)))  # the head on the static points
    parameters = np.full((T, model.parameter_count), np.nan)
    for start, points, _ in mesh_runs():
        at = np.flatnonzero(ok[start:start + len(points)])
        if len(at):
            parameters[start + at] = model.fit_points(points[at, :P] - model.neutral)
    keys = choose_key_frames(model, parameters, frames)
    key_parameters = parameters[keys]
    key_points = posture_points(model, key_parameters)
    triangles = synthesis_triangles(model)
    rest_points = np.concatenate([model.rest, model.static_points])
    uv = texture_uv(rest_points, triangles)
    face, bary = texel_map(uv, triangles, size)
    scale = np.array([width, height], dtype=np.float64)
    images = read_frames([int(t) for t in keys])
    textures = np.stack([
        key_texture(image, project(fit.camera, moved(k, fit.rigid[t])) * scale - 0.5, triangles, face, bary)
        for image, t, k in zip(images, keys, key_points, strict=True)])
    outer, inner = lip_indices(mesh_names, everything)
    lips, skin = lip_and_skin(lip_mask_uv(uv, outer, inner, size))
    skin &= face >= 0
    colour = ColourModel.fit(textures[:, lips].reshape(-1, 3), textures[:, skin].reshape(-1, 3))
    lip_textures = np.stack([colour.probability(t) for t in textures])
    appearance = Appearance(uv, key_parameters, key_points, textures, lip_textures, influence_of(key_points), colour,
                            fit.camera, triangles=triangles, key_frames=keys, key_rigid=fit.rigid[keys],
                            frame_size=(width, height), lip_outer=outer, lip_inner=inner, key_names=KEY_NAMES)
    return appearance, fit
