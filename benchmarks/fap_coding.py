"""FAP coding through the speaker model: PSNR against bit rate (issue 17, part 4; the ICP figure).

    flock /tmp/faceanim-bench.lock python benchmarks/fap_coding.py

For ``speech_man.mp4`` and ``speech_woman.mp4``, two settings:

* **the model's own stream** (the original's setting): the guided 6-parameter model built on the whole
  clip (as ``faceanim speaker build`` does), and the stream ``faceanim speaker analyse`` makes of the
  same clip with it (34 FAPs: lips, jaw, chin, cheeks, nose; whole FAPU counts as in the ``.fap``),
  decoded through the model knowing the quantiser (``regularise(quant=...)``: each FAP weighed by its
  step) as ``faceanim fap-decompress --speaker`` does;
* **the honest case**: the tracked FAPs of the video itself (``motion_to_faps`` of the capture, as
  ``faceanim encode`` writes them, on the model's 34 FAPs) on alternate 2-second blocks, decoded
  through a model built on the other blocks (both folds, their streams joined), with ``regularise``'s
  default weights (cm: the error here is the model's misfit of real motion, not quantisation); the
  step-weighted decoding is reported beside it.

Each stream is coded by ``faceanim.mpeg4.fapcoder.encode_faps`` (packets of 1 s, the default) at
quantiser scales ``quant`` from 0.5 to 64 and decoded: (a) all 34 FAPs coded, decoded as they are; (b)
the same decoded through the speaker model as ``fap-decompress --speaker`` does by default: the
temporal prior as a smoother within each packet, every FAP kept within its quantiser cell
(``regularise(temporal=True, window=packet)``); (bc) through the prior's causal filter, frame by frame
(``--causal``), and (b0) each frame alone (``--frame-by-frame``); (c) only 26 (the lips and jaw, 3-18
and 51-60), 8 (3, 14, 16, 17, 51-54) or 6 (3, 16, 51-54) FAPs coded, decoded as (b), which fills in
the rest.

Why the gain of (b) over (a) holds where it does, on the own stream: the error of (a) is measured in
quantiser steps, each FAP weighed as the interpretation weighs it; its share in the model's span (the
part a projection onto the 6 parameters keeps; white noise: 6/34, so a projection removes at most
10 log10(34/6) = 7.5 dB) and its correlation from one frame to the next (the part a temporal prior
cannot average away) are given per ``quant``, with the floor: (b) at the finest step, where what is
left is the stream's own rounding to whole FAPU, which no model reproduces. Also the cost of the
container's packets (the decoder's delay) in kbit/s.

The model's FAPs were 30 until the nose's 61-64 joined them (the ICP figure's stream held ~36); the
PSNR is over the 34 now, so it is not comparable digit for digit with results from before.

FAP PSNR (``fapcoder.fap_psnr``): 20 log10 of the peak-to-peak range of the original FAPs over the RMS
error, pooled over the 34 FAPs of the original on every frame (sent or filled in; a FAP a decoder
does not fill in counts as its held value). Rate: kbit/s at the video's frame rate, of the whole
``.fba`` (header, masks and end check included) and of the range coder's payload alone. The gain of
(b) over (a) at equal rate interpolates (b)'s curve (PSNR against log rate) at each of (a)'s rates.
Writes ``benchmarks/results/fap_coding.md`` and ``fap_coding.png``.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from report import RESULTS, publish  # noqa: E402

os.environ.setdefault("GLOG_minloglevel", "2")
VIDEOS = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "videos"
CLIPS = ("speech_man", "speech_woman")
QUANTS = (0.5, 1, 2, 4, 8, 16, 32, 64)
SUBSETS = {"26": tuple(range(3, 19)) + tuple(range(51, 61)), "8": (3, 14, 16, 17, 51, 52, 53, 54),
           "6": (3, 16, 51, 52, 53, 54)}
CURVES = ("a: 34 coded", "b: 34 through the model", "bc: 34 through the model, causal filter",
          "b0: 34 through the model frame by frame", "c: 26 through the model", "c: 8 through the model",
          "c: 6 through the model")
EIGHT = CURVES[5]
PACKETS = (1, 5, None, 10**6)  # frames per packet; None: the default (1 s); 10**6: one for the whole clip


def payload_bytes(data: bytes) -> int:
    """The range coder's words in an ``.fba`` of version 2 (4 bytes each), found by walking its packets as
    ``faceanim.mpeg4.fapcoder``'s docstring lays them out."""
    from faceanim.mpeg4.fapcoder import _HEAD

    def varint(at):
        value = shift = 0
        while True:
            byte = data[at]
            value |= (byte & 0x7F) << shift
            at, shift = at + 1, shift + 7
            if not byte & 0x80:
                return value, at

    _, version, flags, _, _, frames, sent = _HEAD.unpack_from(data)
    if version != 2:
        raise ValueError("the .fba's layout is not the one this benchmark reads")
    at = _HEAD.size
    at += 1 + data[at]  # the name
    at += 4 if flags & 1 else 0  # the first frame's number
    width = (int(np.unpackbits(np.frombuffer(sent, np.uint8))[:68].sum()) + 7) // 8
    done = words = 0
    while done < frames:
        runs, at = varint(at)
        count = 0
        for _ in range(runs):
            code, at = varint(at)
            count += code >> 1
            at += 0 if code & 1 else width
        at += 0 if flags & 1 else 4 * count
        n, at = varint(at)
        at += 4 * n
        words += n
        done += count
    if at + 4 != len(data):
        raise ValueError("the .fba's layout is not the one this benchmark reads")
    return 4 * words


