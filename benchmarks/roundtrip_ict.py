"""End to end, with exact truth: an ICT face performs, faceanim watches, another ICT face repeats.

    python benchmarks/roundtrip_ict.py [--seed 3]

ICT identity A performs a scripted sequence (rest, then jawOpen, smile, blink, brows raised, each
eased in and out over 30 frames; 130 frames at 25 fps), rendered to video by faceanim's renderer
(front), three ways: skin, brows, lids, eyes and lips taken from a real photo (``portrait_face``),
the default; eyebrows and lips painted on flat skin; and flat parts only (skin, sclera, iris, lashes,
teeth). ``faceanim animate`` then tracks the video (neutral:
the first 10 frames) and moves identity B, control points placed automatically, by the tracked
motion or by its FAPs. B performing the same sequence is the truth. Score per segment, as in the transfer
benchmark, over the face area (ICT vertices 0-9408) on frames where the expression is at least half
on: rms(|out - truth|) / rms(|truth - rest|). A last run skips the video: A's exact motion at the
points placed on it drives B, so the table separates the retargeting's error from the tracking's.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from faceanim.errors import InputError

sys.path.insert(0, str(Path(__file__).resolve().parent))
from ict_scenario import FACE_VERTICES, ICT, ict_missing, load_ict, relative_error  # noqa: E402
from report import publish  # noqa: E402

# The OBJ's materials, coloured like a face, so the tracker sees eyes, lashes and mouth as in a video.
PART_COLOURS = {"M_Face": (214, 170, 140), "M_BackHead": (214, 170, 140), "M_ScleraLeft": (235, 235, 230),
                "M_ScleraRight": (235, 235, 230), "M_IrisLeft": (60, 45, 35), "M_IrisRight": (60, 45, 35),
                "M_EyeLashes": (30, 20, 15), "M_Teeth": (240, 235, 220), "M_GumsTongue": (150, 60, 60),
                "M_LacrimalFluid": None, "M_EyeOcclusion": None, "M_EyeBlend": None}  # see-through overlays

SKIN, BROW, LIP = (214, 170, 140), (75, 55, 45), (175, 95, 90)


def painted_face(model, vertices) -> np.ndarray:
    """``(V, 3)`` uint8 colours for the source face: skin, eyebrows and lips, as a real face has them.

    ICT's model has no texture, and a face without brows gives the tracker nothing to follow when the
    brows move. The brows are a band 0.7 cm wide just under ICT's brow landmarks (17-26, on the
    brow's upper edge); the lips are the skin inside ICT's outer-lip landmarks (48-59), seen from the
    front. Only the source is painted; the target and its placement never see ICT's landmarks.
    """
    from skimage.measure import points_in_poly

    colours = np.tile(np.array(SKIN, dtype=np.uint8), (len(vertices), 1))
    face = vertices[:FACE_VERTICES]
    marks = vertices[model.landmarks]
    for start, end in ((17, 22), (22, 27)):
        line = marks[start:end] - [0.0, 0.35, 0.0]
        a, b = line[:-1], line[1:]
        ab = b - a
        t = np.clip(np.einsum("vsk,sk->vs", face[:, None] - a, ab) / (ab * ab).sum(1), 0, 1)
        nearest = a + t[..., None] * ab
        distance = np.linalg.norm(face[:, None] - nearest, axis=2).min(axis=1)
        colours[:FACE_VERTICES][distance < 0.35] = BROW
    lips = marks[48:60]
    inside = points_in_poly(face[:, :2], lips[:, :2]) & (face[:, 2] > lips[:, 2].min() - 0.5)
    colours[:FACE_VERTICES][inside] = LIP
    return colours


def portrait_face(model, vertices, labelled) -> np.ndarray:
    """``(V, 3)`` uint8 colours for the source face taken from a real photo: the astronaut portrait that
    scikit-image ships, carried onto the face by correspondence.

    MediaPipe's points are placed on the source identity (``place_landmarks``) and found on the photo; a
    thin-plate warp from the face's front view to the photo then gives every face and eyeball vertex
    its pixel, so the brows, lids, lashes' line, irises and lips are the photo's own and move with the
    vertices. Skin outside the photo's face oval takes the face's median colour (the photo has hair and
    a suit there). Only the source is coloured; the target never sees the photo.
    """
    from skimage.measure import points_in_poly

    from faceanim.capture.metric import canonical_face
    from faceanim.geometry.rbf import RbfWarp
    from faceanim.geometry.topology import boundary_loops
    from faceanim.portrait import portrait, portrait_landmarks
    from faceanim.retarget.placement import place_landmarks

    photo, name = portrait()
    photo_pixels = portrait_landmarks(photo, name)[:468, :2] * [photo.shape[1], photo.shape[0]]
    on_face = place_landmarks(model.mesh(vertices))[:468]
    on_face, first = np.unique(on_face, return_index=True)  # two points on one vertex: keep one
    warp = RbfWarp(vertices[on_face, :2], photo_pixels[first])

    def sample(ids):
        pixels = np.round(warp(vertices[ids, :2])).astype(int)
        pixels = np.clip(pixels, 0, [photo.shape[1] - 1, photo.shape[0] - 1])
        return photo[pixels[:, 1], pixels[:, 0]]

    colours = np.zeros((len(vertices), 3), dtype=np.uint8)
    face = np.arange(FACE_VERTICES)
    colours[face] = sample(face)
    oval = boundary_loops(canonical_face().triangles)[0]  # MediaPipe's face mesh is open only round its edge
    placed = dict(zip(first, on_face, strict=True))  # MediaPipe index -> vertex, where kept
    outline = vertices[[placed[i] for i in oval if i in placed], :2]
    inside = points_in_poly(vertices[face, :2], outline)
    skin = np.median(colours[face][inside], axis=0).astype(np.uint8)
    colours[face[~inside]] = skin
    eyes = [k for k, n in enumerate(labelled.part_names) if n.startswith(("M_Sclera", "M_Iris"))]
    eyeballs = np.unique(labelled.triangles[np.isin(labelled.parts, eyes)])
    colours[eyeballs] = sample(eyeballs)
    colours[np.setdiff1d(np.arange(FACE_VERTICES, len(vertices)), eyeballs)] = skin
    return colours


SEGMENTS = (("jawOpen", ("jawOpen",)), ("smile", ("mouthSmile_L", "mouthSmile_R")),
            ("blink", ("eyeBlink_L", "eyeBlink_R")), ("brows up", ("browInnerUp_L", "browInnerUp_R",
                                                                   "browOuterUp_L", "browOuterUp_R")))


def script(model, rest=10, length=30, segments=SEGMENTS):
    """(T, 53) expression weights: rest, then each of ``segments`` eased 0 -> 1 -> 0."""
    ease = np.sin(np.linspace(0, np.pi, length)) ** 2
    weights = [np.zeros((rest, len(model.expression_names)))]
    for _, names in segments:
        w = np.zeros((length, len(model.expression_names)))
        for name in names:
            w[:, model.expression_names.index(name)] = ease
        weights.append(w)
    return np.concatenate(weights)


# (label, how the source is coloured, animate's route)
RUNS = (("portrait source, motion route (default)", "portrait", "motion"),
        ("portrait source, FAP route", "portrait", "faps"),
        ("painted source, motion route", "painted", "motion"),
        ("unpainted source, motion route", "unpainted", "motion"))


def source_style(model, A, labelled, skin: str) -> dict:
    """The renderer's settings for the source face: ``portrait``, ``painted`` or ``unpainted``."""
    if skin == "unpainted":
        return {"part_colours": PART_COLOURS}
    if skin == "painted":
        return {"part_colours": {k: v for k, v in PART_COLOURS.items() if k != "M_Face"},
                "vertex_colours": painted_face(model, A), "light": (0.0, 1.0, 1.0)}
    # The photo has the eyes, and the lashes' line on the lids; ICT's lash strips drawn solid would be
    # a black ring round each eye.
    kept = {"M_Teeth", "M_GumsTongue", "M_LacrimalFluid", "M_EyeOcclusion", "M_EyeBlend"}
    parts = {k: v for k, v in PART_COLOURS.items() if k in kept}
    parts["M_EyeLashes"] = None
    return {"part_colours": parts, "vertex_colours": portrait_face(model, A, labelled), "light": (0.0, 1.0, 1.0)}


