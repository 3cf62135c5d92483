"""The muscles' action units against ICT-FaceKit's FACS shapes: direction, and reading back.

    python benchmarks/facs_ict.py

ICT-FaceKit's README ties its expression shapes to FACS action units
(``facs_to_ict_shapes.json``). Both figures use ICT's face area (vertices 0-9408).

* **Direction**: each AU of that table made by faceanim's muscles on an ICT face (placed by the face's
  27 feature points from ICT's 68 landmarks), against the sum of ICT's shapes for the AU: cosine of
  the stacked displacement vectors. On the generic neutral, which
  ``benchmarks/calibrate_muscles.py`` tunes the muscle placements on, and on three random ICT
  identities (N(0, 1) identity weights), which it never sees.
* The same on the neutral through the **generic route** (``faceanim express --route generic``).
* **Reading back**: each ICT shape tied to a single AU, applied to the neutral at 0.5 and 1.0; the
  AU fitter (``faceanim.synth.fitting.AuFitter``, bounded least squares on the muscles' AU basis)
  reads the motion of 500 face vertices; the named AU should be the strongest, and its intensity
  should rise from 0.5 to 1.0.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from ict_scenario import FACE_VERTICES, ICT, _farthest_points, ict_missing, load_ict  # noqa: E402
from report import publish  # noqa: E402

from faceanim.mpeg4.multipie import MULTIPIE68_OF_FEATURE_POINT  # noqa: E402
from faceanim.synth.expression import expression_field  # noqa: E402
from faceanim.synth.face import MuscleFace  # noqa: E402
from faceanim.synth.facs import ACTION_UNITS  # noqa: E402
from faceanim.synth.fitting import AuFitter  # noqa: E402
from faceanim.target import Target  # noqa: E402

DENSE = 500


def face_region() -> np.ndarray:
    return np.arange(FACE_VERTICES)


def ict_face(model, vertices, *, dense: int = 0) -> MuscleFace:
    """An ICT face as a muscle face: its feature points from ICT's 68 landmarks (and ``dense`` extra
    face vertices as control points ``v<id>`` for the fitter)."""
    points = {name: int(model.landmarks[i]) for name, i in MULTIPIE68_OF_FEATURE_POINT.items()}
    if dense:
        for v in _farthest_points(vertices, model.landmarks, dense):
            points.setdefault(f"v{int(v)}", int(v))
    return MuscleFace(Target.from_points(model.mesh(vertices), points))


def _code(label: str) -> str:
    number = label.split()[0][2:]
    return number + ("L" if "(left)" in label else "R" if "(right)" in label else "")


def ict_table(model) -> dict[str, np.ndarray]:
    """``{AU code: ICT displacement (26719, 3)}`` for every row of ICT's FACS table."""
    table = json.loads((ICT / "facs_to_ict_shapes.json").read_text())["au_to_ict_shapes"]
    shapes = dict(zip(model.expression_names, model.expression_deltas, strict=False))
    return {_code(label): sum(shapes[s] for s in names) for label, names in table.items()}


def single_shapes(model) -> list[tuple[str, int, np.ndarray]]:
    """ICT shapes the table ties to one AU: (shape name, AU number, displacement)."""
    table = json.loads((ICT / "facs_to_ict_shapes.json").read_text())["au_to_ict_shapes"]
    shapes = dict(zip(model.expression_names, model.expression_deltas, strict=False))
    return [(s, int(_code(label).rstrip("LR")), shapes[s]) for label, names in table.items() for s in names]


def cosine(a, b) -> float:
    return float((a * b).sum() / max(np.linalg.norm(a) * np.linalg.norm(b), 1e-12))


def direction(model, faces) -> dict[str, list[float]]:
    table = ict_table(model)
    region = face_region()
    return {code: [cosine(expression_field(face, {code: 1.0})[region], truth[region]) for face in faces]
            for code, truth in table.items()}


def direction_generic(model) -> dict[str, float]:
    """The same cosines for the generic route: made on the generic face, carried onto the ICT neutral
    by warping and projection (faceanim express --route generic)."""
    from faceanim.expressions import generic_carrier

    generic, carry = generic_carrier(ict_face(model, model.neutral).target)
    region = face_region()
    return {code: cosine(carry(expression_field(generic, {code: 1.0}))[region], truth[region])
            for code, truth in ict_table(model).items()}


