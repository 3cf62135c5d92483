"""The capture's head pose on renders of a still head: how far expressions turn and move it.

    python benchmarks/head_pose_ict.py [--tuning 3] [--reporting 100-111] [--cache DIR]

``roundtrip_ict``'s portrait source: ICT identity A rendered (512 px, front) performing jawOpen, smile,
blink and a brow raise; the head never moves, so the true head pose is the same on every frame. The
video is tracked (MediaPipe's Face Landmarker) and made a ``Motion`` as ``animate`` makes it
(neutral frames 0-9, One Euro filter). Per segment, on the frames where the expression is at least half
on, the head frame's pose against its mean over the neutral frames: the turn (degrees, about the head
frame's x / y / z axes: pitch / yaw / roll, and the whole angle) and how far that error moves the
face at rest in the image (mm at the face, RMS over MediaPipe's 468 points). Per pair the worst frame
of each segment; over the reporting pairs, the median and worst. Three fits of the same tracks are
scored (see :func:`head_poses`), two more with ``--tried``. This is a known answer: 0 everywhere is
exact. Writes ``benchmarks/results/head_pose_ict.md``.

``--cache DIR`` keeps each seed's track there (``head_pose_SEED.npz``), so variants of the head fit
can be scored without rendering and tracking again.
"""

from __future__ import annotations

import argparse
import contextlib
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from report import publish  # noqa: E402

SEGMENT_NAMES = ("jawOpen", "smile", "blink", "brows up")


def seeds_of(text: str) -> list[int]:
    """``"100-111"`` or ``"3,7"`` as a list of seeds."""
    found = []
    for part in filter(None, text.split(",")):
        first, _, last = part.partition("-")
        found += list(range(int(first), int(last or first) + 1))
    return found


def still_track(model, seed: int, cache: Path | None):
    """The tracked render of identity A (of ``seed``) performing the round trip's script with a still head."""
    import roundtrip_ict as R

    return performed_track(model, seed, R.script(model), None if cache is None else cache / f"head_pose_{seed}.npz")


def performed_track(model, seed: int, weights: np.ndarray, saved: Path | None):
    """The tracked render of identity A (of ``seed``) performing the expression ``weights (T, 53)``
    with a still head, read from ``saved`` when it is there and kept there when given."""
    deltas = np.einsum("te,evc->tvc", weights, model.expression_deltas)
    return rendered_track(model, seed, lambda A: (A + d for d in deltas), saved, margin=1.1)


def rendered_track(model, seed: int, frames, saved: Path | None, *, margin: float):
    """Identity A (of ``seed``) rendered at the positions ``frames(A)`` yields, a still camera framing
    its face with ``margin``, as the round trip's portrait source, then tracked; read from ``saved``
    when it is there and kept there when given."""
    import roundtrip_ict as R

    from faceanim.capture.track import Track, track_video
    from faceanim.geometry import read_mesh
    from faceanim.render.camera import front_camera
    from faceanim.render.rasterizer import Renderer
    from faceanim.render.video import video_writer

    if saved is not None and saved.exists():
        return Track.load(saved)
    A, _ = model.random_identities(np.random.default_rng(seed))
    labelled = read_mesh(R.ICT / "obj" / "generic_neutral_mesh.obj")
    source = labelled.with_vertices(A)
    style = R.source_style(model, A, labelled, "portrait")
    with tempfile.TemporaryDirectory() as tmp:
        video = Path(tmp) / "performance.mp4"
        camera = front_camera(A[:R.FACE_VERTICES], 512, 512, vertical_fov=20.0, margin=margin)
        with Renderer(512, 512) as renderer, video_writer(video, 25, 512, 512) as write:
            for positions in frames(A):
                write(renderer.render(source, camera, positions=positions, **style))
        track = track_video(video, progress=False)
    if saved is not None:
        track.save(saved)
    return track


TURN_FRAMES = 50  # each sweep: yaw to +-TURN_YAW and back, then pitch to +-TURN_PITCH and back
TURN_YAW, TURN_PITCH = 20.0, 12.0


def turns(rest: int = 10) -> np.ndarray:
    """``(T, 3, 3)`` the head's true turns: still, then a yaw sweep, then a pitch sweep (world axes)."""
    from scipy.spatial.transform import Rotation

    wave = np.sin(np.linspace(0, 2 * np.pi, TURN_FRAMES))
    angles = np.zeros((rest + 2 * TURN_FRAMES, 2))
    angles[rest:rest + TURN_FRAMES, 0] = TURN_YAW * wave
    angles[rest + TURN_FRAMES:, 1] = TURN_PITCH * wave
    return Rotation.from_euler("yx", angles, degrees=True).as_matrix()


