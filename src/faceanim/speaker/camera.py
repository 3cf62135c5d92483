"""The clone's camera and the head's rigid motion, kept apart as the ICP clone keeps them.

A video is seen through one 3x4 projection matrix ``P`` (fitted once per video) that takes a point
``X`` of the camera space to normalised screen coordinates, ``[u w, v w, w] = P [X, 1]``, with ``u``
across the image from the left and ``v`` down from the top, both in [0, 1] over the frame (the
tracker's normalised landmark coordinates). The head moves by a separate rotation and translation per
frame, ``X = R p + t`` for a point ``p`` of the head frame (cm, MPEG-4 axes), so that an optimiser
moving the head has six uncoupled parameters (a rotation vector and a translation, :func:`to_rigid`)
and never touches the camera.

:func:`fit_video_camera` fits ``P`` to a capture: the head-frame points of each frame, moved by that
frame's rigid motion (the capture's pose without its scale), against the tracked image landmarks, by
the normalised direct linear transform refined on the reprojection error.

>>> import numpy as np
>>> P = np.array([[2.0, 0, 0.5, 0], [0, -2, 0.5, 0], [0, 0, 1, 0]])
>>> rng = np.random.default_rng(0)
>>> X = rng.normal(size=(50, 3)) + [0, 0, 10]
>>> np.allclose(fit_camera(X, project(P, X)), P / np.linalg.norm(P))
True
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from ..errors import FileFormatError, InputError
from ..validation import as_array

__all__ = ["fit_camera", "project", "project_posed", "to_rigid", "from_rigid", "rigid_of_pose", "pose_matrix",
           "rigid_transform", "register_rigid", "fit_video_camera", "fit_video_camera_runs", "CameraFit", "read_camera",
           "write_camera"]


def project(camera, points) -> np.ndarray:
    """``(..., 2)`` normalised screen coordinates of camera-space ``points (..., 3)`` through ``camera (3, 4)``."""
    P = as_array(camera, "camera", shape=(3, 4))
    X = np.asarray(points, dtype=np.float64)
    h = X @ P[:, :3].T + P[:, 3]
    return h[..., :2] / h[..., 2:3]


def _normaliser(points: np.ndarray) -> np.ndarray:
    """The similarity (as a matrix) that centres ``points (M, D)`` and scales their mean distance to sqrt(D)."""
    centre = points.mean(axis=0)
    spread = np.sqrt(((points - centre) ** 2).sum(axis=1)).mean()
    scale = np.sqrt(points.shape[1]) / max(spread, 1e-12)
    T = np.eye(points.shape[1] + 1)
    T[:-1, :-1] *= scale
    T[:-1, -1] = -scale * centre
    return T


def fit_camera(points, image, *, refine: bool = True) -> np.ndarray:
    """The 3x4 projection taking camera-space ``points (M, 3)`` to ``image (M, 2)`` normalised screen
    coordinates: the normalised DLT (Hartley), then, with ``refine``, Levenberg-Marquardt on the
    reprojection error. Scaled to unit Frobenius norm with ``P[2, :3]`` pointing along +w in front.

    Raises
    ------
    ValueError
        Fewer than 6 points, or points that do not determine a camera (all on one plane or line).
    """
    X = as_array(points, "points", shape=("M", 3))
    x = as_array(image, "image", shape=(len(X), 2))
    if len(X) < 6:
        raise ValueError(f"a camera needs at least 6 points, got {len(X)}")
    TX, Tx = _normaliser(X), _normaliser(x)
    Xn = np.c_[X, np.ones(len(X))] @ TX.T
    xn = np.c_[x, np.ones(len(x))] @ Tx.T
    A = np.zeros((2 * len(X), 12))
    A[0::2, 0:4] = Xn
    A[0::2, 8:12] = -xn[:, 0:1] * Xn
    A[1::2, 4:8] = Xn
    A[1::2, 8:12] = -xn[:, 1:2] * Xn
    _, S, Vt = np.linalg.svd(A, full_matrices=False)
    if S[-2] <= 1e-9 * S[0]:
        raise ValueError("the points do not determine a camera (they lie on a plane or a line)")
    P = np.linalg.inv(Tx) @ Vt[-1].reshape(3, 4) @ TX
    if refine:
        def residual(p):
            return (project(p.reshape(3, 4), X) - x).reshape(-1)

        P = least_squares(residual, P.reshape(-1) / np.linalg.norm(P), method="lm", x_scale="jac").x.reshape(3, 4)
    P = P / np.linalg.norm(P)
    if np.median(np.c_[X, np.ones(len(X))] @ P[2]) < 0:  # the points lie in front: positive w
        P = -P
    return P


def to_rigid(rotation, translation) -> np.ndarray:
    """``(..., 6)``: rotation vectors (radians) then translations (cm) of ``rotation (..., 3, 3)`` and
    ``translation (..., 3)``; the optimiser's six uncoupled parameters."""
    R = np.asarray(rotation, dtype=np.float64)
    vectors = Rotation.from_matrix(np.array(R.reshape(-1, 3, 3))).as_rotvec().reshape(*R.shape[:-2], 3)
    return np.concatenate([vectors, np.asarray(translation, dtype=np.float64)], axis=-1)


