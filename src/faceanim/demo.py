"""``faceanim demo``: the whole chain on embedded material, with nothing to download.

1. The public-domain astronaut portrait that scikit-image ships becomes a 3D avatar (the tracker's mesh,
   textured from the photo).
2. A scripted MPEG-4 performance (jaw, smile, brows, blink) is decoded onto that avatar, and the
   photo is warped along the moving points with the image-warping RBF of Arad et al. (1994): a short
   video of the astronaut performing, whose true FAPs are known.
3. That video goes through the product as any user video would: tracked, encoded to FAPs
   (``demo.fap``), its tracked motion followed by the avatar (``demo.glb``), rendered beside the source
   (``preview.mp4``).
4. ``report.html`` says what ran and how long it took, compares the FAPs read back from the video with
   the scripted ones, and shows stills.
"""

from __future__ import annotations

import base64
import contextlib
import html
import io
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .mpeg4 import FAP_COUNT
from .mpeg4.fapstream import FapStream

__all__ = ["SCRIPT", "apex_frames", "scripted_stream", "run_demo", "view_command", "DemoResult"]

FPS = 25.0
DURATION = 4.4  # seconds; the first half second stays neutral, so the capture finds its rest pose there
# (name, start s, end s, {FAP number: apex value in its FAPU}); each rises and falls as a raised cosine.
SCRIPT = (
    ("jaw open", 0.6, 1.5, {3: 650}),
    ("smile", 1.5, 2.5, {12: 320, 13: 320, 6: 90, 7: 90}),
    ("brows up", 2.5, 3.4, {31: 160, 32: 160, 33: 180, 34: 180, 35: 140, 36: 140}),
    ("blink", 3.5, 3.9, {19: 950, 20: 950, 21: 120, 22: 120}),
)


def apex_frames() -> list[int]:
    """The frame at which each expression of :data:`SCRIPT` peaks (the middle of its window)."""
    return [int(FPS * 0.5 * (start + end)) for _, start, end, _ in SCRIPT]


def scripted_stream() -> FapStream:
    """The demo's performance as FAPs: :data:`SCRIPT` sampled at 25 fps."""
    times = np.arange(int(round(DURATION * FPS))) / FPS
    values = np.zeros((len(times), FAP_COUNT))
    for _, start, end, apex in SCRIPT:
        phase = np.clip((times - start) / (end - start), 0.0, 1.0)
        bump = 0.5 - 0.5 * np.cos(2 * np.pi * phase)
        for fap, value in apex.items():
            values[:, fap - 1] += value * bump
    mask = np.zeros_like(values, dtype=bool)
    mask[:, sorted({fap - 1 for *_, apex in SCRIPT for fap in apex})] = True
    return FapStream(values, mask, FPS, name="demo_script")


@dataclass
class DemoResult:
    """Where the demo wrote its outputs, and what it measured."""

    folder: Path
    outputs: dict
    steps: list = field(default_factory=list)  # (what ran, seconds)
    recovery: list = field(default_factory=list)  # (expression, FAPs, correlation, gain)


def run_demo(folder, *, progress=None) -> DemoResult:
    """Run the demo into ``folder`` (created if missing). Returns what it wrote and measured.
    ``progress``, a :class:`~faceanim.progress.Progress`, shows each step as it runs (quiet when None).

    Each step's outputs appear together when the step ends (see :func:`~faceanim.atomic.output_group`):
    the performance video, then the capture's glTF, FAPs and preview, then the report."""
    from .outputs import check_output_folder, check_outputs

    folder = check_output_folder("-o", folder)
    with _made_for(folder):
        result = DemoResult(folder, {name: folder / name for name in
                                     ("demo.glb", "preview.mp4", "demo.fap", "performance.mp4", "report.html")})
        for path in result.outputs.values():
            check_outputs({"-o": (path, path.suffix)})
        return _run_steps(result, progress)


@contextlib.contextmanager
def _made_for(folder: Path):
    """``folder`` made for the demo if missing, and removed again if the demo stops before putting
    anything in it (an error or Ctrl-C in its first step)."""
    made = not folder.exists()
    folder.mkdir(parents=True, exist_ok=True)
    try:
        yield
    except BaseException:
        if made and not any(folder.iterdir()):
            folder.rmdir()
        raise