def turned_track(model, seed: int, cache: Path | None):
    """The tracked render of identity A (of ``seed``) at rest, its head turning (:func:`turns`) about a
    point 5 cm behind its face's centre, the camera still."""
    import roundtrip_ict as R

    def turning(A):
        face = A[:R.FACE_VERTICES]
        centre = 0.5 * (face.min(axis=0) + face.max(axis=0)) - [0.0, 0.0, 5.0]
        return ((A - centre) @ turn.T + centre for turn in turns())

    return rendered_track(model, seed, turning, None if cache is None else cache / f"head_turn_{seed}.npz",
                          margin=1.3)


@contextlib.contextmanager
def earlier_capture():
    """The capture as it was before the turn filter followed speed and before ``unview``, within."""
    from faceanim.capture import headframe

    table, radius = headframe._view_table, headframe._TURN_RADIUS
    headframe._view_table = lambda: np.zeros((5, 478 * 3))
    headframe._TURN_RADIUS = 0.0
    try:
        yield
    finally:
        headframe._view_table, headframe._TURN_RADIUS = table, radius


def turn_score(track) -> tuple[float, float, float, float]:
    """A real turn, as the capture reads it: the worst frame's error of the turn (degrees: the
    capture's turn against the true one, both in the head frame) and its largest true turn; and how
    far the head frame's static points move (RMS over the skull's landmarks and, apart, the nose's base
    9.15, mm, worst frame): a still face turned should stay still in the head frame."""
    from scipy.spatial.transform import Rotation

    from faceanim.capture.headframe import _skull_weights, track_to_motion
    from faceanim.landmarks import FEATURE_POINT_LANDMARK

    motion = track_to_motion(track, neutral=(0, 10), floor=False)  # the static points' movement as tracked
    pose = np.asarray(motion.pose)
    linear = pose[:, :3, :3] / np.cbrt(np.linalg.det(pose[:, :3, :3]))[:, None, None]
    u, _, vt = np.linalg.svd(linear)
    rigid = u @ vt
    u, _, vt = np.linalg.svd(rigid[:10].mean(axis=0))
    frame = u @ vt  # the head frame's axes in the camera's (= the world's: the camera looks along -z)
    seen = np.einsum("ji,tjk->tik", frame, rigid)
    true = np.einsum("ji,tjk,kl->til", frame, turns(), frame)
    error = np.degrees(np.linalg.norm(Rotation.from_matrix(np.einsum("tji,tjk->tik", true, seen)).as_rotvec(),
                                      axis=1))
    size = np.degrees(np.linalg.norm(Rotation.from_matrix(true).as_rotvec(), axis=1))
    moved = np.linalg.norm(np.asarray(motion.displacements), axis=-1) * 10.0  # (T, L) mm
    skull = np.flatnonzero(_skull_weights() > 0)
    nose = FEATURE_POINT_LANDMARK["9.15"]
    return (float(error.max()), float(size.max()), float(np.sqrt((moved[:, skull] ** 2).mean(axis=1)).max()),
            float(moved[:, nose].max()))