def from_rigid(rigid) -> tuple[np.ndarray, np.ndarray]:
    """``(rotation (..., 3, 3), translation (..., 3))`` of ``rigid (..., 6)`` (:func:`to_rigid`)."""
    r = np.asarray(rigid, dtype=np.float64)
    if r.shape[-1:] != (6,):
        raise ValueError(f"rigid must have shape (..., 6), got {r.shape}")
    R = Rotation.from_rotvec(np.array(r.reshape(-1, 6)[:, :3])).as_matrix().reshape(*r.shape[:-1], 3, 3)
    return R, r[..., 3:].copy()


def rigid_of_pose(pose) -> np.ndarray:
    """``(T, 6)`` rigid motion of capture poses ``(T, 4, 4)`` (head frame to camera space): the rotation
    of each pose's linear part (its polar factor) and its translation divided by the pose's scale.
    The tracker's camera sits at the origin of camera space, so a scaled head and the unscaled one
    moved that much nearer project to the same image."""
    T = as_array(pose, "pose", shape=("T", 4, 4))
    U, S, Vt = np.linalg.svd(T[:, :3, :3])
    R = U @ Vt
    scale = S.mean(axis=1)
    return to_rigid(R, T[:, :3, 3] / scale[:, None])


def project_posed(camera, pose, points) -> np.ndarray:
    """``(N, 2)`` normalised screen coordinates of head-frame ``points (N, 3)`` moved by the rigid motion
    ``pose (4, 4)`` into camera space and seen by ``camera (3, 4)``: :func:`project` without its checks,
    as the analysis calls it for every evaluation."""
    posed = points @ pose[:3, :3].T + pose[:3, 3]
    h = posed @ camera[:, :3].T + camera[:, 3]
    return h[:, :2] / h[:, 2:3]


def pose_matrix(rigid) -> np.ndarray:
    """``(4, 4)`` or ``(T, 4, 4)``: the rigid motion ``rigid (6,)`` or ``(T, 6)`` (:func:`to_rigid`:
    a rotation vector in radians, a translation in cm) as a matrix."""
    R, t = from_rigid(rigid)
    M = np.zeros((*R.shape[:-2], 4, 4))
    M[..., :3, :3], M[..., :3, 3], M[..., 3, 3] = R, t, 1.0
    return M


def rigid_transform(correction, centre) -> np.ndarray:
    """(4, 4) the rigid correction ``(rx, ry, rz, tx, ty, tz)`` (a rotation vector in degrees about
    ``centre (3,)``, then a translation in cm), in the head frame."""
    c = np.asarray(correction, dtype=np.float64)
    R = Rotation.from_rotvec(np.radians(c[:3])).as_matrix()
    M = np.eye(4)
    M[:3, :3] = R
    M[:3, 3] = centre - R @ centre + c[3:]
    return M


def moved(points, rigid) -> np.ndarray:
    """Head-frame ``points (..., N, 3)`` moved by ``rigid (..., 6)`` into camera space."""
    R, t = from_rigid(rigid)
    return np.einsum("...ij,...nj->...ni", R, np.asarray(points, dtype=np.float64)) + t[..., None, :]


