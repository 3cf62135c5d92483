"""Whether animated heads hold together: folds, bent teeth, lips through teeth, tears, on real videos.

    python benchmarks/surface_quality.py [--quick]

Videos d18 (mouth wide open), d10 (surprise, "oh") and d6 (exaggerated expressions, 1008 frames) from
../shared/data/videos drive three targets as ``faceanim animate`` would (``--via motion``; the ICT head
on d18 also ``--via faps``): the ICT-FaceKit head (control points placed automatically; teeth, gums
and tongue, eyeballs, lashes), the default avatar (the embedded portrait's face, with a lower row of
teeth and a mouth socket) and the generic face (MediaPipe's canonical mesh; no teeth). Each video is
tracked once and its Motion and FAPs made as ``pipeline.animate`` makes them (neutral found
automatically, One Euro filter on, no head motion); the animation is measured, not written.

Per (video, target, route): skin triangles turned over (normal more than 90 degrees from rest) in
any frame, and the frames with any; each teeth set's worst residual from rigid motion; the lower
incisors' motion over the chin's at the most open frame (the jaw turns about a hinge behind the
teeth, so the incisors move less than the chin, but not much less); how deep lip vertices go into
the teeth; the worst change of a skin edge's length; the chin's drop at the most open frame. Lengths
in cm (the targets' units told from their FAPU). A still of each target at its most open frame, beside
the video's frame, goes to ``results/surface_quality_<video>_<target>.png``. ``--quick``: d18 only,
the table printed, not written.
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from report import RESULTS, publish  # noqa: E402

DATA = Path(__file__).resolve().parents[1] / ".." / "shared" / "data"
VIDEOS = DATA / "videos"
ICT_MESH = DATA / "ict_facekit" / "obj" / "generic_neutral_mesh.obj"
ALL_VIDEOS = ("d18", "d10", "d6")
TARGETS = ("ict", "avatar", "generic")
TARGET_LABELS = {"ict": "ICT head", "avatar": "default avatar", "generic": "generic face"}
EXTRA_ROUTES = {("d18", "ict"): ("faps",)}  # runs besides the motion route

# Points on the inner lips (MediaPipe's, and MPEG-4's 2.2-2.9 where MediaPipe's are not named).
INNER_LIP_POINTS = ("mp13", "mp14", "mp78", "mp308", "mp82", "mp87", "mp312", "mp317",
                    "2.2", "2.3", "2.4", "2.5", "2.6", "2.7", "2.8", "2.9")
LIP_REACH = 0.12       # MW0: skin this close to an inner-lip point is lip (about 0.6 cm on a person)
INCISOR_DEPTH = 0.05   # MW0: lower-teeth vertices this close to the frontmost one are the incisors
STILL_SIZE = 320       # pixels, each half of a still

# ICT's materials, coloured like a face (its see-through overlays left out), as in roundtrip_ict.py.
ICT_COLOURS = {"M_Face": (214, 170, 140), "M_BackHead": (214, 170, 140), "M_ScleraLeft": (235, 235, 230),
               "M_ScleraRight": (235, 235, 230), "M_IrisLeft": (60, 45, 35), "M_IrisRight": (60, 45, 35),
               "M_EyeLashes": (30, 20, 15), "M_Teeth": (240, 235, 220), "M_GumsTongue": (150, 60, 60),
               "M_LacrimalFluid": None, "M_EyeOcclusion": None, "M_EyeBlend": None}


def missing() -> bool:
    """True, after saying so, when the videos or the ICT head are absent and the benchmark must skip."""
    needed = [VIDEOS / f"{v}.mp4" for v in ALL_VIDEOS] + [ICT_MESH]
    absent = [p for p in needed if not p.exists()]
    if absent:
        print(f"skipped: needs {absent[0]} (the shared data folder beside the checkout)")
        return True
    return False


@dataclass(frozen=True)
class Measured:
    """What is looked at on one target: vertex and triangle sets, fixed before any animation."""

    target: object
    parts: object
    cm: float                    # cm per model unit
    skin_triangles: np.ndarray   # (F,) bool
    skin_edges: np.ndarray       # (E, 2)
    upper_teeth: np.ndarray      # vertex ids, rigid with the skull (jaw weight 0)
    lower_teeth: np.ndarray      # vertex ids, rigid with the jaw (jaw weight 1)
    blended_teeth: int           # teeth vertices between the two (a gum-tongue piece split at the bite)
    teeth: np.ndarray            # vertex ids of every teeth vertex
    teeth_triangles: np.ndarray  # (G, 3), indexing ``teeth``
    incisors: np.ndarray         # vertex ids
    lips: np.ndarray             # vertex ids
    chin: int


def measured(target) -> Measured:
    """The sets the metrics need, from the target's parts (:func:`faceanim.parts.face_parts`)."""
    from faceanim.geometry.mesh import Mesh
    from faceanim.geometry.project import project_points
    from faceanim.geometry.quality import signed_distance
    from faceanim.mpeg4 import metres_per_unit
    from faceanim.parts import face_parts

    mesh = target.mesh
    parts = face_parts(target)
    skin = parts.mask("skin")
    skin_triangles = skin[mesh.triangles].all(axis=1)
    skin_edges = mesh.edges[skin[mesh.edges].all(axis=1)]
    upper_role, lower_role = parts.mask("upper_teeth"), parts.mask("lower_teeth")
    upper = np.flatnonzero(upper_role & (parts.jaw_weight == 0))
    lower = np.flatnonzero(lower_role & (parts.jaw_weight == 1))
    teeth_mask = upper_role | lower_role
    teeth = np.flatnonzero(teeth_mask)
    local_index = np.full(len(mesh.vertices), -1)
    local_index[teeth] = np.arange(len(teeth))
    teeth_triangles = local_index[mesh.triangles[teeth_mask[mesh.triangles].all(axis=1)]]
    z = parts.axes[2]
    mw0 = target.fapu.mw0
    incisors = np.array([], dtype=np.int64)
    if len(lower):
        front = mesh.vertices[lower] @ z
        incisors = lower[front >= front.max() - INCISOR_DEPTH * mw0]
    lips = np.array([], dtype=np.int64)
    if len(teeth_triangles):
        marks = mesh.vertices[[target.points[n] for n in INNER_LIP_POINTS if n in target.points]]
        skin_ids = np.flatnonzero(skin)
        near = np.linalg.norm(mesh.vertices[skin_ids, None] - marks[None], axis=2).min(axis=1) < LIP_REACH * mw0
        lips = skin_ids[near]
        # In front of the teeth at rest: outside them, and ahead of the closest teeth point along the face's z.
        teeth_rest = mesh.vertices[teeth]
        outside = signed_distance(mesh.vertices[lips], teeth_rest, teeth_triangles) > 0
        closest = project_points(Mesh(teeth_rest, teeth_triangles), mesh.vertices[lips]).points
        ahead = (mesh.vertices[lips] - closest) @ z > 0
        lips = lips[outside & ahead]
    return Measured(target, parts, 100.0 * metres_per_unit(target.fapu), skin_triangles, skin_edges, upper, lower,
                    int(teeth_mask.sum() - len(upper) - len(lower)), teeth, teeth_triangles, incisors, lips,
                    target.points["2.1"])


