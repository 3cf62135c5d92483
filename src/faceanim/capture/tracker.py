"""Face tracking with MediaPipe's face mesh (478 points with iris refinement), offline.

``mediapipe==0.10.21`` ships the FaceMesh models inside its wheel, so nothing is downloaded.
"""

from __future__ import annotations

import contextlib
import os
import sys
from dataclasses import dataclass

import numpy as np

__all__ = ["FaceTracker", "TrackerOptions", "START_FACES"]

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

    def __call__(self, rgb: np.ndarray) -> np.ndarray | None:
        faces = self.all_faces(rgb)
        if not faces:
            return None
        if self._previous is None:
            face = self._pick_first(faces)
        else:
            centre = self._previous[:, :2].mean(axis=0)
            face = min(faces, key=lambda f: np.linalg.norm(f[:, :2].mean(axis=0) - centre))
        self._previous = face
        return face

    def _pick_first(self, faces):
        if self.options.start_face == "largest":
            return max(faces, key=lambda f: np.prod(np.ptp(f[:, :2], axis=0)))
        x = [f[:, 0].mean() for f in faces]
        return faces[int(np.argmin(x) if self.options.start_face == "left" else np.argmax(x))]

    def close(self):
        if self._mesh is not None:
            self._mesh.close()
            self._mesh = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
