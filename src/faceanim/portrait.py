"""Portraits and the avatars made from them: the embedded portrait, the tracker's landmarks on a photo,
and a ready :class:`~faceanim.target.Target` built from both (composed from ``capture`` and
``retarget``, like the jobs in :mod:`faceanim.pipeline`)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .errors import InputError

__all__ = ["portrait", "portrait_landmarks", "avatar_target"]


def portrait(photo=None) -> tuple[np.ndarray, str]:
    """An RGB portrait and its name: the image file ``photo`` (the first frame of a video), or, with
    None, the public-domain astronaut portrait (Eileen Collins, NASA) that scikit-image ships."""
    if photo is None:
        try:
            from skimage import data
        except ImportError:
            raise ImportError("the embedded portrait comes with scikit-image: pip install 'faceanim[capture]'") \
                from None
        return data.astronaut(), "astronaut"
    from .capture.video import open_frames

    with open_frames(photo) as frames:
        for _, frame in frames:
            return frame, Path(photo).stem
    raise InputError(f"{photo}: holds no frames")


def portrait_landmarks(image: np.ndarray, name: str) -> np.ndarray:
    """The tracker's ``(478, 3)`` landmarks of the (largest) face in a portrait."""
    from .capture.tracker import FaceTracker, TrackerOptions

    with FaceTracker(TrackerOptions(static=True)) as tracker:
        landmarks = tracker(image)
    if landmarks is None:
        raise InputError(f"{name}: the face tracker finds no face in it")
    return landmarks


def avatar_target(photo=None, *, image=None, landmarks=None, subdivisions: int = 2):
    """A Target made from a portrait (see :func:`portrait`): the tracker's face mesh, textured from it.
    ``image`` (and its ``landmarks``, when already tracked) stand in for a file."""
    from .capture.avatar import avatar_points, face_from_landmarks
    from .target import Target

    image, name = (image, "image") if image is not None else portrait(photo)
    if landmarks is None:
        landmarks = portrait_landmarks(image, str(photo) if photo is not None else name)
    mesh = face_from_landmarks(landmarks, image, subdivisions=subdivisions)
    return Target.from_points(mesh, avatar_points(mesh), source=name)