def run(model, A, B, weights, deltas, *, skin: str, via: str):
    """Render A performing, run ``faceanim animate`` onto B; returns (positions (T, V, 3), FapStream)."""
    from faceanim import pipeline
    from faceanim.geometry import read_mesh, write_mesh
    from faceanim.render.camera import front_camera
    from faceanim.render.rasterizer import Renderer
    from faceanim.render.video import video_writer

    labelled = read_mesh(ICT / "obj" / "generic_neutral_mesh.obj")  # its materials label the parts
    source = labelled.with_vertices(A)
    style = source_style(model, A, labelled, skin)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        camera = front_camera(A[:FACE_VERTICES], 512, 512, vertical_fov=20.0, margin=1.1)
        with Renderer(512, 512) as renderer, video_writer(tmp / "performance.mp4", 25, 512, 512) as write:
            for d in deltas:
                write(renderer.render(source, camera, positions=A + d, **style))
        write_mesh(tmp / "B.obj", model.mesh(B))
        animation, stream = pipeline.animate(tmp / "performance.mp4", tmp / "B.glb", target_mesh=tmp / "B.obj",
                                             neutral="0:10", progress=False, via=via)
    return animation.positions, stream


def exact_run(model, A, B, deltas):
    """B moved by A's true motion at MediaPipe's points placed on A (no video): what a perfect tracker
    would give. Its error is the retargeting's own share; the rest of a tracked run's is tracking's."""
    from faceanim import pipeline
    from faceanim.geometry import write_mesh
    from faceanim.landmarks import landmark_names
    from faceanim.motion import Motion
    from faceanim.mpeg4 import fapu_from_points
    from faceanim.retarget.follow import animate_motion
    from faceanim.retarget.placement import place_landmarks

    ids = place_landmarks(model.mesh(A))
    kept = np.flatnonzero(ids >= 0)
    names = tuple(landmark_names(len(ids))[i] for i in kept)
    neutral = A[ids[kept]]
    motion = Motion(names, neutral, deltas[:, ids[kept]], np.tile(np.eye(4), (len(deltas), 1, 1)), 25.0,
                    fapu_from_points(dict(zip(names, neutral, strict=True))))
    with tempfile.TemporaryDirectory() as tmp:
        write_mesh(Path(tmp) / "B.obj", model.mesh(B))
        target = pipeline.load_target(Path(tmp) / "B.obj")
    return animate_motion(motion, target).positions


