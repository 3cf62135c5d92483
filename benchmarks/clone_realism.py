"""The speaker clone's realism and speed (issue 18, the appearance half).

    flock /tmp/faceanim-bench.lock python benchmarks/clone_realism.py

For ``speech_man.mp4`` and ``speech_woman.mp4``: the video is tracked as ``faceanim speaker build``
tracks it; the model (guided, 6 parameters) and its appearance (camera, key postures, textures, colour
model: ``faceanim speaker textures``) are made from the first 70% of the frames only. Each held-out
frame (the last 30%) is re-rendered over itself from its landmark-based parameters
(``SpeakerModel.fit_points`` of its tracked points) and its rigid motion (the capture's pose), and its
mouth region (the box of the tracked outer lip contour, widened by half its height and a quarter of
its width on each side) is compared with the real frame: PSNR (dB, over RGB) and SSIM
(``skimage.metrics.structural_similarity``, RGB, default 7x7 window). The same with a single texture
(the rest key posture's alone) against the multi-texture blend (three key postures). Median and worst
over the held-out frames of each clip.

Speed: a 512x512 clone over a 512x512 background, parameters of the held-out frames in turn,
frames/s of ``CloneRenderer.render`` with the mix in the shader and with the mix in numpy (one texture
upload per frame), median and worst of 5 runs of 100 frames.

Complexity: the synthesis mesh against the original's bounds (<= 250 mobile points, <= 200 static
points, <= 700 triangles, 3 textures of 512x512). Camera: the reprojection error of the fit (pixels,
on the build frames). Writes ``benchmarks/results/clone_realism.md`` and side-by-side stills
``clone_<clip>_<frame>.png`` (real | blend | single texture, mouth region, 2x).
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from report import RESULTS, publish  # noqa: E402

os.environ.setdefault("GLOG_minloglevel", "2")
VIDEOS = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "videos"
CLIPS = ("speech_man", "speech_woman")
BUILD_SHARE = 0.7
RUNS, FRAMES_PER_RUN, SPEED_SIZE = 5, 100, 512


def all_frames(path) -> list[np.ndarray]:
    from faceanim.capture.video import open_frames

    with open_frames(path) as source:
        return [rgb for _, rgb in source]


def mouth_box(landmarks, width: int, height: int) -> tuple[slice, slice]:
    from faceanim.landmarks import LIP_OUTER

    xy = landmarks[list(LIP_OUTER), :2] * [width, height]
    (x0, y0), (x1, y1) = xy.min(axis=0), xy.max(axis=0)
    dx, dy = 0.25 * (x1 - x0), 0.5 * (y1 - y0)
    return (slice(max(0, int(y0 - dy)), min(height, int(np.ceil(y1 + dy)))),
            slice(max(0, int(x0 - dx)), min(width, int(np.ceil(x1 + dx)))))


def single(appearance):
    """The appearance with the rest key posture alone."""
    from dataclasses import replace

    return replace(appearance, key_parameters=appearance.key_parameters[:1], key_points=appearance.key_points[:1],
                   textures=appearance.textures[:1], lip_textures=appearance.lip_textures[:1],
                   influence=np.ones(1), key_frames=appearance.key_frames[:1], key_rigid=appearance.key_rigid[:1],
                   key_names=appearance.key_names[:1])


def scores(real: np.ndarray, made: np.ndarray) -> tuple[float, float]:
    from skimage.metrics import peak_signal_noise_ratio, structural_similarity

    return (peak_signal_noise_ratio(real, made, data_range=255),
            structural_similarity(real, made, channel_axis=2, data_range=255))


def clip_figures(clip: str, stills: list | None, *, speed: bool = True) -> dict:
    from PIL import Image

    from faceanim.capture.track import track_video
    from faceanim.inputs import motion_of_track
    from faceanim.speaker import build_model
    from faceanim.speaker.clone import CloneRenderer
    from faceanim.speaker.texturing import build_appearance

    path = VIDEOS / f"{clip}.mp4"
    track = track_video(path, progress=False)
    motion = motion_of_track(track, floor=False)  # as speaker textures
    images = all_frames(path)
    T = len(motion)
    cut = int(BUILD_SHARE * T)
    build = np.arange(cut)
    model = build_model(motion, frames=build)
    appearance, fit = build_appearance(
        model, names=motion.names, points=motion.neutral + motion.displacements, landmarks=track.landmarks[..., :2],
        pose=motion.pose, valid=motion.valid, width=track.width, height=track.height,
        read_frames=lambda indices: [images[i] for i in indices], frames=build)
    held = np.array([t for t in range(cut, T) if motion.valid[t]])
    parameters = model.fit_points(motion.displacements[:, motion.index(model.names)])
    results = {"blend": [], "single": []}
    keep = set(held[[len(held) // 4, len(held) // 2, 3 * len(held) // 4]].tolist())
    with CloneRenderer(model, appearance) as blended, CloneRenderer(model, single(appearance)) as alone:
        for t in held:
            rows, columns = mouth_box(track.landmarks[t], track.width, track.height)
            real = images[t]
            made = {}
            for name, renderer in (("blend", blended), ("single", alone)):
                image = renderer.render(parameters[t], fit.rigid[t], background=real)
                made[name] = image[rows, columns]
                results[name].append(scores(real[rows, columns], made[name]))
            if t in keep and stills is not None:
                strip = np.concatenate([real[rows, columns], made["blend"], made["single"]], axis=1)
                still = Image.fromarray(strip)
                still = still.resize((2 * still.width, 2 * still.height), Image.Resampling.LANCZOS)
                name = f"clone_{clip}_{t}.png"
                still.save(RESULTS / name)
                stills.append(name)
        rates_of = {}
        for blend in ("shader", "cpu") if speed else ():
            with CloneRenderer(model, appearance, width=SPEED_SIZE, height=SPEED_SIZE, blend=blend) as small:
                background = np.full((SPEED_SIZE, SPEED_SIZE, 3), 90, dtype=np.uint8)
                small.render(parameters[held[0]], fit.rigid[held[0]], background=background)  # warm-up
                rates = []
                for _ in range(RUNS):
                    start = time.perf_counter()
                    for i in range(FRAMES_PER_RUN):
                        t = held[i % len(held)]
                        small.render(parameters[t], fit.rigid[t], background=background)
                    rates.append(FRAMES_PER_RUN / (time.perf_counter() - start))
                rates_of[blend] = rates
        rates_of["load"] = os.getloadavg()[0]
    used = np.unique(appearance.triangles)
    P = len(model.names)
    weights = appearance.weights(np.concatenate([model.points(parameters[held]), np.broadcast_to(
        model.static_points, (len(held), *model.static_points.shape))], axis=1))
    return {"clip": clip, "frames": T, "build": cut, "held": len(held), "results": results, "speed": rates_of,
            "mobile": int((used < P).sum()), "static": int((used >= P).sum()), "triangles": len(appearance.triangles),
            "textures": appearance.textures.shape, "camera": fit, "keys": appearance.key_frames,
            "weights": weights, "model_triangles": len(model.triangles), "model_static": len(model.static_names)}


def main() -> None:
    stills: list[str] = []
    figures = [clip_figures(clip, stills) for clip in CLIPS if (VIDEOS / f"{clip}.mp4").exists()]
    if not figures:
        print("no speech clips in ../shared/data/videos: nothing measured")
        return
    lines = ["# The speaker clone: realism of the re-rendered mouth, speed, complexity (issue 18)", "",
             "`flock /tmp/faceanim-bench.lock python benchmarks/clone_realism.py`; model and appearance from the "
             "first 70% of each clip, scored on the held-out 30% (landmark-based parameters and the capture's "
             "pose); mouth region = the tracked outer lip contour's box, widened. SSIM: skimage.metrics. The "
             "key-posture rule and the blend's power of the distance were chosen on the talking clips d12 and d20, "
             "not on these.", "",
             "## Realism (held-out frames, mouth region)", "",
             "| clip | held-out frames | texturing | PSNR median (dB) | PSNR worst | SSIM median | SSIM worst | "
             "blend better (PSNR) |", "|---|---|---|---|---|---|---|---|"]
    for f in figures:
        blend, alone = np.array(f["results"]["blend"]), np.array(f["results"]["single"])
        wins = int((blend[:, 0] > alone[:, 0]).sum())
        for name, r in (("blend of 3 keys", blend), ("rest texture alone", alone)):
            lines.append(f"| {f['clip']} | {f['held']} | {name} | {np.median(r[:, 0]):.2f} | {r[:, 0].min():.2f} | "
                         f"{np.median(r[:, 1]):.4f} | {r[:, 1].min():.4f} | "
                         + (f"{wins} of {f['held']} |" if name.startswith("blend") else "|"))
    lines += ["", "## Rendering speed (512x512 clone over a 512x512 background, frames/s, 5 runs of 100 frames; "
              "2 cores, Mesa llvmpipe)", "", "| clip | mix | median | worst |", "|---|---|---|---|"]
    for f in figures:
        for blend, rates in f["speed"].items():
            if blend == "load":
                continue
            lines.append(f"| {f['clip']} | {'shader (Q samplers)' if blend == 'shader' else 'numpy, one texture'} | "
                         f"{np.median(rates):.1f} | {min(rates):.1f} |")
    lines += ["", "Load average (1 minute) after each clip's speed runs: " + ", ".join(
        f"{f['clip']} {f['speed']['load']:.1f}" for f in figures if "load" in f["speed"])
        + " (the timings run under the bench lock, but the 2 cores are shared with other work).",
        "", "## Complexity (synthesis mesh) and camera", "",
              "| clip | mobile points (<= 250) | static points (<= 200) | triangles (<= 700) | textures | "
              "model's own mesh | key frames (rest, open, rounded) | reprojection median / worst frame / worst point "
              "(px) |", "|---|---|---|---|---|---|---|---|"]
    for f in figures:
        cam, (Q, S, _, _) = f["camera"], f["textures"]
        lines.append(f"| {f['clip']} | {f['mobile']} | {f['static']} | {f['triangles']} | {Q} of {S}x{S} | "
                     f"{f['model_static']} static, {f['model_triangles']} triangles | "
                     f"{', '.join(str(k) for k in f['keys'])} | {cam.median_px:.2f} / {cam.worst_frame_px:.2f} / "
                     f"{cam.worst_point_px:.2f} |")
    lines += ["", "Blending weights over the held-out frames (mean, and the largest change between consecutive "
              "frames):", ""]
    for f in figures:
        w = f["weights"]
        lines.append(f"- {f['clip']}: mean {np.round(w.mean(axis=0), 3).tolist()}, largest step "
                     f"{np.abs(np.diff(w, axis=0)).max():.3f}")
    lines += ["", "Stills (real | blend | rest texture alone): " + ", ".join(f"`{s}`" for s in stills)]
    publish("clone_realism.md", lines)


if __name__ == "__main__":
    main()