def model_stream(motion, model, frames):
    """The speaker analyse stream of ``frames`` of ``motion`` (whole counts, as in the ``.fap``)."""
    from faceanim.mpeg4.fapstream import FapStream

    d = motion.displacements[frames][:, motion.index(model.names)]
    stream = model.to_faps(model.fit_points(d), fps=motion.fps)
    return FapStream(np.rint(stream.values), stream.mask, stream.fps)


def tracked_stream(faps, model, frames):
    """The tracked FAPs of ``frames`` (as encode writes them) on the model's FAPs only."""
    from faceanim.motion import clip_to_range
    from faceanim.mpeg4.fapstream import FapStream

    keep = np.zeros(faps.mask.shape[1], bool)
    keep[model.fap_columns] = True
    stream, _ = clip_to_range(faps)
    return FapStream(np.rint(stream.values[frames]), stream.mask[frames] & keep, stream.fps)


def curves(pieces, *, weigh: str = "steps") -> dict:
    """{curve: [(quant, kbit/s, payload kbit/s, PSNR)]} over ``pieces``: [(original stream, model)] coded
    separately, rates and errors pooled. ``weigh``: the interpretation's weights, "steps" (each FAP by
    its quantiser step, ``regularise(quant=...)``) or "cm" (the default of ``regularise``)."""
    from faceanim.mpeg4.fapcoder import decode_faps, encode_faps
    from faceanim.mpeg4.fapstream import FapStream, held

    out = {name: [] for name in CURVES}
    for quant in QUANTS:
        for name in CURVES:
            bits = payload = seconds = 0.0
            errors, originals = [], []
            for original, model in pieces:
                sent = None if name.startswith(("a", "b")) else SUBSETS[name.split()[1]]
                data = encode_faps(original, quant=quant, faps=sent)
                decoded = decode_faps(data)
                if not name.startswith("a"):
                    window = None if name.startswith(("bc", "b0")) else packet_of(original)
                    decoded = model.regularise(decoded, quant=quant if weigh == "steps" else None,
                                               temporal=not name.startswith("b0"), window=window)
                decoded = FapStream(decoded.values, decoded.mask, decoded.fps)
                where = original.mask
                errors.append((held(decoded) - original.values)[where])
                originals.append(original.values[where])
                bits += 8 * len(data)
                payload += 8 * payload_bytes(data)
                seconds += len(original) / original.fps
            truth = np.concatenate(originals)
            rms = np.sqrt(np.mean(np.concatenate(errors) ** 2))
            psnr = 20 * np.log10(np.ptp(truth) / rms) if rms > 0 else np.inf
            out[name].append((quant, bits / seconds / 1000, payload / seconds / 1000, psnr))
    return out


