"""Where the clone's error comes from: each region of the face registered exactly, the rest as registered.

    python benchmarks/transfer_ict_budget.py [--seeds 4,5]

For a pair of ``transfer_ict.py`` (tuning seeds only: 3, 4, 5, 7, 11), the source is registered onto the
target as ``--method clone`` with 68 pairs does it; then, one region at a time, the registered positions of
that region's source vertices are replaced by the truth (identity B at the same ICT vertex, which is where
the target's surface holds that skin) and the expressions are transferred again. The fall of the pair's
median and worst expression says how much of them that region's registration error costs; "all but it
exact" says what would be left if every other region were exact.

Regions (on the source, by its nearest control point and its side of the face's openings): the jaw line,
brows, nose; the eyes' skin above the lid line (nearest an upper-lid point 37, 38, 43, 44), below it
(40, 41, 46, 47), beside it (nearest a corner), inside the lids (the lids' margins and the sockets, on or
inside the loop the lids close along); the mouth's inside (the inner lips and the socket, on or inside the
inner lip loop), the vermilion (nearest a lip point, within the outer lip line seen from the front), and the
skin round the lips (nearest a lip point, outside the outer lip line).
Writes ``benchmarks/results/transfer_ict_budget.md``.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from ict_scenario import control_sets, ict_missing, load_ict, relative_error  # noqa: E402
from report import publish  # noqa: E402
from transfer_ict import TUNING, WIDE, identity_pair, parse_seeds  # noqa: E402

from faceanim.geometry.mesh import Mesh  # noqa: E402
from faceanim.retarget import ControlPairs, DenseTransfer  # noqa: E402
from faceanim.retarget import transfer as transfer_module  # noqa: E402
from faceanim.retarget.contours import opening_sides  # noqa: E402
from faceanim.retarget.correspondence import _part_with, register_faces  # noqa: E402

GROUPS = {"jaw line": range(0, 17), "brows": range(17, 27), "nose": range(27, 36), "eyes": range(36, 48),
          "lips": range(48, 68)}
UPPER_LID, LOWER_LID = (37, 38, 43, 44), (40, 41, 46, 47)


def _within(vertices: np.ndarray, controls: np.ndarray, loop) -> np.ndarray:
    """Which vertices lie inside the polygon of the control points ``loop``, seen along the face's forward axis
    (the normal of the control points' best plane): an even-odd count of crossings."""
    centre = controls.mean(axis=0)
    axes = np.linalg.svd(controls - centre)[2][:2]
    xy = (vertices - centre) @ axes.T
    poly = (controls[list(loop)] - centre) @ axes.T
    a, b = poly, np.roll(poly, -1, axis=0)
    x, y = xy[:, :1], xy[:, 1:]
    spans = (a[:, 1] > y) != (b[:, 1] > y)
    at = a[:, 0] + (y - a[:, 1]) * (b[:, 0] - a[:, 0]) / np.where(b[:, 1] == a[:, 1], 1e-12, b[:, 1] - a[:, 1])
    return (spans & (x < at)).sum(axis=1) % 2 == 1


def regions(part: Mesh, local: np.ndarray) -> np.ndarray:
    """A region name per vertex of the source's registered part (see the module text)."""
    near = np.argmin(np.linalg.norm(part.vertices[:, None] - part.vertices[local][None], axis=2), axis=1)
    label = np.empty(len(part.vertices), dtype=object)
    for name, group in GROUPS.items():
        label[np.isin(near, list(group))] = name
    side = opening_sides(part, local, "ibug68")  # mouth 1, 2; right eye 3, 4; left eye 5, 6; -1 on a loop
    in_outer_lips = _within(part.vertices, part.vertices[local], range(48, 60))
    eye, lips = label == "eyes", label == "lips"
    label[eye & np.isin(near, UPPER_LID)] = "eyes: skin above the lid line"
    label[eye & np.isin(near, LOWER_LID)] = "eyes: skin below the lid line"
    label[eye & ~np.isin(near, UPPER_LID + LOWER_LID)] = "eyes: skin beside (corners)"
    label[lips] = "lips: skin round the lips"
    label[lips & in_outer_lips] = "lips: vermilion"
    label[np.isin(side, (3, 4, 5, 6)) | (eye & (side == -1))] = "eyes: inside the lids (margins, sockets)"
    label[np.isin(side, (1, 2)) | (~eye & (side == -1))] = "lips: inside the mouth"
    return label


def budget(model, seed: int):
    _, A, B, source, target = identity_pair(model, seed)
    ids = control_sets(model, A)["68 landmarks"]
    tids = target.index_of[ids]
    part, kept, local = _part_with(source, ids)
    label = regions(part, local)
    singles = model.expression_deltas
    rest = target.mesh.vertices
    truth = np.stack([target.from_ict @ d for d in singles])
    registered = register_faces(source, target.mesh, ids, tids, contours="ibug68")

    def scored(exact: np.ndarray) -> np.ndarray:
        vertices = registered.mesh.vertices.copy()
        vertices[exact] = B[kept[exact]]
        changed = dataclasses.replace(registered, mesh=Mesh(vertices, registered.mesh.triangles))
        # DenseTransfer registers through register_faces; hand it the changed registration instead.
        real = transfer_module.register_faces
        transfer_module.register_faces = lambda *args, **kwargs: changed
        try:
            dense = DenseTransfer(source, target.mesh, ControlPairs(ids, tids), contours="ibug68")
        finally:
            transfer_module.register_faces = real
        moved = np.stack([dense.matrix @ d for d in singles])
        return relative_error(rest + moved, rest + truth, rest)

    rows = {"(as registered)": (0, scored(np.zeros(len(kept), dtype=bool)), None)}
    for name in sorted(set(label.tolist())):
        region = label == name
        rows[name] = (int(region.sum()), scored(region), scored(~region))
        print(f"seed {seed} {name}: median {np.median(rows[name][1]):.3f}", flush=True)
    return rows


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=parse_seeds, default=(4, 5), help="tuning seeds, e.g. 4,5 or 3-5")
    args = parser.parse_args(argv)
    if not set(args.seeds) <= set(TUNING):
        parser.error(f"--seeds: tuning seeds only ({', '.join(map(str, TUNING))}); the reporting seeds stay unseen")
    if ict_missing():
        return 0
    model = load_ict()
    names = model.expression_names
    lines = [
        "# Where the clone's error comes from (ICT-FaceKit, tuning pairs)",
        "",
        f"`python benchmarks/transfer_ict_budget.py --seeds {','.join(map(str, args.seeds))}`. clone with 68 pairs "
        "(NICP + contours) as `transfer_ict.py` runs it; then one region's registered source vertices replaced by "
        "the truth (identity B at the same ICT vertex). Median and worst of the 53 single expressions (relative "
        "error as in `transfer_ict.md`); 'all but it' replaces every other region instead.",
        "",
    ]
    for seed in args.seeds:
        rows = budget(model, seed)
        lines += [f"## Seed {seed} (sigma {2.5 if seed in WIDE else 1.5})", "",
                  "| region | source vertices | only it exact: median / worst (expression) | "
                  "all but it exact: median / worst (expression) |", "|---|---|---|---|"]
        for name, (count, only, but) in rows.items():
            cell = f"{np.median(only):.3f} / {only.max():.3f} ({names[int(only.argmax())]})"
            rest = "" if but is None else f"{np.median(but):.3f} / {but.max():.3f} ({names[int(but.argmax())]})"
            lines.append(f"| {name} | {count or ''} | {cell} | {rest} |")
        lines.append("")
    print(f"wrote {publish('transfer_ict_budget.md', lines, echo=True)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