def pose_error(pose: np.ndarray, reference: slice, rest: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per frame, ``pose (T, 4, 4)`` (head frame to camera) against its mean over ``reference`` frames:
    the turn ``(T, 3)`` in degrees (rotation vector in the head frame's axes) and ``(T,)`` how far the
    pose error moves the face at rest, ``rest (L, 3)`` in the head frame (cm), in the image: the RMS
    over its points of the shift of their projections, in mm at the face's distance (one image fits a
    face of any size at a matching distance, so the pose's depth and size do not count, only what
    the image shows)."""
    from scipy.spatial.transform import Rotation

    def rigid(m):
        linear = m[..., :3, :3] / np.cbrt(np.linalg.det(m[..., :3, :3]))[..., None, None]
        u, _, vt = np.linalg.svd(linear)
        return u @ vt

    def seen(m):  # rest's points through pose m, projected: (x / -z, y / -z), the camera looking down -z
        at = np.einsum("...ij,lj->...li", m[..., :3, :3], rest) + m[..., None, :3, 3]
        return at[..., :2] / -at[..., 2:3], -at[..., 2].mean(axis=-1)

    ref = pose[reference].mean(axis=0)
    turn = np.einsum("ji,tjk->tik", rigid(ref), rigid(pose))  # ref^T R_t: the turn in the head frame
    degrees = np.degrees(Rotation.from_matrix(turn).as_rotvec())
    at_rest, depth = seen(ref)
    face_size = np.cbrt(np.linalg.det(ref[:3, :3]))  # camera units per head-frame cm
    shift = np.sqrt(((seen(pose)[0] - at_rest) ** 2).sum(-1).mean(-1)) * depth / face_size * 10.0
    return degrees, shift


def head_poses(track, variant: str, shifts_table=None) -> tuple[np.ndarray, np.ndarray]:
    """``(pose (T, 4, 4), rest (468, 3))`` of the capture as ``animate`` makes it (neutral frames 0-9,
    One Euro filter), by ``variant``:

    * ``mediapipe``: the canonical face's pose (``capture/metric.py``, MediaPipe's face-geometry pipeline,
      which gives the Face Landmarker's facial transformation matrix), before the refit to the neutral;
    * ``plain``: refitted to the person's neutral, every skull landmark at full weight;
    * ``faceanim``: refitted by ``robust_procrustes`` (what the capture does);
    * ``spread weights``: the robust refit with each skull landmark weighed by ``1 / (spread^2 +
      0.03^2)``, its spread on still-head renders of tuning identities (``shifts_table``);
    * ``score shifts``: the robust refit after taking out of the skull's landmarks the moves the
      tracker's scores predict (``shifts_table``: a linear map fitted on tuning identities).
    """
    from faceanim.capture import headframe as H
    from faceanim.geometry.align import robust_procrustes

    usable = track.usable
    points = np.empty(track.landmarks.shape)
    pose = np.empty((len(track), 4, 4))
    H.head_frame_into(track.landmarks, usable, track.times, track.width, track.height, points, pose)
    rest = points[0:10][usable[0:10]].mean(axis=0)
    if variant == "mediapipe":
        return pose, rest[:468]
    weights, spread, moves = H._skull_weights(), H._SKULL_SPREAD, np.zeros((len(track), 468, 3))
    if variant == "plain":
        spread = np.inf
    elif variant == "spread weights":
        weights = weights / (np.array(shifts_table["spread_all_cm"]) ** 2 + 0.03 ** 2)
    elif variant == "score shifts":
        names = list(track.blendshape_names)
        scores = track.blendshapes[:, [names.index(n) for n in shifts_table["scores"]]]
        scores = scores - scores[0:10].mean(axis=0)
        table = np.array(shifts_table["shift_cm_per_score"])
        moves[:, shifts_table["landmarks"]] = (np.nan_to_num(scores) @ table).reshape(len(track), -1, 3)
    elif variant != "faceanim":
        raise ValueError(f"unknown variant {variant!r}")
    at = np.flatnonzero(usable)
    to_frame = robust_procrustes(rest[:468], points[at, :468] - moves[at], weights, scale=spread)
    pose[at] = pose[at] @ to_frame
    return pose, rest[:468]


def score(track, frames_of, variant: str = "faceanim", shifts_table=None) -> list[tuple[float, ...]]:
    """Per segment: worst frame's |pitch|, |yaw|, |roll|, whole angle (degrees) and face shift (mm)."""
    pose, rest = head_poses(track, variant, shifts_table)
    degrees, shift = pose_error(pose, slice(0, 10), rest)
    rows = []
    for frames in frames_of:
        d = degrees[frames]
        rows.append((*np.abs(d).max(axis=0), np.linalg.norm(d, axis=1).max(), shift[frames].max()))
    return rows


VARIANTS = ("mediapipe", "plain", "faceanim")
TRIED = ("spread weights", "score shifts")


def main(argv=None) -> int:
    import json

    import roundtrip_ict as R
    from ict_scenario import ict_missing, load_ict

    from faceanim.errors import InputError

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tuning", default="3")
    parser.add_argument("--reporting", default="100-111")
    parser.add_argument("--cache", type=Path, help="keep the seeds' tracks here")
    parser.add_argument("--tried", type=Path, help="also score the fits tried and not adopted, with this table "
                        "(benchmarks/skull_shifts.py's output)")
    parser.add_argument("--output", default="head_pose_ict.md", help="results file name")
    args = parser.parse_args(argv)
    if ict_missing():
        return 0
    if args.cache is not None:
        args.cache.mkdir(parents=True, exist_ok=True)
    table = None if args.tried is None else json.loads(args.tried.read_text())
    variants = VARIANTS + (TRIED if table is not None else ())
    model = load_ict()
    frames_of = list(R.segment_frames(R.script(model), model))
    lines = ["# The head pose on renders of a still head (issues 16 and 17)", "",
             f"`python benchmarks/head_pose_ict.py --tuning {args.tuning} --reporting {args.reporting}"
             + (f" --tried {args.tried}" if table is not None else "") + "`: "
             "roundtrip_ict's portrait source (identity A, a still head, performing the script), tracked and "
             "made a Motion as `animate` does (neutral frames 0-9). The head pose against its mean on the "
             "neutral frames, worst frame of each segment (frames with the expression at least half on): "
             "turn about the head frame's x (pitch), y (yaw), z (roll) and the whole angle in degrees, and "
             "the face shift: how far the pose's error moves the face at rest in the image (RMS over MediaPipe's "
             "468 points of their projections' shift, in mm at the face: one image fits a face of any size at a "
             "matching distance, so the pose's depth and size do not count). The truth is 0 everywhere.", "",
             "Fits: *mediapipe*: the canonical face's pose (MediaPipe's face-geometry pipeline, "
             "`capture/metric.py`: what the Face Landmarker's facial transformation matrix is); *plain*: refitted "
             "to the person's neutral over the skull's landmarks, all at full weight; *faceanim*: the robust refit "
             "the capture makes (`robust_procrustes`, 0.1 cm)"
             + ("; tried, not adopted: *spread weights* (each skull landmark weighed by how still it stays on "
                "tuning identities' still-head renders) and *score shifts* (the skull's moves the tracker's scores "
                "predict taken out before the fit), both from `benchmarks/skull_shifts.py`'s table" if table else "")
             + ".", "",
             "| seed | use | fit | segment | pitch | yaw | roll | angle | face shift (mm) |",
             "|---|---|---|---|---|---|---|---|---|"]
    found = {}
    seeds = [(s, "tuning") for s in seeds_of(args.tuning)] + [(s, "reporting") for s in seeds_of(args.reporting)]
    for seed, use in seeds:
        try:
            track = still_track(model, seed, args.cache)
        except InputError as exc:  # the portrait's colouring places MediaPipe's points on A automatically
            lines.append(f"| {seed} | {use} | refused: {exc} | | | | | | |")
            print(lines[-1], flush=True)
            continue
        for variant in variants:
            rows = score(track, frames_of, variant, table)
            for name, row in zip(SEGMENT_NAMES, rows, strict=True):
                lines.append(f"| {seed} | {use} | {variant} | {name} | " + " | ".join(f"{v:.2f}" for v in row) + " |")
                print(lines[-1], flush=True)
            found.setdefault((use, variant), []).append(rows)
    lines += ["", "## A real turn of a still face", "",
              f"Identity A at rest, its head turned (yaw to +-{TURN_YAW:.0f} degrees and back, then pitch to "
              f"+-{TURN_PITCH:.0f} and back, {TURN_FRAMES} frames each, about a point 5 cm behind the face's "
              "centre), the camera still; the capture as `animate` makes it (neutral frames 0-9). The turn must "
              "come out as pose, and the face stay still in the head frame: the worst frame's turn error "
              "(the capture's turn against the true one, degrees), and how far the static points move in the "
              "head frame (mm, worst frame: RMS over the skull's landmarks, and the nose's base 9.15).", "",
              "| seed | use | largest true turn | turn error | skull's landmarks moved (mm) | 9.15 moved (mm) |",
              "|---|---|---|---|---|---|"]
    turned = {}
    for seed, use in seeds:
        try:
            track = turned_track(model, seed, args.cache)
        except InputError as exc:
            lines.append(f"| {seed} | {use} | refused: {exc} | | | |")
            continue
        row = turn_score(track)
        turned.setdefault(use, []).append(row)
        with earlier_capture():
            turned.setdefault(use + ", before", []).append(turn_score(track))
        lines.append(f"| {seed} | {use} | {row[1]:.1f} | " + " | ".join(f"{v:.2f}" for v in (row[0], *row[2:])) + " |")
        print(lines[-1], flush=True)
    for use, rows in turned.items():
        rows = np.array(rows)
        lines.append(f"| **{use}: median (worst)** | {len(rows)} pairs | | "
                     + " | ".join(f"{np.median(rows[:, k]):.2f} ({rows[:, k].max():.2f})" for k in (0, 2, 3)) + " |")
    lines += ["", "*before*: the capture as it was before issue 16's head-pose work (the turn filtered at a fixed "
              "1.5 Hz cut-off, nothing taken out for the view: `earlier_capture`)."]
    for use in ("tuning", "reporting"):
        if not any(u == use for u, _ in found):
            continue
        lines += ["", f"## Over the {use} pairs: median (worst)", "",
                  "| fit | segment | pairs | pitch | yaw | roll | angle | face shift (mm) |",
                  "|---|---|---|---|---|---|---|---|"]
        for variant in variants:
            values = np.array(found[(use, variant)])  # (pairs, segments, 5)
            for k, name in enumerate((*SEGMENT_NAMES, "every segment")):
                v = values[:, k] if k < len(SEGMENT_NAMES) else values.reshape(-1, 5)
                cells = [f"{m:.2f} ({w:.2f})" for m, w in zip(np.median(v, axis=0), v.max(axis=0), strict=True)]
                lines.append(f"| {variant} | {name} | {len(values)} | " + " | ".join(cells) + " |")
    if "/" in args.output:  # a scratch table outside the results folder (tuning runs)
        Path(args.output).write_text("\n".join(lines) + "\n")
        print("\n".join(lines))
    else:
        publish(args.output, lines + [""])
    return 0


if __name__ == "__main__":
    sys.exit(main())