def scores(m: Measured, positions: np.ndarray) -> dict:
    """The table's numbers for one animation ``positions (T, V, 3)`` of ``m.target``."""
    from faceanim.geometry.quality import bend_change, edge_stretch, penetration_depth, rigid_residual, turned_over

    rest = m.target.mesh.vertices
    turned = turned_over(rest, positions, m.target.mesh.triangles, mask=m.skin_triangles)
    down = -m.parts.axes[1]
    drop = (positions[:, m.chin] - rest[m.chin]) @ down
    open_frame = int(np.argmax(drop))
    per_frame = turned.sum(axis=1)
    out = {"frames": len(positions), "turned": int(turned.any(axis=0).sum()),
           "turned_frames": int((per_frame > 0).sum()),
           "fold_frame": int(np.argmax(per_frame)) if per_frame.any() else None,
           "open_frame": open_frame,
           "chin_drop": float(drop[open_frame]) * m.cm,
           "stretch": float(edge_stretch(rest, positions, m.skin_edges).max())}
    skin = m.target.mesh.triangles[m.skin_triangles]
    out["bend"] = bend_change(rest, positions[open_frame][None], skin, percentile=[95, 99])[0].tolist()
    for name, ids in (("upper", m.upper_teeth), ("lower", m.lower_teeth)):
        out[name] = float(rigid_residual(rest[ids], positions[:, ids]).max()) * m.cm if len(ids) >= 3 else None
    out["ratio"] = None
    if len(m.incisors):
        chin_moved = np.linalg.norm(positions[open_frame, m.chin] - rest[m.chin])
        incisor_moved = np.linalg.norm((positions[open_frame, m.incisors] - rest[m.incisors]).mean(axis=0))
        out["ratio"] = float(incisor_moved / chin_moved) if chin_moved > 0 else None
    out["depth"] = None
    if len(m.lips):
        out["depth"] = float(penetration_depth(positions[:, m.lips], positions[:, m.teeth], m.teeth_triangles).max()
                             ) * m.cm
    return out


