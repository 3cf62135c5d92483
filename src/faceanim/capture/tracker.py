"""Face tracking with MediaPipe's Face Landmarker (478 points, 52 blendshape scores), offline.

The model bundle (``face_landmarker.task``, Apache-2.0, 3.8 MB) ships inside the package
(:data:`DEFAULT_MODEL`, with its licence and source in the same folder), so nothing is downloaded;
another bundle may be given as ``model``.
"""

from __future__ import annotations

import contextlib
import os
import sys
import threading
from dataclasses import dataclass
from pathlib import Path

import numpy as np

__all__ = ["FaceTracker", "TaskTracker", "TrackerOptions", "START_FACES", "DEFAULT_MODEL", "open_tracker"]

START_FACES = ("largest", "left", "right")
DEFAULT_MODEL = Path(__file__).resolve().parent / "models" / "face_landmarker.task"
"""MediaPipe's Face Landmarker bundle shipped with faceanim (see ``models/SOURCE`` beside it)."""


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


class _NativeStderr:
    """MediaPipe's C++ side (TFLite, absl) prints set-up notices straight to file descriptor 2, which
    no Python setting reaches; they come when a graph is built and on its first frame. :meth:`silenced`
    points the descriptor at /dev/null for just those moments.

    Shared by threads: ``animate`` builds the placement's graph while the video's is running in
    another thread. Each saving and restoring the descriptor on its own, the second saved the first's
    /dev/null and put it back last, and every error and the final "interrupted" went nowhere. So the
    first to enter redirects, the last to leave restores."""

    def __init__(self):
        self._lock = threading.Lock()
        self._inside = 0
        self._saved: int | None = None

    @contextlib.contextmanager
    def silenced(self):
        with self._lock:
            if self._inside == 0:
                self._saved = self._redirected()
            self._inside += 1
        try:
            yield
        finally:
            with self._lock:
                self._inside -= 1
                if self._inside == 0 and self._saved is not None:
                    os.dup2(self._saved, 2)
                    os.close(self._saved)
                    self._saved = None

    @staticmethod
    def _redirected() -> int | None:
        """Descriptor 2 pointed at /dev/null; its old target kept as a new descriptor (None where there
        is no real descriptor, an embedding host: nothing is silenced)."""
        try:
            sys.stderr.flush()
            saved = os.dup(2)
        except (OSError, ValueError):
            return None
        devnull = os.open(os.devnull, os.O_WRONLY)
        try:
            os.dup2(devnull, 2)
        finally:
            os.close(devnull)
        return saved


_native_stderr = _NativeStderr()