def packet_of(stream) -> int:
    """The frames of a packet that encode_faps makes by default (1 s): the decoder's smoothing window."""
    from faceanim.mpeg4.fapcoder import PACKET_SECONDS

    return max(1, round(PACKET_SECONDS * stream.fps))


def error_structure(original, model) -> list[str]:
    """Per quant, the coding error of (a) on the model's own stream in quantiser steps: its RMS, its
    share in the model's span (weighted as the interpretation weighs it), its lag-one correlation, the
    projection's measured gain (b0 - a) against the white-noise bound, and (bc), (b) beside them."""
    from faceanim.mpeg4 import fap_table
    from faceanim.mpeg4.fapcoder import decode_faps, encode_faps, fap_psnr

    j, G = model.fap_columns, model.fap_matrix
    lines = ["| quant | (a) error, RMS steps | in the model's span | lag-1 correlation | projection's bound | "
             "b0 - a | bc - a | b - a |", "|---:|---:|---:|---:|---:|---:|---:|---:|"]
    bound = 10 * np.log10(len(j) / model.parameter_count)
    for quant in QUANTS:
        decoded = decode_faps(encode_faps(original, quant=quant))
        step = fap_table().quant_step[j] * quant
        e = (decoded.values[:, j] - original.values[:, j]) / step
        W = G / step[:, None]
        inside = ((e @ (W @ np.linalg.pinv(W)).T) ** 2).sum() / (e**2).sum()
        lag = (e[1:] * e[:-1]).sum() / (e**2).sum()
        a = fap_psnr(original, decoded)
        gains = [fap_psnr(original, model.regularise(decoded, quant=quant, temporal=t, window=w)) - a
                 for t, w in ((False, None), (True, None), (True, packet_of(original)))]
        lines.append(f"| {quant:g} | {np.sqrt((e**2).mean()):.2f} | {100 * inside:.0f}% | {lag:.2f} | "
                     f"{10 * np.log10(1 / max(inside, 1e-9)):.1f} dB (white: {bound:.1f}) | "
                     + " | ".join(f"{g:+.1f} dB" for g in gains) + " |")
    return lines


def packet_costs(pieces) -> list[str]:
    """kbit/s of the whole .fba against the frames per packet (the decoder's delay), pooled over ``pieces``."""
    from faceanim.mpeg4.fapcoder import encode_faps

    lines = ["| FAPs | quant | " + " | ".join("1 s (default)" if p is None else "whole clip" if p == 10**6 else
                                             f"{p} frame{'s' * (p > 1)}" for p in PACKETS) + " |",
             "|---|---:|" + "---:|" * len(PACKETS)]
    for label, sent in (("34", None), ("8", SUBSETS["8"])):
        for quant in (1, 8, 32):
            cells = []
            for packet in PACKETS:
                bits = seconds = 0.0
                for original, _ in pieces:
                    bits += 8 * len(encode_faps(original, quant=quant, faps=sent, packet=packet))
                    seconds += len(original) / original.fps
                cells.append(f"{bits / seconds / 1000:.2f}")
            lines.append(f"| {label} | {quant:g} | " + " | ".join(cells) + " |")
    return lines


def gain_at_equal_rate(a, b) -> list[tuple[float, float]]:
    """(rate, PSNR of b interpolated at that rate minus a's) at each of a's rates inside b's range."""
    rb = np.log([r for _, r, _, _ in b])
    pb = np.array([p for *_, p in b])
    order = np.argsort(rb)
    gains = []
    for _, rate, _, psnr in a:
        x = np.log(rate)
        if rb.min() <= x <= rb.max():
            gains.append((rate, float(np.interp(x, rb[order], pb[order]) - psnr)))
    return gains


