"""Calibrate the muscle table (``src/faceanim/synth/data/movers.json``) on ICT-FaceKit's FACS shapes.

    python benchmarks/calibrate_muscles.py [--write]

The anatomy (which muscle, between which feature points) is fixed by hand in the table. This script
adjusts each AU's main mover within bounds around that hand placement (origin and insertion offsets
up to 0.3 ES0, zone, radii) to maximise the cosine between its displacement field and ICT's shape
for that AU on ICT's *generic neutral* only, then sets its strength so the peak displacement equals
ICT's at intensity 1. ``benchmarks/facs_ict.py`` reports the result on the neutral (seen here) and
on random ICT identities (not seen here), so the calibration cannot hide overfitting.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import fields, replace
from pathlib import Path

import numpy as np
from scipy.optimize import minimize

sys.path.insert(0, str(Path(__file__).resolve().parent))
from facs_ict import face_region, ict_face, ict_table  # noqa: E402
from ict_scenario import ict_missing, load_ict  # noqa: E402

from faceanim.synth import facs  # noqa: E402
from faceanim.synth.expression import expression_field  # noqa: E402

TABLE = Path(facs.__file__).parent / "data" / "movers.json"
# What may move, per mover type: field name -> (lower, upper) relative to the hand value, or absolute.
_RELATIVE = {"origin_offset": 0.3, "insertion_offset": 0.3, "centre_offset": 0.25, "hinge_offset": 0.3}
_ABSOLUTE = {"zone": (15.0, 75.0), "end": (1.1, 2.6), "inner": (0.2, 0.9), "above": (0.0, 1.0),
             "below": (0.0, 1.0), "radius": (0.08, 0.6), "lid_follow": (0.0, 1.0)}
_SCALED = {"radii": (0.5, 1.8)}
_STRENGTH = {"LinearMuscle": ("strength",), "Sphincter": ("gain_x", "gain_y", "push"), "Rotator": ("degrees",),
             "Inflation": ("strength",), "Translator": ("shift",), "Gaze": ("lid_follow",)}


def _vector(mover, hand):
    """The free numbers of ``mover``, their bounds around the ``hand`` placement, and a function
    rebuilding the mover from them."""
    values, bounds, slots = [], [], []

    def add(value, bound, slot):
        values.append(value)
        bounds.append(bound)
        slots.append(slot)

    for f in fields(mover):
        v, h = getattr(mover, f.name), getattr(hand, f.name)
        if f.name in _RELATIVE:
            for k, (x, x0) in enumerate(zip(v, h, strict=True)):
                add(x, (x0 - _RELATIVE[f.name], x0 + _RELATIVE[f.name]), (f.name, k))
        elif f.name in _ABSOLUTE and v is not None:
            add(float(v), _ABSOLUTE[f.name], (f.name, None))
        elif f.name in _SCALED:
            lo, hi = _SCALED[f.name]
            for k, (x, x0) in enumerate(zip(v, h, strict=True)):
                add(x, (x0 * lo, x0 * hi), (f.name, k))
    values = np.clip(values, [b[0] for b in bounds], [b[1] for b in bounds])

    def rebuild(x):
        changes: dict = {}
        for (name, k), value in zip(slots, x, strict=False):
            if k is None:
                changes[name] = float(value)
            else:
                current = list(changes.get(name, getattr(mover, name)))
                current[k] = float(value)
                changes[name] = tuple(current)
        return replace(mover, **changes)

    return np.array(values), bounds, rebuild


def _cosine(a, b):
    return float((a * b).sum() / max(np.linalg.norm(a) * np.linalg.norm(b), 1e-12))


def calibrate(face, table, region, evaluations: int) -> dict:
    """Calibrated movers ``{name: mover}`` for every mover that leads an AU of ICT's table."""
    by_mover: dict[str, list] = {}
    for code, truth in table.items():
        lead = facs.ACTION_UNITS[int(code.rstrip("LR"))].movers[0][0]
        by_mover.setdefault(lead, []).append((code, truth))
    done = {}
    spec = json.loads(TABLE.read_text())
    for name, cases in by_mover.items():
        mover, paired = facs.MOVERS[name]
        hand = facs.mover_from_spec({**spec[name], **spec[name].get("hand", {})})
        x0, bounds, rebuild = _vector(mover, hand)

        def score(x, cases=cases, rebuild=rebuild, name=name, paired=paired):
            facs.MOVERS[name] = (rebuild(x), paired)
            return -np.mean([_cosine(expression_field(face, {c: 1.0})[region], t) for c, t in cases])

        start = time.perf_counter()
        before = -score(x0)
        if not len(x0):  # nothing to place (a translation): only its strength is set
            best = _set_strength(face, mover, name, paired, cases, region)
            facs.MOVERS[name] = (best, paired)
            done[name] = best
            print(f"{name:18s} cosine {before:.3f} (strength only)", flush=True)
            continue
        result = minimize(score, x0, method="Powell", bounds=bounds, options={"maxfev": evaluations, "xtol": 1e-3})
        best = rebuild(result.x) if -result.fun > before else mover
        facs.MOVERS[name] = (best, paired)
        after = -score(result.x if best is not mover else x0)
        best = _set_strength(face, best, name, paired, cases, region)
        facs.MOVERS[name] = (best, paired)
        done[name] = best
        print(f"{name:18s} cosine {before:.3f} -> {after:.3f}  ({time.perf_counter() - start:.0f} s)", flush=True)
    return done


def _set_strength(face, mover, name, paired, cases, region):
    """Scale the mover so its AU's peak displacement over the face equals ICT's."""
    code, truth = cases[0]
    ours = np.linalg.norm(expression_field(face, {code: 1.0})[region], axis=1).max()
    target = np.linalg.norm(truth, axis=1).max()
    if ours <= 0:
        return mover
    ratio = target / ours
    changes = {}
    for name in _STRENGTH[type(mover).__name__]:
        value = getattr(mover, name)
        if value is None:  # a lid turning "all the way": its reach is set by the face
            continue
        changes[name] = tuple(v * ratio for v in value) if isinstance(value, tuple) else value * ratio
    return replace(mover, **changes)


def write_table(movers: dict) -> None:
    """Write the calibrated numbers into the table, keeping each mover's hand placement under
    ``"hand"`` (the first calibration records it) so later calibrations stay within the same bounds."""
    spec = json.loads(TABLE.read_text())
    for name, mover in movers.items():
        entry = spec[name]
        calibrated = {}
        for f in fields(mover):
            v = getattr(mover, f.name)
            if isinstance(v, float):
                calibrated[f.name] = round(v, 4)
            elif isinstance(v, tuple) and v and isinstance(v[0], float):
                calibrated[f.name] = [round(x, 4) for x in v]
        entry.setdefault("hand", {k: entry[k] for k in calibrated})
        entry.update(calibrated)
    lines = ["{"] + [f' "{k}": {json.dumps(v)}{"," if i < len(spec) - 1 else ""}'
                     for i, (k, v) in enumerate(spec.items())]
    TABLE.write_text("\n".join(lines + ["}"]) + "\n")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--write", action="store_true", help="write the calibrated table into the package")
    parser.add_argument("--evaluations", type=int, default=400)
    args = parser.parse_args(argv)
    if ict_missing():
        return 0
    model = load_ict()
    face = ict_face(model, model.neutral)
    region = face_region()
    table = {code: truth[region] for code, truth in ict_table(model).items()}
    movers = calibrate(face, table, region, args.evaluations)
    if args.write:
        write_table(movers)
        print(f"wrote {TABLE}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
