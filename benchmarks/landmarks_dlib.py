"""MediaPipe's landmarks mapped to the 68-point iBUG layout, against dlib's points on real photos.

    python benchmarks/landmarks_dlib.py

For each face box in ``../shared/data/dlib_faces/training_with_face_landmarks.xml`` (4 PASCAL VOC
photos, 18 faces, points from dlib's 68-point model), MediaPipe's Face Landmarker runs on the box's
surroundings (faces in these photos are small: 15-48 px between the eyes), its 478 points are mapped to the 68 layout
(``faceanim.landmarks.IBUG68_LANDMARK``), and the normalised mean error is taken: mean point
distance over the distance between the outer eye corners (points 36 and 45), the usual iBUG measure.
Writes ``benchmarks/results/landmarks_dlib.md``.
"""

from __future__ import annotations

import os
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from report import publish  # noqa: E402

DLIB = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "dlib_faces"


def dlib_faces():
    """``(image path, box (left, top, width, height), points (68, 2))`` for every annotated face."""
    root = ET.parse(DLIB / "training_with_face_landmarks.xml").getroot()
    for image in root.iter("image"):
        for box in image.iter("box"):
            parts = {int(p.get("name")): (float(p.get("x")), float(p.get("y"))) for p in box.iter("part")}
            points = np.array([parts[i] for i in range(68)])
            rect = tuple(int(box.get(k)) for k in ("left", "top", "width", "height"))
            yield DLIB / image.get("file"), rect, points


def mapped_landmarks(rgb, box):
    """MediaPipe's face in a crop around ``box`` (three times its size, resized to 256 px), as 68 pixels."""
    from PIL import Image

    from faceanim.capture.tracker import FaceTracker, TrackerOptions
    from faceanim.landmarks import IBUG68_LANDMARK

    left, top, width, height = box
    cx, cy, half = left + width / 2, top + height / 2, 1.5 * max(width, height)
    x0, y0 = int(max(cx - half, 0)), int(max(cy - half, 0))
    x1, y1 = int(min(cx + half, rgb.shape[1])), int(min(cy + half, rgb.shape[0]))
    crop = Image.fromarray(rgb[y0:y1, x0:x1])
    scale = 256 / max(crop.size)
    crop = np.asarray(crop.resize((round(crop.size[0] * scale), round(crop.size[1] * scale)), Image.BICUBIC))
    with FaceTracker(TrackerOptions(static=True, max_faces=3)) as tracker:
        faces = tracker.all_faces(crop)
    if not faces:
        return None
    centre = np.array([crop.shape[1], crop.shape[0]]) / 2
    face = min(faces, key=lambda f: np.linalg.norm(f[:, :2].mean(0) * [crop.shape[1], crop.shape[0]] - centre))
    pixels = face[list(IBUG68_LANDMARK), :2] * [crop.shape[1], crop.shape[0]]
    return pixels / scale + [x0, y0]


def evaluate():
    from PIL import Image

    rows = []
    for path, box, truth in dlib_faces():
        rgb = np.asarray(Image.open(path).convert("RGB"))
        found = mapped_landmarks(rgb, box)
        interocular = np.linalg.norm(truth[36] - truth[45])
        nme = np.nan if found is None else np.linalg.norm(found - truth, axis=1).mean() / interocular
        per_group = None if found is None else {
            name: np.linalg.norm(found[a:b] - truth[a:b], axis=1).mean() / interocular
            for name, (a, b) in {"jaw": (0, 17), "brows": (17, 27), "nose": (27, 36), "eyes": (36, 48),
                                 "lips": (48, 68)}.items()}
        rows.append((path.name, box, interocular, nme, per_group))
    return rows


def main() -> int:
    if not (DLIB / "training_with_face_landmarks.xml").exists():
        print(f"skipped: needs {DLIB} (the shared data folder beside the checkout)")
        return 0
    os.environ.setdefault("GLOG_minloglevel", "2")
    rows = evaluate()
    found = [r for r in rows if np.isfinite(r[3])]
    nmes = np.array([r[3] for r in found])
    lines = ["# MediaPipe mapped to the 68-point layout, against dlib's points", "",
             f"`python benchmarks/landmarks_dlib.py`: {len(rows)} faces in 4 photos, {len(found)} found. "
             "NME: mean point distance / outer-eye-corner distance.", "",
             f"**Mean NME {nmes.mean():.3f}, median {np.median(nmes):.3f}, worst {nmes.max():.3f}.**", "",
             "| photo | box | inter-ocular px | NME | jaw | brows | nose | eyes | lips |",
             "|---|---|---|---|---|---|---|---|---|"]
    for name, box, io, nme, groups in rows:
        cells = " | ".join(f"{v:.3f}" for v in groups.values()) if groups else " | ".join(["-"] * 5)
        lines.append(f"| {name} | {box} | {io:.0f} | {nme:.3f} | {cells} |")
    publish("landmarks_dlib.md", lines)
    return 0


if __name__ == "__main__":
    sys.exit(main())
