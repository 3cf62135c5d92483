"""ICT-FaceKit's expressions carried onto faces that are not ICT: the default avatar and the generic face.

    python benchmarks/transfer_stills.py [--expressions jawOpen,mouthSmile_L,eyeBlink_L,mouthFunnel,browInnerUp_L]

Source: the ICT mean face (full head). Targets: :func:`faceanim.portrait.avatar_target` (the default
portrait's face) and :func:`faceanim.generic.generic_target`, each paired with ICT through the 68
iBUG points (MediaPipe's ids from :data:`faceanim.landmarks.IBUG68_LANDMARK`). The clone
method registers ICT onto each target (non-rigid ICP with the face's contours) and carries each
expression across. Writes one PNG per target (neutral, then each expression, shaded, front view) to
``benchmarks/results/`` and a table of turned-over triangles (:func:`faceanim.geometry.quality.turned_over`)
to ``benchmarks/results/transfer_stills.md``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from ict_scenario import ict_missing, load_ict  # noqa: E402
from report import RESULTS, publish  # noqa: E402

from faceanim.geometry.quality import turned_over  # noqa: E402
from faceanim.landmarks import IBUG68_LANDMARK  # noqa: E402
from faceanim.retarget import ControlPairs, DenseTransfer  # noqa: E402

DEFAULT = "jawOpen,mouthSmile_L,eyeBlink_L,mouthFunnel,browInnerUp_L"


def targets():
    from faceanim.generic import generic_target
    from faceanim.portrait import avatar_target

    return {"avatar": avatar_target().mesh, "generic": generic_target().mesh}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--expressions", default=DEFAULT)
    parser.add_argument("--size", type=int, default=320)
    args = parser.parse_args(argv)
    if ict_missing():
        return 0
    from PIL import Image

    from faceanim.render import front_camera
    from faceanim.render.rasterizer import Renderer

    model = load_ict()
    names = args.expressions.split(",")
    deltas = model.expression_deltas[[model.expression_names.index(n) for n in names]]
    source = model.mesh(model.neutral)
    lines = ["# ICT-FaceKit's expressions on faces that are not ICT", "",
             f"`python benchmarks/transfer_stills.py --expressions {args.expressions}`. Source: the ICT mean face; "
             "pairs: the 68 iBUG points. Clone with dense registration. Turned-over triangles: "
             "`faceanim.geometry.quality.turned_over` against the target at rest.", "",
             "| target | vertices | registration s | fit (median distance) | landmark error (RMS) | contour points | "
             + " | ".join(f"turned over: {n}" for n in names) + " | image |",
             "|---|---|---|---|---|---|" + "---|" * len(names) + "---|"]
    for label, mesh in targets().items():
        start = time.perf_counter()
        dense = DenseTransfer(source, mesh, ControlPairs(model.landmarks, np.asarray(IBUG68_LANDMARK)))
        seconds = time.perf_counter() - start
        moved = np.stack([mesh.vertices + dense(d) for d in deltas])
        flipped = turned_over(mesh.vertices, moved, mesh.triangles)
        flips = [int(np.asarray(f).sum()) for f in flipped]
        camera = front_camera(mesh.vertices, args.size, args.size)
        with Renderer(args.size, args.size) as renderer:
            tiles = [renderer.render(mesh, camera)] + [renderer.render(mesh, camera, positions=p) for p in moved]
        path = RESULTS / f"transfer_stills_{label}.png"
        RESULTS.mkdir(exist_ok=True)
        Image.fromarray(np.concatenate(tiles, axis=1)).save(path)
        reg = dense.registration
        lines.append(f"| {label} | {len(mesh.vertices)} | {seconds:.1f} | {reg.fit:.3f} | {reg.landmark_error:.3f} | "
                     f"{reg.contour_points} | " + " | ".join(map(str, flips)) + f" | `{path.name}` |")
        print(lines[-1], flush=True)
    lines += ["", "Each image: the target at rest, then " + ", ".join(names) + ", left to right."]
    publish("transfer_stills.md", lines)
    return 0


if __name__ == "__main__":
    sys.exit(main())
