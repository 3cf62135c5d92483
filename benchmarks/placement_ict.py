"""Automatic control-point placement on the ICT-FaceKit neutral, against ICT's own 68 landmarks.

    python benchmarks/placement_ict.py [--identities]

The untextured ICT head is rendered (lit from above), MediaPipe's Face Landmarker runs on the render, its
points are cast back onto the surface (``faceanim.retarget.placement``) and mapped to the 68-point
layout; the table gives the distance (cm) of each group from ICT's landmark vertices.

``--identities`` also places the points on the identities of ``roundtrip_ict.py``'s pairs (both faces, A and B,
drawn from each seed as ``roundtrip_ict.py --pairs`` draws them): tuning seeds 0-5 (the placement's settings
were chosen on these, and on the pairs named in ``faceanim.retarget.placement``), reporting seeds 100-111 (the
round trip's pairs). Per face: the median distance over all 68 points, over the eyes' 12, the eyes' worst, and
the lid opening (IRISD0, from the upper to the lower lid, as the FAPU measures it); or why it was refused.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from ict_scenario import ict_missing, load_ict  # noqa: E402
from report import publish  # noqa: E402

from faceanim.errors import InputError  # noqa: E402
from faceanim.landmarks import IBUG68_LANDMARK  # noqa: E402
from faceanim.retarget.placement import auto_target, place_landmarks  # noqa: E402

GROUPS = {"jaw": (0, 17), "brows": (17, 27), "nose": (27, 36), "eyes": (36, 48), "lips": (48, 68)}
TUNING_IDENTITIES = tuple(range(0, 6))
REPORTING_IDENTITIES = tuple(range(100, 112))


def identities(model) -> list[str]:
    """Rows for the faces of roundtrip_ict.py's pairs (see the module text)."""
    lines = []
    mp = list(IBUG68_LANDMARK)
    for group, seeds in (("tuning", TUNING_IDENTITIES), ("reporting", REPORTING_IDENTITIES)):
        rows, scores, refused = [], [], []
        for seed in seeds:
            for name, vertices in zip("AB", model.random_identities(np.random.default_rng(seed)), strict=True):
                try:
                    target = auto_target(model.mesh(vertices))
                except InputError as exc:
                    refused.append(f"{seed}{name}")
                    rows.append(f"| {seed}{name} | refused: {exc} | | | |")
                    continue
                placed = vertices[[target.points[f"mp{i}"] for i in mp]]
                d = np.linalg.norm(placed - vertices[model.landmarks], axis=1)
                scores.append((np.median(d), np.median(d[36:48]), d[36:48].max()))
                rows.append(f"| {seed}{name} | {scores[-1][0]:.2f} | {scores[-1][1]:.2f} | {scores[-1][2]:.2f} | "
                            f"{target.fapu.irisd0:.2f} |")
                print(rows[-1], flush=True)
        s = np.asarray(scores)
        lines += ["", f"## {group.capitalize()} identities (seeds {seeds[0]}-{seeds[-1]}, faces A and B)", "",
                  f"Over the {len(s)} faces placed: median (worst) of the per-face medians, all points "
                  f"{np.median(s[:, 0]):.2f} ({s[:, 0].max():.2f}) cm, eyes {np.median(s[:, 1]):.2f} "
                  f"({s[:, 1].max():.2f}) cm, eyes' worst point {np.median(s[:, 2]):.2f} ({s[:, 2].max():.2f}) cm; "
                  f"refused: {', '.join(refused) or 'none'}.", "",
                  "| face | all: median cm | eyes: median cm | eyes: worst cm | IRISD0 cm |", "|---|---|---|---|---|",
                  *rows]
    return lines


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--identities", action="store_true", help="also the round trip's identities (tuning 0-5, "
                        "reporting 100-111)")
    args = parser.parse_args(argv)
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
             f"`python benchmarks/placement_ict.py{' --identities' if args.identities else ''}`: {seconds:.1f} s. "
             "Distances (cm) from the placed 68-layout "
             f"points to ICT's 68 landmark vertices; face width (jaw 0-16) {face_width:.1f} cm.", "",
             f"**Median {np.median(d):.2f} cm ({np.median(d) / face_width:.1%} of face width), "
             f"mean {d.mean():.2f} cm.**",
             "", "| group | median cm | max cm |", "|---|---|---|"]
    for name, (a, b) in GROUPS.items():
        lines.append(f"| {name} | {np.median(d[a:b]):.2f} | {d[a:b].max():.2f} |")
    if args.identities:
        lines += identities(model)
    publish("placement_ict.md", lines)
    return 0


if __name__ == "__main__":
    sys.exit(main())
