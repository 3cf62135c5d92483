"""Face tracking with MediaPipe's face mesh (478 points with iris refinement), offline.

``mediapipe==0.10.21`` ships the FaceMesh models inside its wheel, so nothing is downloaded.
"""

from __future__ import annotations

import contextlib
import os
import sys
from dataclasses import dataclass

import numpy as np

__all__ = ["FaceTracker", "TaskTracker", "TrackerOptions", "START_FACES", "open_tracker"]

START_FACES = ("largest", "left", "right")


@dataclass(frozen=True)
class TrackerOptions:
    """How faces are found and which one is followed.

    ``max_faces``: faces looked for per frame. ``start_face``: which face to follow first
    (``largest``, or the one furthest ``left``/``right`` in the image); later frames follow the face
    nearest the previous one. ``static``: treat frames as unrelated photos (detect every frame).
    """

    max_faces: int = 4
    start_face: str = "largest"
    static: bool = False
    min_detection_confidence: float = 0.5
    min_tracking_confidence: float = 0.5

    def __post_init__(self):
        if self.start_face not in START_FACES:
            raise ValueError(f"start_face must be one of {', '.join(START_FACES)}, got {self.start_face!r}")
        if self.max_faces < 1:
            raise ValueError(f"max_faces must be at least 1, got {self.max_faces}")


@contextlib.contextmanager
def _native_stderr_silenced():
    """MediaPipe's C++ side (TFLite, absl) prints set-up notices straight to file descriptor 2, which
    no Python setting reaches; they come when a graph is built and on its first frame. Point the
    descriptor at /dev/null for just those moments."""
    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, ValueError):  # no real descriptor (an embedding host): nothing to silence
        yield
        return
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, 2)
        yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)
        os.close(devnull)


class FaceTracker:
    """Follows one face through a sequence of RGB frames; a context manager.

    ``tracker(rgb)`` returns the followed face's ``(478, 3)`` normalised landmarks (x, y in [0, 1]
    of width and height from the top left, z in width units, smaller nearer), or None when no face is
    found in the frame. ``tracker.all_faces(rgb)`` returns every face found.
    """

    def __init__(self, options: TrackerOptions | None = None):
        os.environ.setdefault("GLOG_minloglevel", "2")  # keep MediaPipe's start-up chatter off the terminal
        try:
            from mediapipe.python.solutions import face_mesh
        except ImportError:
            raise ImportError("face tracking needs MediaPipe: pip install 'faceanim[capture]'") from None
        self.options = options or TrackerOptions()
        self._face_mesh = face_mesh
        self._mesh = None
        self._previous = None

    def _open(self, faces: int):
        o = self.options
        with _native_stderr_silenced():
            return self._face_mesh.FaceMesh(
                static_image_mode=o.static, max_num_faces=faces, refine_landmarks=True,
                min_detection_confidence=o.min_detection_confidence,
                min_tracking_confidence=o.min_tracking_confidence)

    def _start(self, rgb: np.ndarray):
        """Open the mesh for this sequence. MediaPipe looks for new faces in every frame while it
        tracks fewer than its maximum, which costs a third of its speed; so the first frame is counted
        and a sequence that starts with one face is tracked as one face."""
        if self.options.static or self.options.max_faces == 1:
            self._mesh = self._open(self.options.max_faces)
            return
        with _native_stderr_silenced(), self._face_mesh.FaceMesh(
                static_image_mode=True, max_num_faces=self.options.max_faces, refine_landmarks=False,
                min_detection_confidence=self.options.min_detection_confidence) as probe:
            found = probe.process(np.ascontiguousarray(rgb)).multi_face_landmarks or ()
        self._mesh = self._open(1 if len(found) <= 1 else self.options.max_faces)

    def all_faces(self, rgb: np.ndarray) -> list[np.ndarray]:
        if self._mesh is None:
            self._start(rgb)
            with _native_stderr_silenced():
                result = self._mesh.process(np.ascontiguousarray(rgb))
        else:
            result = self._mesh.process(np.ascontiguousarray(rgb))
        faces = []
        for face in result.multi_face_landmarks or ():
            faces.append(np.array([(p.x, p.y, p.z) for p in face.landmark], dtype=np.float64))
        return faces

    blendshapes = None  # FaceMesh gives none; see TaskTracker

    def __call__(self, rgb: np.ndarray, time: float | None = None) -> np.ndarray | None:
        faces = self.all_faces(rgb)
        return faces[self._follow(faces)] if faces else None

    def _follow(self, faces) -> int:
        """Index of the face to follow: the chosen one at the start, then the nearest to the last."""
        if self._previous is None:
            if self.options.start_face == "largest":
                index = int(np.argmax([np.prod(np.ptp(f[:, :2], axis=0)) for f in faces]))
            else:
                x = [f[:, 0].mean() for f in faces]
                index = int(np.argmin(x) if self.options.start_face == "left" else np.argmax(x))
        else:
            centre = self._previous[:, :2].mean(axis=0)
            index = int(np.argmin([np.linalg.norm(f[:, :2].mean(axis=0) - centre) for f in faces]))
        self._previous = faces[index]
        return index

    def close(self):
        if self._mesh is not None:
            self._mesh.close()
            self._mesh = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