def _run_steps(result: DemoResult, progress) -> DemoResult:
    """The demo's steps, each putting its outputs in place as it ends (see :func:`run_demo`)."""
    from . import pipeline, portrait
    from .atomic import output_group
    from .progress import as_progress
    from .render.video import video_writer

    shown = as_progress(progress)
    shown.status("making the avatar of the astronaut portrait")
    with _timed(result.steps, "the avatar: astronaut portrait tracked, face mesh built and textured"):
        image = face_crop(*portrait.portrait())
        landmarks = portrait.portrait_landmarks(image, "the embedded portrait")
        target = portrait.avatar_target(image=image, landmarks=landmarks)
    with _timed(result.steps, "the performance: scripted FAPs decoded on the avatar, the photo warped along "
                              "them (Arad's RBF)"):
        script = scripted_stream()
        frames = performance_frames(image, landmarks, target, script, progress=shown)
        with output_group(), video_writer(result.outputs["performance.mp4"], FPS, image.shape[1],
                                          image.shape[0]) as write:  # in place now: the capture reads it
            for frame in frames:
                write(frame)
    with _timed(result.steps, "the capture and retargeting: video tracked, encoded to FAPs, its motion "
                              "followed by the avatar, glTF, preview video"):
        with output_group():  # in place when the step ends: the report's stills are read from the preview
            animation, recovered = pipeline.animate(
                result.outputs["performance.mp4"], result.outputs["demo.glb"], target=target,
                preview=result.outputs["preview.mp4"], fap=result.outputs["demo.fap"], progress=shown)
    result.recovery = fap_recovery(script, recovered)
    stills = _stills(result.outputs["preview.mp4"], apex_frames())
    _write_report(result, stills, frames=len(animation), vertices=len(target.mesh.vertices),
                  curves=_curves_png(recovered))
    return result


def face_crop(image: np.ndarray, name: str, *, size: int = 480) -> np.ndarray:
    """The portrait cut to a square around its face and scaled to ``size``, so the face fills the video."""
    from PIL import Image

    from . import portrait

    pixels = portrait.portrait_landmarks(image, name)[:, :2] * image.shape[1::-1]
    centre = 0.5 * (pixels.min(axis=0) + pixels.max(axis=0)) - [0.0, 0.05 * np.ptp(pixels[:, 1])]
    half = min(1.1 * np.ptp(pixels, axis=0).max(), 0.5 * min(image.shape[:2]))
    left, top = np.clip(np.rint(centre - half), 0, np.array(image.shape[1::-1]) - 2 * half).astype(int)
    side = int(round(2 * half))
    crop = Image.fromarray(image[top:top + side, left:left + side])
    return np.asarray(crop.resize((size, size), Image.LANCZOS))


def performance_frames(image: np.ndarray, landmarks: np.ndarray, target, stream, *,
                       progress=None) -> list[np.ndarray]:
    """The portrait warped frame by frame as ``stream`` moves the avatar's tracker points (shown on
    ``progress``, a :class:`~faceanim.progress.Progress`, when given).

    The avatar's points move in 3D (centimetres, head frame); a weak-perspective camera fitted to where
    the same points sit in the photo carries their motion into pixels.
    """
    from .geometry.imagewarp import ImageWarp
    from .progress import as_progress
    from .retarget.decode import animate_faps

    height, width = image.shape[:2]
    pixels = landmarks[:468, :2] * [width, height]
    rest = target.mesh.vertices[:468]
    camera, *_ = np.linalg.lstsq(np.column_stack([rest, np.ones(len(rest))]), pixels, rcond=None)
    motion = animate_faps(stream, target).positions[:, :468] - rest
    moved = motion @ camera[:3]
    centre, radius = pixels.mean(axis=0), 0.5 * np.ptp(pixels, axis=0)
    angles = np.linspace(0, 2 * np.pi, 32, endpoint=False)
    ring = centre + np.column_stack([np.cos(angles), np.sin(angles)]) * radius * [1.3, 1.45]
    warp = ImageWarp(pixels, width, height, fixed=ring)
    return [warp(image, d) for d in as_progress(progress).bar(moved, total=len(moved), desc="filming the performance")]


def fap_recovery(script, recovered) -> list[tuple[str, str, float, float]]:
    """Per scripted expression: the correlation over the clip between scripted and recovered FAPs (pooled
    over the expression's FAPs), and the gain (recovered / scripted, least squares)."""
    rows = []
    for name, _, _, apex in SCRIPT:
        columns = [fap - 1 for fap in apex]
        truth = script.values[:, columns].ravel()
        found = np.where(recovered.mask[:, columns], recovered.values[:, columns], 0.0).ravel()
        correlation = float(np.corrcoef(truth, found)[0, 1]) if found.std() > 0 else 0.0
        gain = float(truth @ found / (truth @ truth))
        rows.append((name, " ".join(str(f) for f in apex), correlation, gain))
    return rows


@contextlib.contextmanager
def _timed(steps: list, what: str):
    """Append ``(what, seconds)`` to ``steps`` when the block ends without error."""
    start = time.perf_counter()
    yield
    steps.append((what, time.perf_counter() - start))