def read_back(model) -> list[tuple[str, int, int, int, float, float]]:
    """Per single shape: name, named AU, strongest AU at 0.5 and at 1.0, named AU's intensity at both."""
    face = ict_face(model, model.neutral, dense=DENSE)
    names = [n for n in face.target.points]
    fitter = AuFitter(face, names)
    ids = face.target.ids(names)
    number_of = np.array([int(c.rstrip("LR")) for c in fitter.codes])
    rows = []
    for shape, au, delta in single_shapes(model):
        x = fitter(np.stack([w * delta[ids] for w in (0.5, 1.0)]))
        strongest = [int(number_of[np.argmax(frame)]) for frame in x]
        named = [float(frame[number_of == au].max()) for frame in x]
        rows.append((shape, au, *strongest, *named))
    return rows


def main() -> int:
    if ict_missing():
        return 0
    start = time.perf_counter()
    model = load_ict()
    rng = np.random.default_rng(7)
    faces = [ict_face(model, model.neutral)] + [
        ict_face(model, model.identity(rng.normal(size=len(model.identity_deltas)))) for _ in range(3)]
    cos = direction(model, faces)
    via_generic = direction_generic(model)
    rows = read_back(model)
    seconds = time.perf_counter() - start
    neutral = np.array([v[0] for v in cos.values()])
    others = np.array([np.mean(v[1:]) for v in cos.values()])
    top1 = [(a == s05) and (a == s10) for _, a, s05, s10, _, _ in rows]
    rising = [i10 > i05 for *_, i05, i10 in rows]
    lines = ["# FACS action units against ICT-FaceKit", "",
             f"`python benchmarks/facs_ict.py`: {seconds:.0f} s. Face area: ICT vertices 0-{FACE_VERTICES - 1}.", "",
             "## Direction: cosine of the muscles' AU field with ICT's shapes for that AU", "",
             f"**Generic neutral (calibrated on): median {np.median(neutral):.2f}, lowest {neutral.min():.2f} "
             f"(AU{list(cos)[int(np.argmin(neutral))]}); {int((neutral >= 0.5).sum())}/{len(neutral)} AUs at 0.5 "
             f"or more.**",
             f"**Three random identities (not seen by the calibration): median {np.median(others):.2f}, lowest "
             f"{others.min():.2f}.** Target: median >= 0.7, every AU >= 0.5.",
             f"The generic route (made on the generic face, projected onto the neutral): median "
             f"{np.median(list(via_generic.values())):.2f}, lowest {min(via_generic.values()):.2f}.", "",
             "| AU | name | ICT shapes | neutral | identities (mean) | generic route |", "|---|---|---|---|---|---|"]
    table = json.loads((ICT / "facs_to_ict_shapes.json").read_text())["au_to_ict_shapes"]
    for (_label, shapes), (code, values) in zip(table.items(), cos.items(), strict=False):
        name = ACTION_UNITS[int(code.rstrip("LR"))].name
        lines.append(f"| {code} | {name} | {' + '.join(shapes)} | {values[0]:.2f} | {np.mean(values[1:]):.2f} "
                     f"| {via_generic[code]:.2f} |")
    lines += ["", "## Reading back: ICT shape at 0.5 and 1.0 -> AU fitter on 500 face vertices", "",
              f"**Top-1 (the named AU strongest at both weights): {np.mean(top1):.0%} of {len(rows)} shapes; "
              f"named AU's intensity rises from 0.5 to 1.0 in {np.mean(rising):.0%}.** Target: top-1 >= 80%.", "",
              "| ICT shape | AU | strongest at 0.5 | strongest at 1.0 | AU intensity 0.5 -> 1.0 |",
              "|---|---|---|---|---|"]
    for shape, au, s05, s10, i05, i10 in rows:
        lines.append(f"| {shape} | {au} | {s05} | {s10} | {i05:.2f} -> {i10:.2f} |")
    publish("facs_ict.md", lines)
    return 0


if __name__ == "__main__":
    sys.exit(main())
