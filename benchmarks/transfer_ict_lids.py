"""What the upper lids' band measures height to: the brow, the lid's crease, or the mean of the two landings.

    python benchmarks/transfer_ict_lids.py [--seeds 3,4,5,7,11] [--ends brow,crease,mean] [--jobs 2]

For the tuning pairs of ``transfer_ict.py`` (tuning seeds only: 3, 4, 5, 7, 11), ``--method clone`` with 68
pairs (NICP + contours) as ``transfer_ict.py`` runs it, once per upper end of the lid band
(:data:`faceanim.retarget.correspondence.LID_UPPER`, see :func:`faceanim.retarget.contours.lid_bands`): the
median and worst of the 53 single expressions, eyeBlink_L and eyeBlink_R, and the registration's distance from
the truth on the upper lids' skin (the source vertices between 0.08 and 0.5 of the height from the lid line to
the brow: the registered place against identity B at the same ICT vertex). The crease is found from the
geometry alone (:func:`faceanim.retarget.contours._crease_line`). Clone with 16 points has no lid band and is
not run. Writes ``benchmarks/results/transfer_ict_lids.md``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from ict_scenario import control_sets, ict_missing, load_ict, relative_error  # noqa: E402
from report import publish  # noqa: E402
from transfer_ict import TUNING, WIDE, identity_pair, parse_seeds  # noqa: E402

from faceanim.retarget import (  # noqa: E402
    ControlPairs,
    DenseTransfer,
    correspondence,  # noqa: E402
)
from faceanim.retarget.contours import LID_UPPER_ENDS, lid_bands  # noqa: E402
from faceanim.retarget.correspondence import _part_with  # noqa: E402

_model = None


def score(seed: int, end: str):
    global _model
    if _model is None:  # one copy per worker process
        _model = load_ict()
    model = _model
    correspondence.LID_UPPER = end
    correspondence.clear_cache()
    _, A, B, source, target = identity_pair(model, seed)
    ids = control_sets(model, A)["68 landmarks"]
    tids = target.index_of[ids]
    singles = model.expression_deltas
    rest = target.mesh.vertices
    truth = np.stack([target.from_ict @ d for d in singles])
    dense = DenseTransfer(source, target.mesh, ControlPairs(ids, tids), contours="ibug68")
    err = relative_error(rest + np.stack([dense.matrix @ d for d in singles]), rest + truth, rest)
    part, kept, local = _part_with(source, ids)
    face, _, face_ids = _part_with(target.mesh, tids)
    lid, _ = lid_bands(part, face, local, face_ids, "ibug68", rise=(0.08, 0.5))
    off = np.linalg.norm(dense.registration.mesh.vertices[lid] - B[kept[lid]], axis=1)
    print(f"seed {seed} {end}: median {np.median(err):.3f} worst {err.max():.3f}", flush=True)
    return err, float(np.median(off))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=parse_seeds, default=TUNING, help="tuning seeds, e.g. 4,5 or 3-5")
    parser.add_argument("--ends", default=",".join(LID_UPPER_ENDS), help="upper ends of the lid band to compare")
    parser.add_argument("--jobs", type=int, default=1, help="runs at once, each in its own process")
    args = parser.parse_args(argv)
    if not set(args.seeds) <= set(TUNING):
        parser.error(f"--seeds: tuning seeds only ({', '.join(map(str, TUNING))}); the reporting seeds stay unseen")
    ends = args.ends.split(",")
    if not set(ends) <= set(LID_UPPER_ENDS):
        parser.error(f"--ends: some of {', '.join(LID_UPPER_ENDS)}")
    if ict_missing():
        return 0
    runs = [(seed, end) for seed in args.seeds for end in ends]
    if args.jobs > 1:
        from concurrent.futures import ProcessPoolExecutor

        with ProcessPoolExecutor(args.jobs) as pool:
            results = dict(zip(runs, pool.map(score, *zip(*runs, strict=True)), strict=True))
    else:
        results = {run: score(*run) for run in runs}
    names = load_ict().expression_names
    blink = [names.index("eyeBlink_L"), names.index("eyeBlink_R")]
    lines = ["# The upper lids' band: height to the brow, the crease, or the mean (ICT-FaceKit, tuning pairs)", "",
             f"`python benchmarks/transfer_ict_lids.py --seeds {','.join(map(str, args.seeds))} --ends {args.ends}`. "
             "clone with 68 pairs (NICP + contours) as `transfer_ict.py` runs it, the lid band's height measured to "
             f"each end (`faceanim.retarget.correspondence.LID_UPPER`, now `{correspondence.LID_UPPER}` in the "
             "library). Relative error as in `transfer_ict.md`; lid skin: median distance (cm) of the registered "
             "upper lids' skin from the truth.", "",
             "| seed | sigma | upper end | median | worst (expression) | eyeBlink_L | eyeBlink_R | lid skin cm |",
             "|---|---|---|---|---|---|---|---|"]
    for (seed, end), (err, off) in results.items():
        worst = int(err.argmax())
        lines.append(f"| {seed} | {2.5 if seed in WIDE else 1.5} | {end} | {np.median(err):.3f} | "
                     f"{err[worst]:.3f} ({names[worst]}) | {err[blink[0]]:.3f} | {err[blink[1]]:.3f} | {off:.3f} |")
    print(f"wrote {publish('transfer_ict_lids.md', lines, echo=True)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