class FaceTracker:
    """Follows one face through a sequence of RGB frames with MediaPipe's Face Landmarker; a context
    manager.

    ``tracker(rgb, time)`` returns the followed face's ``(478, 3)`` normalised landmarks (x, y in
    [0, 1] of width and height from the top left, z in width units, smaller nearer), or None when no
    face is found in the frame; ``time`` (seconds) must grow from frame to frame unless the options
    say ``static``. After each call ``tracker.blendshapes`` holds that face's 52 blendshape scores
    ``(52,) float64`` in [0, 1] (None without a face), named by ``tracker.blendshape_names``
    (MediaPipe's: ``_neutral`` then the 51 ARKit names it scores, ``tongueOut`` not among them), and
    ``tracker.matrix`` its ``(4, 4)`` facial transformation matrix (MediaPipe's canonical face, cm,
    into the camera's frame). ``tracker.all_faces(rgb, time)`` returns every face found.

    ``model``: a ``face_landmarker.task`` bundle; :data:`DEFAULT_MODEL` (shipped with faceanim)
    when None.

    Raises
    ------
    InputError
        ``model`` is not a file, or not a face landmarker bundle MediaPipe can load.
    """

    def __init__(self, options: TrackerOptions | None = None, *, model=None):
        from ..errors import InputError

        os.environ.setdefault("GLOG_minloglevel", "2")  # keep MediaPipe's start-up chatter off the terminal
        self.options = options or TrackerOptions()
        self.model = Path(DEFAULT_MODEL if model is None else model)
        if not self.model.is_file():
            raise InputError(f"{self.model}: no such model file" + (
                " (faceanim's own: reinstall faceanim)" if model is None else ""))
        try:
            import mediapipe
            from mediapipe.tasks.python import BaseOptions, vision
        except ImportError:
            raise ImportError("face tracking needs MediaPipe: pip install 'faceanim[capture]'") from None
        self._vision, self._base = vision, BaseOptions
        self._image, self._format = mediapipe.Image, mediapipe.ImageFormat.SRGB
        self._mesh = None
        self._previous = None
        self._last_ms = -1
        self._shapes, self._matrices = [], []
        self.blendshapes = self.matrix = None
        self.blendshape_names: tuple[str, ...] = ()
        self._landmarker(1, static=True).close()  # a bad bundle is refused now, not at the first frame

    def _landmarker(self, faces: int, *, static: bool):
        vision = self._vision
        mode = vision.RunningMode.IMAGE if static else vision.RunningMode.VIDEO
        o = self.options
        settings = vision.FaceLandmarkerOptions(
            base_options=self._base(model_asset_path=str(self.model)), running_mode=mode, num_faces=faces,
            output_face_blendshapes=True, output_facial_transformation_matrixes=True,
            min_face_detection_confidence=o.min_detection_confidence,
            min_tracking_confidence=o.min_tracking_confidence)
        from ..errors import InputError

        try:
            with _native_stderr.silenced():
                return vision.FaceLandmarker.create_from_options(settings)
        except (RuntimeError, ValueError) as exc:
            raise InputError(f"{self.model}: not a MediaPipe face landmarker model ({exc})") from None

    def _start(self, image):
        """Open the landmarker for this sequence. In video mode MediaPipe runs its face detector on
        every frame while it follows fewer faces than it may, which costs a third of its speed; so the
        first frame's faces are counted and a sequence that starts with one face is followed as one."""
        o = self.options
        if o.static or o.max_faces == 1:
            self._mesh = self._landmarker(o.max_faces, static=o.static)
            return
        with self._landmarker(o.max_faces, static=True) as probe:
            found = len(probe.detect(image).face_landmarks)
        self._mesh = self._landmarker(1 if found <= 1 else o.max_faces, static=False)

    def all_faces(self, rgb: np.ndarray, time: float | None = None) -> list[np.ndarray]:
        image = self._image(image_format=self._format, data=np.ascontiguousarray(rgb))
        if self._mesh is None:
            self._start(image)
            with _native_stderr.silenced():  # the first frame brings TFLite's notices
                result = self._detect(image, time)
        else:
            result = self._detect(image, time)
        self._shapes = result.face_blendshapes or []
        self._matrices = result.facial_transformation_matrixes or []
        return [np.array([(p.x, p.y, p.z) for p in face], dtype=np.float64) for face in result.face_landmarks]

    def _detect(self, image, time: float | None):
        if self.options.static:
            return self._mesh.detect(image)
        ms = max(self._last_ms + 1, int(round(1000 * (time or 0.0))))  # strictly increasing, as VIDEO mode needs
        self._last_ms = ms
        return self._mesh.detect_for_video(image, ms)

    def __call__(self, rgb: np.ndarray, time: float | None = None) -> np.ndarray | None:
        faces = self.all_faces(rgb, time)
        self.blendshapes = self.matrix = None
        if not faces:
            return None
        index = self._follow(faces)
        if index < len(self._shapes):
            shapes = self._shapes[index]
            self.blendshape_names = self.blendshape_names or tuple(c.category_name for c in shapes)
            self.blendshapes = np.array([c.score for c in shapes], dtype=np.float64)
        if index < len(self._matrices):
            self.matrix = np.array(self._matrices[index], dtype=np.float64).reshape(4, 4)
        return faces[index]

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
    """:class:`FaceTracker` with the model bundle given first: ``TaskTracker(model, options)`` (the
    name the Tasks tracker had when FaceMesh was the default)."""

    def __init__(self, model=None, options: TrackerOptions | None = None):
        super().__init__(options, model=model)


def open_tracker(options: TrackerOptions | None = None, model=None) -> FaceTracker:
    """The Face Landmarker tracker, from ``model`` (a ``face_landmarker.task`` file) or faceanim's own
    bundle (:data:`DEFAULT_MODEL`) when None."""
    return FaceTracker(options, model=model)