def segment_table(out, truth, rest, weights, model) -> tuple[list[str], float]:
    """Markdown rows scoring ``out`` per segment (median and 95th percentile of the per-frame error: a
    median does not see a few torn frames), and the median over all active frames."""
    lines = ["| segment | frames | relative error | worst 5% of frames | truth rms (cm) | best gain "
             "| error at best gain |",
             "|---|---|---|---|---|---|---|"]
    all_errors = []
    for (name, _), frames in zip(SEGMENTS, segment_frames(weights, model), strict=True):
        err = relative_error(out[frames], truth[frames], rest)
        all_errors.append(err)
        size = np.sqrt(((truth[frames] - rest) ** 2).sum(-1).mean())
        moved, wanted = (out[frames] - rest).ravel(), (truth[frames] - rest).ravel()
        gain = moved @ wanted / max(moved @ moved, 1e-300)
        refit = relative_error(rest + gain * (out[frames] - rest), truth[frames], rest)
        lines.append(f"| {name} | {len(frames)} | {np.median(err):.2f} | {np.percentile(err, 95):.2f} | {size:.3f} | "
                     f"{gain:.2f} | {np.median(refit):.2f} |")
    every = np.concatenate(all_errors)
    lines.append(f"| all active frames | {len(every)} | {np.median(every):.2f} | "
                 f"{np.percentile(every, 95):.2f} | | | |")
    return lines, float(np.median(every))