class TaskTracker(FaceTracker):
    """MediaPipe's Tasks face landmarker, from a ``face_landmarker.task`` bundle the user gives:
    the same 478 points plus 52 blendshape scores per frame (``self.blendshapes`` after each call,
    names in ``self.blendshape_names``)."""

    def __init__(self, model, options: TrackerOptions | None = None):
        from pathlib import Path

        from ..errors import InputError

        self.options = options or TrackerOptions()
        self._previous = None
        self.blendshapes = None
        self.blendshape_names = ()
        model = Path(model)
        if not model.is_file():
            raise InputError(f"{model}: no such model file")
        try:
            from mediapipe.tasks.python import BaseOptions, vision
        except ImportError:
            raise ImportError("face tracking needs MediaPipe: pip install 'faceanim[capture]'") from None
        mode = vision.RunningMode.IMAGE if self.options.static else vision.RunningMode.VIDEO
        settings = vision.FaceLandmarkerOptions(
            base_options=BaseOptions(model_asset_path=str(model)), running_mode=mode,
            num_faces=self.options.max_faces, output_face_blendshapes=True,
            min_face_detection_confidence=self.options.min_detection_confidence,
            min_tracking_confidence=self.options.min_tracking_confidence)
        try:
            with _native_stderr_silenced():
                self._mesh = vision.FaceLandmarker.create_from_options(settings)
        except (RuntimeError, ValueError) as exc:
            raise InputError(f"{model}: not a MediaPipe face landmarker model ({exc})") from None
        self._image = __import__("mediapipe").Image
        self._format = __import__("mediapipe").ImageFormat.SRGB
        self._last_ms = -1

    def _detect(self, rgb: np.ndarray, time: float | None):
        image = self._image(image_format=self._format, data=np.ascontiguousarray(rgb))
        if self.options.static:
            return self._mesh.detect(image)
        ms = max(self._last_ms + 1, int(round(1000 * (time or 0.0))))  # strictly increasing, as VIDEO mode needs
        self._last_ms = ms
        return self._mesh.detect_for_video(image, ms)

    def all_faces(self, rgb: np.ndarray, time: float | None = None) -> list[np.ndarray]:
        result = self._detect(rgb, time)
        self._shapes = result.face_blendshapes or []
        return [np.array([(p.x, p.y, p.z) for p in face], dtype=np.float64) for face in result.face_landmarks]

    def __call__(self, rgb: np.ndarray, time: float | None = None) -> np.ndarray | None:
        faces = self.all_faces(rgb, time)
        if not faces:
            self.blendshapes = None
            return None
        index = self._follow(faces)
        if index < len(self._shapes):
            shapes = self._shapes[index]
            self.blendshape_names = tuple(c.category_name for c in shapes)
            self.blendshapes = np.array([c.score for c in shapes], dtype=np.float64)
        return faces[index]


def open_tracker(options: TrackerOptions | None = None, model=None) -> FaceTracker:
    """The FaceMesh tracker, or the Tasks tracker when a ``face_landmarker.task`` model is given."""
    return FaceTracker(options) if model is None else TaskTracker(model, options)