def animated(motion, stream, target, via: str) -> np.ndarray:
    """``(T, V, 3)``: what ``pipeline.animate`` computes for ``via``, without writing the ``.glb``."""
    from faceanim.retarget.decode import animate_faps
    from faceanim.retarget.follow import MINIMUM_SHARED_POINTS, animate_motion, shared_points

    if via == "motion" and len(shared_points(motion, target)) < MINIMUM_SHARED_POINTS:
        via = "faps"  # pipeline.animate falls back (with a warning) the same way
    if via == "motion":
        return animate_motion(motion, target, gaze=stream).positions
    return animate_faps(stream, target).positions


def video_frames(path, wanted) -> dict:
    """The frames numbered ``wanted`` of a video, ``{index: (H, W, 3) uint8}``, in one pass."""
    from faceanim.capture.video import open_frames

    wanted, found = set(wanted), {}
    with open_frames(path) as source:
        for index, (_, rgb) in enumerate(source):
            if index in wanted:
                found[index] = rgb
            if len(found) == len(wanted):
                break
    return found


def _fitted(image: np.ndarray, size: int) -> np.ndarray:
    """``image`` scaled into a black ``size`` x ``size`` square, centred."""
    from PIL import Image

    h, w = image.shape[:2]
    scale = size / max(h, w)
    small = np.asarray(Image.fromarray(image).resize((max(1, round(w * scale)), max(1, round(h * scale))),
                                                     Image.LANCZOS))
    canvas = np.zeros((size, size, 3), np.uint8)
    top, left = (size - small.shape[0]) // 2, (size - small.shape[1]) // 2
    canvas[top:top + small.shape[0], left:left + small.shape[1]] = small
    return canvas


def save_still(path: Path, renderer, target, positions: np.ndarray, frame: np.ndarray) -> None:
    """The video frame and the target at ``positions (V, 3)`` side by side, as a PNG."""
    from PIL import Image

    from faceanim.render.camera import front_camera

    mesh = target.mesh
    face = mesh.vertices[target.ids(list(target.points))]
    camera = front_camera(face, STILL_SIZE, STILL_SIZE, vertical_fov=20.0, margin=1.05)
    textured = mesh.texture is not None
    colours = ICT_COLOURS if not textured and set(ICT_COLOURS) & set(mesh.part_names) else None
    image = renderer.render(mesh, camera, positions=positions, mode="textured" if textured else "shaded",
                            part_colours=colours, light=(0.0, 0.5, 1.0))
    Image.fromarray(np.hstack([_fitted(frame, STILL_SIZE), image])).save(path, optimize=True)