def where_at_least(gains, level=7.0) -> str:
    """The rates (a's) at which the gain reaches ``level`` dB, as the span from the lowest to the highest
    (and how many of the rates between fall short)."""
    rates = [r for r, g in gains if g >= level]
    if not rates:
        return f"nowhere (largest {max(g for _, g in gains):+.1f} dB)" if gains else "nowhere"
    inside = [g for r, g in gains if min(rates) <= r <= max(rates)]
    short = sum(g < level for g in inside)
    return f"{min(rates):.2f} to {max(rates):.2f} kbit/s" + (f" ({short} rate(s) between short of it)" if short else "")


def worst_faps(pieces, quant=0.5, weigh="cm") -> str:
    """The three FAPs the model misses most (RMS, FAPU) on ``pieces`` decoded through it, finely coded."""
    from faceanim.mpeg4 import fap_table
    from faceanim.mpeg4.fapcoder import decode_faps, encode_faps

    table = fap_table()
    squared, count = 0.0, 0
    for original, model in pieces:
        decoded = model.regularise(decode_faps(encode_faps(original, quant=quant)),
                                   quant=quant if weigh == "steps" else None, temporal=True)
        squared = squared + ((decoded.values - original.values) ** 2 * original.mask).sum(axis=0)
        count = count + original.mask.sum(axis=0)
    rms = np.sqrt(squared / np.maximum(count, 1))
    top = np.argsort(-rms)[:3]
    return ", ".join(f"{j + 1} {table.names[j]} {rms[j]:.0f}" for j in top)