def register_rigid(camera, points, landmarks, rigid) -> np.ndarray:
    """``(T, 6)``: each frame's rigid motion refitted so that ``camera`` projects its head-frame
    ``points (T, M, 3)`` onto its tracked ``landmarks (T, M, 2)`` (least squares on the reprojection,
    from ``rigid (T, 6)``, the capture's pose); frames with a NaN start or fewer than 6 finite points
    keep their start.

    The capture's pose is filtered apart from its head-frame points (its rotation more strongly), so
    pose and points together miss the image: on speech_woman the lips' landmarks reprojected through
    the video's camera sat 2.6 pixels off the tracked ones on a median frame, 12.5 on the worst (a
    mouth 74 pixels wide), and the clone's textures and analysis inherited it. Registered on the
    model's static points (the face less what speech moves) the lips sit 1.2 pixels off (4.0 worst).
    """
    P = as_array(camera, "camera", shape=(3, 4))
    X = np.asarray(points, dtype=np.float64)
    x = np.asarray(landmarks, dtype=np.float64)[..., :2]
    out = np.array(rigid, dtype=np.float64, copy=True)
    for t in range(len(out)):
        ok = np.isfinite(X[t]).all(axis=-1) & np.isfinite(x[t]).all(axis=-1)
        if ok.sum() < 6 or not np.isfinite(out[t]).all():
            continue
        Xt, xt = X[t, ok], x[t, ok]

        def residual(r, Xt=Xt, xt=xt):
            return (project(P, moved(Xt, r)) - xt).reshape(-1)

        out[t] = least_squares(residual, out[t], method="lm", x_scale=np.r_[0.05, 0.05, 0.05, 0.5, 0.5, 0.5]).x
    return out


@dataclass(frozen=True, eq=False)
class CameraFit:
    """A video's camera (3, 4), the rigid motion of each frame (T, 6), NaN where the frame had no face,
    and the reprojection error of the landmarks used, in pixels: median and worst over frames of each
    frame's median, and the worst single point."""

    camera: np.ndarray
    rigid: np.ndarray
    median_px: float
    worst_frame_px: float
    worst_point_px: float


def fit_video_camera(points, landmarks, pose, valid, width: int, height: int, *, frames=None,
                     max_points: int = 20000) -> CameraFit:
    """Fit one camera to a video's capture.

    Parameters
    ----------
    points : (T, L, 3) float64
        Head-frame points per frame (cm), NaN on frames without a face.
    landmarks : (T, L, 2) float64
        The tracked landmarks, normalised image coordinates.
    pose : (T, 4, 4) float64
        The capture's head pose (head frame to camera space).
    valid : (T,) bool
    width, height : int
        The frame's size in pixels, for the error.
    frames : indices, optional
        The frames to fit on (default: every valid frame); the error is measured over the same.
    max_points : int
        The fit takes an even spread of at most this many (frame, point) pairs.
    """
    points = as_array(points, "points", shape=("T", "L", 3), finite=False)
    T, L, _ = points.shape
    landmarks = as_array(landmarks, "landmarks", shape=(T, L, 2), finite=False)
    return fit_video_camera_runs(lambda: iter([(0, points, landmarks)]), pose, valid, width, height, frames=frames,
                                 max_points=max_points)


