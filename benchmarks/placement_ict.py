"""Automatic control-point placement on the ICT-FaceKit neutral, against ICT's own 68 landmarks.

    python benchmarks/placement_ict.py

The untextured ICT head is rendered (lit from above), MediaPipe's Face Landmarker runs on the render, its
points are cast back onto the surface (``faceanim.retarget.placement``) and mapped to the 68-point
layout; the table gives the distance (cm) of each group from ICT's landmark vertices.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from ict_scenario import ict_missing, load_ict  # noqa: E402
from report import publish  # noqa: E402

from faceanim.landmarks import IBUG68_LANDMARK  # noqa: E402
from faceanim.retarget.placement import place_landmarks  # noqa: E402

GROUPS = {"jaw": (0, 17), "brows": (17, 27), "nose": (27, 36), "eyes": (36, 48), "lips": (48, 68)}


def main() -> int:
    if ict_missing():
        return 0
    model = load_ict()
    mesh = model.mesh(model.neutral)
    start = time.perf_counter()
    ids = place_landmarks(mesh)
    seconds = time.perf_counter() - start
    placed = model.neutral[ids[list(IBUG68_LANDMARK)]]
    truth = model.neutral[model.landmarks]
    d = np.linalg.norm(placed - truth, axis=1)
    face_width = np.linalg.norm(truth[0] - truth[16])
    lines = ["# Automatic placement on the ICT-FaceKit neutral", "",
             f"`python benchmarks/placement_ict.py`: {seconds:.1f} s. Distances (cm) from the placed 68-layout "
             f"points to ICT's 68 landmark vertices; face width (jaw 0-16) {face_width:.1f} cm.", "",
             f"**Median {np.median(d):.2f} cm ({np.median(d) / face_width:.1%} of face width), "
             f"mean {d.mean():.2f} cm.**",
             "", "| group | median cm | max cm |", "|---|---|---|"]
    for name, (a, b) in GROUPS.items():
        lines.append(f"| {name} | {np.median(d[a:b]):.2f} | {d[a:b].max():.2f} |")
    publish("placement_ict.md", lines)
    return 0


if __name__ == "__main__":
    sys.exit(main())