def many_pairs(first: int, count: int) -> int:
    """The headline route (portrait source, motion) and the no-video run over ``count`` identity pairs
    drawn from seeds ``first`` .. ``first + count - 1`` (apart from seed 3, the one the methods were
    tuned on): per pair the median and 95th percentile of the per-frame error; over pairs, the median
    and the worst."""
    model = load_ict()
    weights = script(model)
    label, skin, via = RUNS[0]
    segments = [name for name, _ in SEGMENTS]
    lower_teeth = _lower_teeth(model)
    jaw_frames = next(segment_frames(weights, model))
    rows = ["| seed | tracked: median | tracked: worst 5% of frames | no video: median | no video: worst 5% | "
            + " | ".join(f"tracked {name}" for name in segments) + " | tracked: lower teeth off (cm), jawOpen |",
            "|---|---|---|---|---|" + "---|" * (len(segments) + 1)]
    found, failed = [], []
    for seed in range(first, first + count):
        A, B = model.random_identities(np.random.default_rng(seed))
        deltas = np.einsum("te,evc->tvc", weights, model.expression_deltas)
        truth, rest = (B + deltas)[:, :FACE_VERTICES], B[:FACE_VERTICES]
        try:
            positions, _ = run(model, A, B, weights, deltas, skin=skin, via=via)
            exact = exact_run(model, A, B, deltas)
        except InputError as exc:  # a pair the pipeline refuses counts, as a failure, not a crash
            failed.append(seed)
            rows.append(f"| {seed} | failed: {exc} |" + " |" * (4 + len(segments)))
            print(rows[-1], flush=True)
            continue
        scores, per_segment = [], []
        for out in (positions, exact):
            per_segment.append([relative_error(out[:, :FACE_VERTICES][frames], truth[frames], rest)
                                for frames in segment_frames(weights, model)])
            errors = np.concatenate(per_segment[-1])
            scores += [float(np.median(errors)), float(np.percentile(errors, 95))]
        scores += [float(np.median(e)) for e in per_segment[0]]  # the tracked run's, segment by segment
        off = np.linalg.norm(positions[jaw_frames][:, lower_teeth] - (B + deltas[jaw_frames])[:, lower_teeth], axis=2)
        scores.append(float(np.median(off)))  # the teeth are not in B's face area, and a user sees them
        found.append(scores)
        rows.append(f"| {seed} | " + " | ".join(f"{v:.2f}" for v in scores) + " |")
        print(rows[-1], flush=True)
    found = np.array(found)
    # three decimals over pairs: issue 16's goals sit on the second (median <= 0.5)
    rows += ["| **median over pairs** | " + " | ".join(f"{v:.3f}" for v in np.median(found, axis=0)) + " |",
             "| **worst pair** | " + " | ".join(f"{v:.3f}" for v in found.max(axis=0)) + " |"]
    publish("roundtrip_pairs.md", [
        "# End to end over many identity pairs", "",
        f"`python benchmarks/roundtrip_ict.py --pairs {count} --first {first}`: {label}, and the no-video run "
        "(A's exact motion at the placed points), for each pair of identities drawn from the seed (as "
        "`--seed` does). Relative error over B's face on frames where an expression is at least half on; "
        "then the tracked run's median per segment (issue 16's goals: median <= 0.5, blink <= 0.6, brows <= 0.6); "
        "the last column, the median distance (cm) of B's lower teeth from the truth on the jawOpen frames "
        "(whether the teeth go where the lips go).", "",
        *rows, "", f"Pairs the pipeline refused: {len(failed)} of {count}"
        + (f" (seeds {', '.join(map(str, failed))}); the statistics are over the others." if failed else "."), ""])
    return 0