def main() -> None:
    from faceanim.inputs import capture_motion
    from faceanim.motion import motion_to_faps
    from faceanim.speaker import build_model

    settings = {}
    for clip in CLIPS:
        motion = capture_motion(VIDEOS / f"{clip}.mp4", progress=False, floor=False)  # as speaker build
        faps = motion_to_faps(motion)
        everything = np.flatnonzero(motion.valid)
        model = build_model(motion, parameters=6)
        settings[clip, "own"] = [(model_stream(motion, model, everything), model)]
        block = (np.arange(len(motion)) // int(round(2 * motion.fps))) % 2
        honest = []
        for fold in (0, 1):
            other = build_model(motion, parameters=6, frames=block != fold)
            honest.append((tracked_stream(faps, other, np.flatnonzero((block == fold) & motion.valid)), other))
        settings[clip, "honest"] = honest
        print(f"{clip}: {len(motion)} frames at {motion.fps:g} fps", flush=True)
    results = {(clip, setting): curves(pieces, weigh="steps" if setting == "own" else "cm")
               for (clip, setting), pieces in settings.items()}
    by_steps = {clip: curves(settings[clip, "honest"], weigh="steps") for clip in CLIPS}
    lines = ["# FAP coding through the speaker model: PSNR against bit rate", "",
             "`flock /tmp/faceanim-bench.lock python benchmarks/fap_coding.py` (see the script for the settings). "
             "PSNR: 20 log10(peak-to-peak range of the original's 34 FAPs / RMS error over them, sent or filled "
             "in). kbit/s of the whole .fba (header, masks, end check), payload-only in brackets. own: the "
             "stream speaker analyse makes with the model built on the whole clip; honest: the tracked FAPs "
             "(encode's) of alternate 2-second blocks through a model built on the other blocks. b and c: through "
             "the model as fap-decompress --speaker decodes by default (the temporal prior as a smoother within "
             "each 1 s packet, every FAP kept within its quantiser cell; cm-weighed in the honest case, no "
             "cells); bc: the prior's causal filter (--causal); b0: frame by frame. Gain at equal rate: b's PSNR "
             "interpolated (against log rate) at a's rate, minus a's.", ""]
    for (clip, setting), table in results.items():
        lines += [f"## {clip}, {setting}", "", "| quant | " + " | ".join(CURVES) + " |",
                  "|---:|" + "---:|" * len(CURVES)]
        for i, quant in enumerate(QUANTS):
            cells = [f"{table[c][i][3]:.1f} dB @ {table[c][i][1]:.2f} ({table[c][i][2]:.2f})" for c in CURVES]
            lines.append(f"| {quant:g} | " + " | ".join(cells) + " |")
        for curve in CURVES[1:4]:
            gains = gain_at_equal_rate(table[CURVES[0]], table[curve])
            lines += ["", f"Gain of ({curve.split(':')[0]}) over (a) at (a)'s rates: " + ", ".join(
                f"{g:+.1f} dB @ {r:.2f}" for r, g in gains) + f"; at least 7 dB from {where_at_least(gains)}"
                if gains else f"({curve.split(':')[0]})'s rates do not overlap (a)'s."]
        lines.append("")
        eight = [(r, p) for _, r, _, p in table[EIGHT] if r <= 0.5]
        best = max(eight, key=lambda x: x[1]) if eight else None
        lines.append("Best 8-FAP PSNR at <= 0.5 kbit/s (whole file): " + (
            f"{best[1]:.1f} dB @ {best[0]:.2f} kbit/s" if best else "none at that rate"))
        eight_payload = [(r, p) for _, _, r, p in table[EIGHT] if r <= 0.5]
        best = max(eight_payload, key=lambda x: x[1]) if eight_payload else None
        lines.append("Best 8-FAP PSNR at <= 0.5 kbit/s of payload: " + (
            f"{best[1]:.1f} dB @ {best[0]:.2f} kbit/s" if best else "none at that rate"))
        if setting == "honest":
            lines.append(f"FAPs the model misses most (RMS FAPU, quant 0.5, through the model): "
                         f"{worst_faps(settings[clip, setting])}")
            other = by_steps[clip]
            gains = gain_at_equal_rate(other[CURVES[0]], other[CURVES[1]])
            lines.append("Weighed by quantiser steps instead (as for the own stream): (b) " + ", ".join(
                f"{p:.1f} dB @ {r:.2f}" for _, r, _, p in other[CURVES[1]]) + "; 8 FAPs " + ", ".join(
                f"{p:.1f} dB @ {r:.2f}" for _, r, _, p in other[EIGHT]) + "; gain of (b) over (a): " + ", ".join(
                f"{g:+.1f} dB @ {r:.2f}" for r, g in gains))
        if setting == "own":
            lines += ["", f"Where the gain comes from ({clip}, own stream): the coding error of (a) in quantiser steps "
                      "and what the model removes of it.", ""]
            lines += error_structure(*settings[clip, setting][0])
            lines += ["", f"The container's packets ({clip}, own stream): kbit/s of the whole .fba against the "
                      "frames per packet, the delay of a decoder that reads it as it arrives.", ""]
            lines += packet_costs(settings[clip, setting])
        lines.append("")
    publish("fap_coding.md", lines)
    plot(results)


def plot(results) -> None:
    import matplotlib
    import matplotlib.ticker

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 2, figsize=(10, 7.5), sharey=True)
    for ax, ((clip, setting), table) in zip(axes.T.ravel(), results.items(), strict=True):
        for name, style in zip(CURVES, ("o-", "s-", "+-.", "x:", "^--", "v--", "d:"), strict=True):
            rates = [r for _, r, _, _ in table[name]]
            ax.plot(rates, [p for *_, p in table[name]], style, label=name, markersize=4)
        ax.set_xscale("log")
        ax.xaxis.set_major_formatter(matplotlib.ticker.FormatStrFormatter("%g"))
        ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        ax.set_xticks([0.2, 0.5, 1, 2, 5])
        ax.set_title(f"{clip}, {setting}")
        ax.set_xlabel("kbit/s (whole .fba)")
        ax.set_ylabel("FAP PSNR (dB)")
        ax.axhline(30, color="grey", lw=0.5)
        ax.axvline(0.5, color="grey", lw=0.5)
        ax.grid(True, which="both", lw=0.3)
    axes[0, 0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(RESULTS / "fap_coding.png", dpi=80)
    print(f"wrote {RESULTS / 'fap_coding.png'} ({(RESULTS / 'fap_coding.png').stat().st_size / 1024:.0f} KB)")


if __name__ == "__main__":
    main()