def _stills(video, indices) -> list[tuple[int, str]]:
    """``(frame, base64 JPEG)`` of the preview at ``indices``."""
    from PIL import Image

    from .capture.video import open_frames

    wanted, found = set(indices), []
    with open_frames(video) as frames:
        for i, (_, frame) in enumerate(frames):
            if i in wanted:
                buffer = io.BytesIO()
                Image.fromarray(frame).save(buffer, format="JPEG", quality=85)
                found.append((i, base64.b64encode(buffer.getvalue()).decode()))
    return found


def view_command(result: DemoResult) -> str:
    """The command that opens the demo's outputs in the web viewer."""
    o = result.outputs
    return f"faceanim view {o['demo.glb']} --video {o['performance.mp4']} --fap {o['demo.fap']}"


def _curves_png(stream) -> str | None:
    """``stream``'s FAP curves drawn as ``faceanim plot`` draws them (a panel per group, each on its own
    scale and unit), as a base64 PNG for the report; None without matplotlib (the ``plot`` extra)."""
    from .export.plots import fap_png

    try:
        png = fap_png(stream, title="FAPs read back from the performance", dpi=80)
    except ImportError:
        return None
    return base64.b64encode(png).decode("ascii")


def _write_report(result: DemoResult, stills, *, frames: int, vertices: int, curves: str | None = None) -> None:
    from .atomic import atomic_output

    total = sum(seconds for _, seconds in result.steps)
    steps = "".join(f"<tr><td>{html.escape(what)}</td><td>{seconds:.1f} s</td></tr>" for what, seconds in result.steps)
    recovery = "".join(f"<tr><td>{name}</td><td>{faps}</td><td>{corr:.2f}</td><td>{gain:.2f}</td></tr>"
                       for name, faps, corr, gain in result.recovery)
    names = dict(zip(apex_frames(), (name for name, *_ in SCRIPT), strict=True))
    pictures = "".join(f'<figure><img src="data:image/jpeg;base64,{data}" alt="frame {i}">'
                       f"<figcaption>frame {i}: {names.get(i, '')}</figcaption></figure>" for i, data in stills)
    plot = ("<p>(The FAP curves are drawn with matplotlib: <code>pip install 'faceanim[plot]'</code>.)</p>"
            if curves is None else f'<img class="curves" src="data:image/png;base64,{curves}" '
                                   'alt="the FAP curves read back, a panel per group">')
    links = " · ".join(f'<a href="{path.name}">{path.name}</a>' for key, path in result.outputs.items()
                       if key != "report.html")
    page = f"""<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>faceanim demo</title>
<style>
body {{ font: 15px/1.5 system-ui, sans-serif; max-width: 60rem; margin: 2rem auto; padding: 0 1rem; color: #222; }}
table {{ border-collapse: collapse; margin: 0.5rem 0 1.5rem; }}
td, th {{ border-bottom: 1px solid #ddd; padding: 0.25rem 0.75rem; text-align: left; }}
figure {{ display: inline-block; margin: 0 0.5rem 0.5rem 0; }} img {{ width: 28rem; }}
video {{ width: 100%; max-width: 58rem; }} img.curves {{ width: 100%; max-width: 58rem; }}
</style></head><body>
<h1>faceanim demo</h1>
<p>The astronaut portrait that scikit-image ships (Eileen Collins, NASA, public domain) was made into a 3D
avatar, made to perform a scripted expression sequence by warping the photo (Arad et al.'s RBF image
warp), and that video was then tracked, encoded to MPEG-4 FAPs and retargeted onto the avatar:
{frames} frames onto {vertices:,} vertices.</p>
<p>Outputs: {links}</p>
<p>Watch it in the viewer (face, source video and FAP curves in step):
<code>{html.escape(view_command(result))}</code>, then open
<a href="http://127.0.0.1:8765/">http://127.0.0.1:8765/</a>.</p>
<video src="preview.mp4" controls loop muted></video>
<h2>What ran</h2>
<table><tr><th>step</th><th>time</th></tr>{steps}<tr><th>total</th><th>{total:.1f} s</th></tr></table>
<h2>FAPs read back from the video</h2>
<p>The performance's true FAPs are known, so the capture can be scored: correlation over the clip between
the scripted and the recovered FAP curves, and the gain (recovered / scripted; 1 is exact).</p>
<table><tr><th>expression</th><th>FAPs</th><th>correlation</th><th>gain</th></tr>{recovery}</table>
{plot}
<h2>Stills (source | animated avatar)</h2>
{pictures}
</body></html>
"""
    with atomic_output(result.outputs["report.html"], suffix=".html") as tmp:
        tmp.write_text(page)