def fit_video_camera_runs(runs, pose, valid, width: int, height: int, *, frames=None, max_points: int = 20000,
                          register=None) -> CameraFit:
    """:func:`fit_video_camera` over a capture read in runs of frames, holding one run at a time (what
    ``faceanim speaker textures`` does with a streamed capture); the same answer.

    ``runs()`` gives an iterator of ``(start, points (n, L, 3), landmarks (n, L, 2))`` over the video's
    frames in order; it is called three times (count the pairs, gather the fit's even spread of them,
    measure the error; a fourth with ``register``).

    ``register``: indices of the points (into ``L``) to register each frame's rigid motion on once the
    camera is fitted (:func:`register_rigid`); the error is then measured with the registered motion.
    None: the capture's pose as it is (:func:`fit_video_camera`)."""
    pose = np.asarray(pose, dtype=np.float64)
    valid = np.asarray(valid, dtype=bool)
    T = len(valid)
    rigid = np.full((T, 6), np.nan)
    rigid[valid] = rigid_of_pose(pose[valid])
    chosen = np.flatnonzero(valid) if frames is None else np.intersect1d(np.asarray(frames), np.flatnonzero(valid))
    if len(chosen) == 0:
        raise InputError("no frame with a face to fit the camera on")
    wanted = np.zeros(T, dtype=bool)
    wanted[chosen] = True

    def pairs():
        """Per run: the chosen frames, their camera-space points, landmarks and which pairs are finite."""
        for start, points, landmarks in runs():
            at = np.flatnonzero(wanted[start:start + len(points)])
            if len(at) == 0:
                continue
            X = moved(np.asarray(points, dtype=np.float64)[at], rigid[start + at])
            x = np.asarray(landmarks, dtype=np.float64)[at, :, :2]
            yield start + at, X, x, np.isfinite(X).all(axis=-1) & np.isfinite(x).all(axis=-1)

    count = sum(int(ok.sum()) for _, _, _, ok in pairs())
    step = max(1, count // max_points)
    kept_X, kept_x, seen = [], [], 0
    for _, X, x, ok in pairs():  # every step-th finite pair, in (frame, point) order
        n = int(ok.sum())
        take = (seen + np.arange(n)) % step == 0
        kept_X.append(X[ok][take])
        kept_x.append(x[ok][take])
        seen += n
    P = fit_camera(np.concatenate(kept_X), np.concatenate(kept_x))
    if register is not None:  # every frame's rigid motion refitted to its landmarks through the camera
        register = np.asarray(register, dtype=np.int64)
        for start, points, landmarks in runs():
            at = np.flatnonzero(valid[start:start + len(points)])
            if len(at):
                rigid[start + at] = register_rigid(P, np.asarray(points)[at][:, register],
                                                   np.asarray(landmarks)[at][:, register], rigid[start + at])
    scale = np.array([width, height], dtype=np.float64)
    per_frame, worst = [], np.nan
    for _, X, x, ok in pairs():
        error = np.linalg.norm((project(P, X) - x) * scale, axis=-1)
        error[~ok] = np.nan
        some = ok.any(axis=1)  # a frame with no finite point has no error to report
        if some.any():
            per_frame.append(np.nanmedian(error[some], axis=1))
            worst = np.nanmax([worst, np.nanmax(error)])
    per_frame = np.concatenate(per_frame)
    return CameraFit(P, rigid, float(np.median(per_frame)), float(per_frame.max()), float(worst))


def read_camera(path) -> np.ndarray:
    """A 3x4 camera from a text file (3 lines of 4 numbers, as :func:`write_camera` writes).

    Raises
    ------
    InputError
        The file is missing.
    FileFormatError
        It does not hold 3 rows of 4 finite numbers (the message says what it holds).
    """
    from pathlib import Path

    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: no such file")
    try:
        rows = [line.replace(",", " ").split() for line in path.read_text(encoding="utf-8").splitlines()]
        rows = [[float(v) for v in row] for row in rows if row and not row[0].startswith("#")]
    except (ValueError, UnicodeDecodeError):
        raise FileFormatError(path, "a camera must be 3 lines of 4 numbers") from None
    if len(rows) != 3 or any(len(r) != 4 for r in rows):
        shape = f"{len(rows)} lines of {sorted({len(r) for r in rows})} numbers" if rows else "no numbers"
        raise FileFormatError(path, f"a camera must be 3 lines of 4 numbers (a 3x4 matrix), got {shape}")
    P = np.array(rows)
    if not np.isfinite(P).all() or np.linalg.matrix_rank(P) < 3:
        raise FileFormatError(path, "a camera must be a finite 3x4 matrix of rank 3")
    return P


def write_camera(path, camera) -> None:
    """Write ``camera (3, 4)`` as 3 lines of 4 numbers, complete or not at all."""
    from ..atomic import atomic_output

    P = as_array(camera, "camera", shape=(3, 4))
    with atomic_output(path) as tmp:
        np.savetxt(tmp, P, fmt="%.10g", header="3x4 projection: camera space (cm) -> normalised screen (u right, "
                                                "v down, [0, 1])")
