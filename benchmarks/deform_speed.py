"""Speed of mesh deformation from moving control points: faceanim against scipy, side by side.

    python benchmarks/deform_speed.py [--frames 1000] [--scipy-frames 20]

Deforms the ICT-FaceKit head (26,719 vertices) from 468 control vertices (spread over the face by
farthest-point sampling, as many as MediaPipe tracks) moving through ``--frames`` frames of real
expression motion (smooth random mixes of ICT's expression shapes). faceanim fits the thin-plate RBF
once and applies its ``(V, K)`` operator to all frames in one matrix product; what a user would write
with scipy is ``RBFInterpolator(centres, frame_values, kernel="thin_plate_spline")(vertices)`` per
frame, timed on the first ``--scipy-frames`` frames. Both outputs are compared on those frames.
Writes ``benchmarks/results/deform_speed.md``.
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
from ict_scenario import _farthest_points, ict_missing, load_ict  # noqa: E402
from report import publish  # noqa: E402

from faceanim.geometry import RbfWarp, apply_operator  # noqa: E402


def expression_track(model, frames: int, rng) -> np.ndarray:
    """(frames, 53) smooth expression weights in [0, 1]: random keys every 10 frames, eased between."""
    keys = rng.uniform(0, 1, size=(frames // 10 + 2, len(model.expression_deltas))) ** 4
    t = np.arange(frames) / 10.0
    i = np.floor(t).astype(int)
    s = (t - i)[:, None]
    s = s * s * (3 - 2 * s)
    return (1 - s) * keys[i] + s * keys[i + 1]


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=1000)
    parser.add_argument("--scipy-frames", type=int, default=20)
    parser.add_argument("--repeats", type=int, default=3, help="best of this many timings of faceanim")
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

    start = time.perf_counter()
    operator = RbfWarp(centres, moving[0], kernel="thin_plate").operator(vertices)
    fit_seconds = time.perf_counter() - start
    best = np.inf
    for _ in range(args.repeats):
        start = time.perf_counter()
        ours = apply_operator(operator, moving)
        best = min(best, time.perf_counter() - start)
        if _ < args.repeats - 1:
            del ours
    ours_fps = args.frames / best

    # The machine's ceiling for this work: one float64 matrix product of the same shape, nothing else.
    a = rng.random(operator.shape)
    b = rng.random((operator.shape[1], 3 * args.frames))
    gemm = np.inf
    for _ in range(args.repeats):
        start = time.perf_counter()
        a @ b
        gemm = min(gemm, time.perf_counter() - start)
    gflops = 2 * a.shape[0] * a.shape[1] * b.shape[1] / gemm / 1e9
    del a, b

    n = min(args.scipy_frames, args.frames)
    start = time.perf_counter()
    theirs = np.stack([RBFInterpolator(centres, moving[t], kernel="thin_plate_spline", degree=1)(vertices)
                       for t in range(n)])
    scipy_fps = n / (time.perf_counter() - start)
    difference = np.abs(ours[:n] - theirs).max()
    motion = np.abs(ours[:n]).max()

    threads = os.environ.get("OMP_NUM_THREADS") or os.environ.get("OPENBLAS_NUM_THREADS") or "default"
    lines = [
        "# Deforming the ICT head from 468 moving control points",
        "",
        f"`python benchmarks/deform_speed.py --frames {args.frames} --scipy-frames {args.scipy_frames}` on "
        f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores (BLAS threads: {threads}), "
        f"numpy {np.__version__}. {len(vertices)} vertices, {len(controls)} control points, thin-plate kernel "
        "with affine term.",
        "",
        "| method | frames timed | frames/s | speed-up |",
        "|---|---|---|---|",
        f"| scipy `RBFInterpolator` fitted per frame | {n} | {scipy_fps:.1f} | 1.0x |",
        f"| faceanim: operator fitted once ({fit_seconds:.2f} s), one product for all frames "
        f"(best of {args.repeats}) | {args.frames} | {ours_fps:.0f} | {ours_fps / scipy_fps:.0f}x |",
        f"| bare float64 matrix product of the same size (this machine's ceiling, {gflops:.0f} GFLOP/s) | "
        f"{args.frames} | {args.frames / gemm:.0f} | {args.frames / gemm / scipy_fps:.0f}x |",
        "",
        f"Largest difference between the two outputs on the {n} compared frames: {difference:.1e} "
        f"(largest displacement {motion:.2f} model units).",
    ]
    publish("deform_speed.md", lines)
    return 0


if __name__ == "__main__":
    sys.exit(main())
