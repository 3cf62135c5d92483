"""Speed of mesh deformation from moving control points: faceanim's operators against scipy, in one run.

    python benchmarks/deform_speed.py [--frames 1000] [--repeats 3]

Deforms the ICT-FaceKit head (26,719 vertices) from 468 control vertices (spread over the face by
farthest-point sampling, as many as MediaPipe tracks) moving through ``--frames`` frames of real
expression motion (smooth random mixes of ICT's expression shapes), thin-plate kernel with affine
term. Compared, on the same frames in one run:

* scipy's ``RBFInterpolator(centres, values, kernel="thin_plate_spline")`` fitted once with all frames
  as vector-valued data ``(K, 3T)`` and evaluated at the vertices (the fair use of scipy: one fit, one
  evaluation, no refit per frame);
* faceanim's float64 operator (``RbfWarp.operator``, one ``(V, K) x (K, 3T)`` product);
* faceanim's float32 operator (:class:`faceanim.geometry.fastop.Float32Operator`), with its stated
  error bounds and the error measured against the float64 product.

Fitting the operator is timed apart (it is done once per target). Writes
``benchmarks/results/deform_speed.md``; note the machine's load (``uptime``) it prints.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np
from scipy.interpolate import RBFInterpolator

sys.path.insert(0, str(Path(__file__).resolve().parent))
from ict_scenario import FACE_VERTICES, _farthest_points, ict_missing, load_ict  # noqa: E402
from report import publish  # noqa: E402

from faceanim.geometry import RbfWarp, apply_operator  # noqa: E402
from faceanim.geometry.fastop import Float32Operator  # noqa: E402


def expression_track(model, frames: int, rng) -> np.ndarray:
    """(frames, 53) smooth expression weights in [0, 1]: random keys every 10 frames, eased between."""
    keys = rng.uniform(0, 1, size=(frames // 10 + 2, len(model.expression_deltas))) ** 4
    t = np.arange(frames) / 10.0
    i = np.floor(t).astype(int)
    s = (t - i)[:, None]
    s = s * s * (3 - 2 * s)
    return (1 - s) * keys[i] + s * keys[i + 1]


def _best_time(fn, repeats: int):
    best, out = np.inf, None
    for _ in range(repeats):
        out = None
        start = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - start)
    return best, out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=1000)
    parser.add_argument("--repeats", type=int, default=3, help="best of this many timings of each method")
    args = parser.parse_args(argv)
    if ict_missing():
        return 0
    rng = np.random.default_rng(0)
    model = load_ict()
    vertices = model.neutral
    controls = _farthest_points(vertices, model.landmarks, 468)
    weights = expression_track(model, args.frames, rng)
    moving = np.einsum("te,ekc->tkc", weights, model.expression_deltas[:, controls])  # (T, 468, 3)
    centres = vertices[controls]
    T, K, _ = moving.shape
    load_before = os.getloadavg()

    start = time.perf_counter()
    operator = RbfWarp(centres, moving[0], kernel="thin_plate").operator(vertices)
    fit64 = time.perf_counter() - start
    start = time.perf_counter()
    fast = Float32Operator(operator)
    fit32 = time.perf_counter() - start

    t64, ours = _best_time(lambda: apply_operator(operator, moving), args.repeats)
    t32, quick = _best_time(lambda: fast(moving), args.repeats)
    stacked = moving.transpose(1, 0, 2).reshape(K, 3 * T)

    def scipy_once():
        return RBFInterpolator(centres, stacked, kernel="thin_plate_spline", degree=1)(vertices)

    tsp, theirs = _best_time(scipy_once, args.repeats)
    theirs = theirs.reshape(len(vertices), T, 3).transpose(1, 0, 2)
    load_after = os.getloadavg()

    err32 = float(np.abs(quick - ours).max())
    diff_scipy = float(np.abs(theirs - ours).max())
    m = float(np.abs(moving).max())
    on_face = fast.row_norms[:FACE_VERTICES].max() / fast.row_norms.max()  # the bounds scale with row norms
    threads = os.environ.get("OMP_NUM_THREADS") or os.environ.get("OPENBLAS_NUM_THREADS") or "default"
    lines = [
        "# Deforming the ICT head from 468 moving control points",
        "",
        f"`python benchmarks/deform_speed.py --frames {args.frames} --repeats {args.repeats}` on "
        f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores (BLAS threads: {threads}), "
        f"numpy {np.__version__}. {len(vertices)} vertices, {K} control points, thin-plate kernel with affine "
        f"term, {T} frames; best of {args.repeats}. Load average (1 min) {load_before[0]:.2f} before, "
        f"{load_after[0]:.2f} after (a shared machine: other people's work ran beside this).",
        "",
        "| method | frames/s | speed-up over scipy | largest difference from the float64 product (cm) |",
        "|---|---|---|---|",
        f"| scipy `RBFInterpolator`, fitted once with all {T} frames as vector-valued data, evaluated once | "
        f"{T / tsp:.0f} | 1.0x | {diff_scipy:.1e} |",
        f"| faceanim float64 operator, one product for all frames (operator fitted once: {fit64:.2f} s) | "
        f"{T / t64:.0f} | {tsp / t64:.1f}x | 0 |",
        f"| faceanim float32 operator, one product (made from the float64 one in {fit32:.2f} s) | "
        f"{T / t32:.0f} | {tsp / t32:.1f}x | {err32:.1e} |",
        "",
        f"float32 error bounds for these frames (largest control displacement m = {m:.2f} cm; see "
        "`faceanim.geometry.fastop`): guaranteed worst case "
        f"{fast.worst_case * m:.1e} cm over the whole head and {fast.worst_case * on_face * m:.1e} cm "
        f"over the face (vertices 0-9408); probabilistic (lambda = 6) {fast.probable * m:.1e} cm over the head and "
        f"{fast.probable * on_face * m:.1e} cm over the face; measured {err32:.1e} cm.",
    ]
    publish("deform_speed.md", lines)
    return 0


if __name__ == "__main__":
    sys.exit(main())