def _cell(value, form: str) -> str:
    return "n/a" if value is None else format(value, form)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="d18 only (for development)")
    args = parser.parse_args(argv)
    if missing():
        return 0
    from faceanim.capture.track import track_video
    from faceanim.generic import generic_target
    from faceanim.inputs import load_target, motion_of_track
    from faceanim.motion import clip_to_range, motion_to_faps
    from faceanim.render.rasterizer import Renderer

    started = time.perf_counter()
    videos = ALL_VIDEOS[:1] if args.quick else ALL_VIDEOS
    loaders = {"ict": lambda: load_target(ICT_MESH), "avatar": lambda: load_target(None), "generic": generic_target}
    targets = {name: measured(loaders[name]()) for name in TARGETS}
    rows, stills, notes = [], [], []
    with Renderer(STILL_SIZE, STILL_SIZE) as renderer:
        for video in videos:
            path = VIDEOS / f"{video}.mp4"
            clock = time.perf_counter()
            recorded = track_video(path, progress=False)
            motion = motion_of_track(recorded)
            stream, _ = clip_to_range(motion_to_faps(motion, name=video))
            print(f"{video}: tracked {len(recorded)} frames in {time.perf_counter() - clock:.0f} s", flush=True)
            pending = []  # (png path, target name, positions at the most open frame, frame index)
            for name in TARGETS:
                m = targets[name]
                for via in ("motion", *EXTRA_ROUTES.get((video, name), ())):
                    clock = time.perf_counter()
                    positions = animated(motion, stream, m.target, via)
                    seconds = time.perf_counter() - clock
                    s = scores(m, positions)
                    s.update(video=video, target=name, via=via, seconds=seconds)
                    rows.append(s)
                    if via == "motion":
                        png = RESULTS / f"surface_quality_{video}_{name}.png"
                        pending.append((png, name, positions[s["open_frame"]].copy(), s["open_frame"]))
                    print(f"  {TARGET_LABELS[name]} via {via}: {seconds:.0f} s to animate, "
                          f"{time.perf_counter() - clock - seconds:.0f} s to measure", flush=True)
                    del positions
            frames = video_frames(path, [p[3] for p in pending])
            RESULTS.mkdir(exist_ok=True)
            for png, name, at, index in pending:
                save_still(png, renderer, targets[name].target, at, frames[index])
                stills.append((png.name, video, name, index))
    total = time.perf_counter() - started

    lines = ["# Surface quality on real videos: folds, teeth, lips, tears", "",
             f"`python benchmarks/surface_quality.py{' --quick' if args.quick else ''}` "
             f"({total / 60:.1f} min on this machine, tracking included). Each video tracked once, then the "
             "Motion and FAPs made as `faceanim animate` makes them (neutral found automatically, One Euro "
             "filter, no head motion) and each target animated as `animate --via motion` (or `--via faps`) "
             "does; the animation is measured, not written. Lengths in cm.", "",
             "| video | target | route | frames | skin triangles turned (goal 0) | frames with any | "
             "most folded frame | upper teeth non-rigid (cm, goal ≤ 0.02) | lower teeth non-rigid (cm, goal ≤ 0.02) | "
             "incisors / chin at most open (goal 0.5-1.2) | lips into teeth (cm) | worst skin edge stretch | "
             "skin bent at most open, p95 / p99 (°) | chin drop (cm) | most open frame | animate (s) |",
             "|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        lines.append(f"| {r['video']} | {TARGET_LABELS[r['target']]} | {r['via']} | {r['frames']} | {r['turned']} | "
                     f"{r['turned_frames']} | {_cell(r['fold_frame'], 'd')} | {_cell(r['upper'], '.4f')} | "
                     f"{_cell(r['lower'], '.4f')} | "
                     f"{_cell(r['ratio'], '.2f')} | {_cell(r['depth'], '.3f')} | {r['stretch']:.2f} | "
                     f"{r['bend'][0]:.1f} / {r['bend'][1]:.1f} | {r['chin_drop']:.2f} | {r['open_frame']} | "
                     f"{r['seconds']:.0f} |")
    for name, m in targets.items():
        notes.append(f"{TARGET_LABELS[name]}: {len(m.target.mesh.vertices):,} vertices, "
                     f"{int(m.skin_triangles.sum()):,} skin triangles, {len(m.skin_edges):,} skin edges; "
                     "teeth rigid with the skull "
                     f"{len(m.upper_teeth)}, with the jaw {len(m.lower_teeth)}, blended between "
                     f"{m.blended_teeth}; {len(m.incisors)} lower-incisor vertices; {len(m.lips)} lip vertices.")
    lines += ["", "How each column is measured (`faceanim.geometry.quality`):", "",
              "- *skin triangles turned*: triangles of three skin vertices whose normal turned by more than 90° "
              "from rest in any frame (`turned_over`); *frames with any*: frames holding at least one; "
              "*most folded frame*: the frame with the most.",
              "- *teeth non-rigid*: the worst distance, over frames, left after the best rigid fit of the set's rest "
              "shape (`rigid_residual`): the upper set is the teeth vertices of jaw weight 0, the lower those of jaw "
              "weight 1; vertices blended between (where a gum-and-tongue piece is split at the bite) are left out.",
              "- *incisors / chin*: at the frame where the chin (2.1) has dropped most, the length of the mean "
              f"displacement of the lower incisors (lower-teeth vertices within {INCISOR_DEPTH} MW0 of the frontmost, "
              "along the face's forward axis) over the length of the chin's.",
              "- *lips into teeth*: the deepest any lip vertex goes behind the teeth surface in any frame "
              "(`penetration_depth`, signed by the teeth's interpolated outward normal at the closest point). Lip "
              f"vertices: skin within {LIP_REACH} MW0 of the inner-lip points (MediaPipe 13, 14, 78, 308, 82, 87, "
              "312, 317 or MPEG-4 2.2-2.9) that lie outside the teeth and in front of them at rest.",
              "- *worst skin edge stretch*: the largest max(l / l0, l0 / l) over skin edges and frames "
              "(`edge_stretch`).",
              "- *skin bent*: at the most open frame, the 95th and 99th percentiles over skin edges of how far the "
              "angle between the edge's two triangles changed from rest (`bend_change`): creases the deformation "
              "adds (the jaw's turn, the fold fill) are edges bent far more than the rest.",
              "- *chin drop*: how far 2.1 moved down (the face's -y) at its most open frame.", "",
              "n/a: the target has no such part (the avatar has no upper teeth; the generic face no teeth).", "",
              *[f"- {n}" for n in notes], "",
              "Stills: the video frame (left) and the target at its most open frame (right); the ICT head shaded "
              "by material, the avatar textured, the generic face shaded.", ""]
    lines += [f"- {video}, {TARGET_LABELS[target]} (frame {index}): ![{video} {target}]({png})"
              for png, video, target, index in stills]
    if args.quick:  # a partial table: shown, not published
        print("\n".join(lines))
    else:
        publish("surface_quality.md", lines)
    return 0


if __name__ == "__main__":
    sys.exit(main())