def _lower_teeth(model) -> np.ndarray:
    """ICT's lower teeth: the teeth (material M_Teeth) that jawOpen moves."""
    from faceanim.geometry import read_mesh

    labelled = read_mesh(ICT / "obj" / "generic_neutral_mesh.obj")
    teeth = np.unique(labelled.triangles[labelled.parts == labelled.part_names.index("M_Teeth")])
    opening = model.expression_deltas[model.expression_names.index("jawOpen")]
    return teeth[np.linalg.norm(opening[teeth], axis=1) > 0.1]


def segment_frames(weights, model):
    """Per segment of the script, the frames where its expression is at least half on."""
    for _, expressions in SEGMENTS:
        column = model.expression_names.index(expressions[0])
        yield np.flatnonzero(weights[:, column] >= 0.5)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=3)
    parser.add_argument("--pairs", type=int, help="score the headline route over this many identity pairs")
    parser.add_argument("--first", type=int, default=100, help="with --pairs: the first seed (default 100)")
    args = parser.parse_args(argv)
    if ict_missing():
        return 0
    if args.pairs:
        return many_pairs(args.first, args.pairs)
    rng = np.random.default_rng(args.seed)
    model = load_ict()
    A, B = model.random_identities(rng)
    weights = script(model)
    deltas = np.einsum("te,evc->tvc", weights, model.expression_deltas)
    truth = (B + deltas)[:, :FACE_VERTICES]
    rest = B[:FACE_VERTICES]
    lines = ["# End to end on ICT-FaceKit: render, track, another face", "",
             f"`python benchmarks/roundtrip_ict.py --seed {args.seed}`. Source: identity A rendered (512 px, front) "
             "performing the script; target: identity B, control points placed automatically; `faceanim animate` "
             "with the neutral on frames 0-9 (MediaPipe's Face Landmarker, head pose, One Euro filter, then B). "
             "Relative error over B's face area on frames where the expression is at least half on: 0 is exact, "
             "1 is no better than not moving.", "",
             "Sources: *portrait*: A's face and eyeballs coloured from the astronaut photo scikit-image ships, "
             "carried across by MediaPipe's points on both (`portrait_face`), lit from above; "
             "*painted*: skin, eyebrows and lips painted on A (`painted_face`), lit from above; "
             "*unpainted*: A's parts coloured (skin, sclera, iris, lashes, teeth) but no brows or lips, lit "
             "from the camera. Routes: *motion* follows the tracked points in 3D (`--via motion`, the default); "
             "*FAP* plays the MPEG-4 FAPs the video gives (`--via faps`, what `decode` does with the `.fap`).", "",
             "Diagnosis columns: the gain that would fit the output's motion best to the truth (least squares; 1 "
             "means the size is right, negative the wrong direction), and the error left at that gain (the shape "
             "of the motion, not its size).", ""]
    for label, skin, via in RUNS:
        start = time.perf_counter()
        positions, stream = run(model, A, B, weights, deltas, skin=skin, via=via)
        seconds = time.perf_counter() - start
        rows, median = segment_table(positions[:, :FACE_VERTICES], truth, rest, weights, model)
        lines += [f"## {label} ({seconds:.0f} s)", "", *rows, "",
                  f"**Median over all active frames: {median:.2f}** "
                  f"(FAPs written per frame: {int(stream.mask[0].sum())}).", ""]
    rows, median = segment_table(exact_run(model, A, B, deltas)[:, :FACE_VERTICES], truth, rest, weights, model)
    lines += ["## no video: A's exact motion at the placed points (the retargeting's share)", "",
              "What a perfect tracker would give: MediaPipe's points placed on A, moved by A's true motion, followed "
              "by B as in the motion route. The gap between this and the runs above is tracking's.", "", *rows, "",
              f"**Median over all active frames: {median:.2f}**", ""]
    publish("roundtrip_ict.md", lines)
    return 0


if __name__ == "__main__":
    sys.exit(main())
