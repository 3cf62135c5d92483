"""Cross-identity expression transfer on ICT-FaceKit, scored against exact ground truth.

    python benchmarks/transfer_ict.py [--mixes 20] [--seed 7]

Source: identity A (the full ICT head mesh). Target: identity B's face region, re-triangulated,
subdivided and shuffled (see ``ict_scenario.py``). For each of the 53 ICT expressions and for random
mixes of three, the source's motion is transferred and compared with B wearing the same expression.
Score: rms(|out - truth|) / rms(|truth - target neutral|) over the target face (0 is perfect; 1 is no
better than not moving). Per region the errors are pooled over all expressions, because a region that
an expression leaves still (brows in a smile) has no scale of its own. Writes
``benchmarks/results/transfer_ict.md``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from ict_scenario import control_sets, ict_missing, load_ict, relative_error, remade_face  # noqa: E402
from report import publish  # noqa: E402

from faceanim.retarget import REGIONS, ControlPairs, DenseTransfer, SparseTransfer, label_regions  # noqa: E402

# (label, method, options): the thesis' RBF first, then what faceanim adds.
METHODS = [
    ("rbf: euclidean multiquadric (thesis)", "rbf", dict(metric="euclidean", kernel="multiquadric")),
    ("rbf: euclidean thin-plate", "rbf", dict(metric="euclidean", kernel="thin_plate")),
    ("rbf: geodesic thin-plate", "rbf", dict(metric="geodesic", kernel="thin_plate")),
    ("rbf: surface biharmonic, no falloff", "rbf", dict(metric="surface", falloff=0.0)),
    ("rbf: surface biharmonic + falloff (default)", "rbf", dict(metric="surface", falloff=0.25)),
    ("clone: plain closest point", "clone", dict(max_angle=180.0)),
    ("clone: normal-compatible (default)", "clone", dict(max_angle=60.0)),
]


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--mixes", type=int, default=20, help="random mixes of three expressions")
    parser.add_argument("--seed", type=int, default=7)
    args = parser.parse_args(argv)
    if ict_missing():
        return 0

    rng = np.random.default_rng(args.seed)
    model = load_ict()
    A, B = model.random_identities(rng)
    target = remade_face(model, B, rng)
    source = model.mesh(A)
    rest = target.mesh.vertices

    singles = model.expression_deltas
    picks = np.array([rng.choice(len(singles), 3, replace=False) for _ in range(args.mixes)])
    weights = rng.uniform(0.3, 1.0, size=(args.mixes, 3))
    mixes = np.einsum("mk,mkvc->mvc", weights, singles[picks]) if args.mixes else singles[:0]
    motions = np.concatenate([singles, mixes])                       # source displacements (E, 26719, 3)
    truth = np.stack([target.from_ict @ d for d in motions])         # target displacements (E, Vt, 3)
    labels = label_regions(rest, B[model.landmarks])
    n_single = len(singles)

    rows, per_expression = [], {}
    for set_name, ids in control_sets(model, A).items():
        tids = target.index_of[ids]
        for label, method, options in METHODS:
            start = time.perf_counter()
            if method == "rbf":
                moved = SparseTransfer(target.mesh, tids, **options)(motions[:, ids])
            else:
                dense = DenseTransfer(source, target.mesh, ControlPairs(ids, tids), **options)
                moved = np.stack([dense.matrix @ d for d in motions])
            seconds = time.perf_counter() - start
            err = relative_error(rest + moved, rest + truth, rest)
            single, mixed = err[:n_single], err[n_single:]
            pooled = [np.sqrt(((moved - truth)[:, labels == r] ** 2).sum() / (truth[:, labels == r] ** 2).sum())
                      for r in range(len(REGIONS))]
            rows.append((set_name, label, np.median(single), single.mean(), single.max(),
                         model.expression_names[int(single.argmax())],
                         np.median(mixed) if len(mixed) else np.nan, pooled, seconds))
            per_expression[(set_name, label)] = single
            print(f"{set_name:13s} {label:45s} median {np.median(single):.3f} max {single.max():.3f} "
                  f"({seconds:.1f} s)", flush=True)

    lines = [
        "# Cross-identity expression transfer on ICT-FaceKit",
        "",
        f"`python benchmarks/transfer_ict.py --mixes {args.mixes} --seed {args.seed}`. Source: ICT identity A, "
        f"full head ({len(A)} vertices). Target: identity B's face region re-triangulated, subdivided and "
        f"shuffled ({len(rest)} vertices, {len(target.mesh.triangles)} triangles). Identity weights from "
        "N(0, 1.5^2). Relative error rms(|out - truth|) / rms(|truth - rest|): 0 is exact, 1 is no better "
        "than not moving. Singles: the 53 ICT expressions at weight 1; mixes: random sums of three with "
        "weights in [0.3, 1]. Regions: errors pooled over all singles and mixes.",
        "",
        "| controls | method | median | mean | max | worst expression | mixes median | "
        + " | ".join(REGIONS) + " | seconds |",
        "|---|---|---|---|---|---|---|" + "---|" * len(REGIONS) + "---|",
    ]
    for set_name, label, med, mean, worst, worst_name, mix_med, pooled, seconds in rows:
        lines.append(f"| {set_name} | {label} | {med:.3f} | {mean:.3f} | {worst:.3f} | {worst_name} | {mix_med:.3f} | "
                     + " | ".join(f"{p:.2f}" for p in pooled) + f" | {seconds:.1f} |")
    shown = [("68 landmarks", METHODS[0][0]), ("68 landmarks", METHODS[4][0]), ("~500 dense", METHODS[4][0]),
             ("68 landmarks", METHODS[5][0]), ("68 landmarks", METHODS[6][0])]
    lines += ["", "## Per expression (singles)", "",
              "| expression | " + " | ".join(f"{s}: {m}" for s, m in shown) + " |",
              "|---|" + "---|" * len(shown)]
    for i, name in enumerate(model.expression_names):
        lines.append(f"| {name} | " + " | ".join(f"{per_expression[k][i]:.3f}" for k in shown) + " |")
    print(f"wrote {publish('transfer_ict.md', lines, echo=False)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
