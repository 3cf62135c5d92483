"""Speed and rate of the FAP stream coder (issue 17, part 5: coding and decoding at >= 5,000 frames/s).

    flock /tmp/faceanim-bench.lock python benchmarks/fap_codec_speed.py [--runs 20]

On the real MPEG-4 FAP files of ``../shared/data/xface/Faps`` (9 files, 43-108 frames at 25 fps,
40-50 FAPs each) and on all of them joined end to end (one longer stream): ``encode_faps`` and
``decode_faps`` (bytes in memory, the container and its end check included; no file I/O) timed
``--runs`` times each; frames/s per run is frames / seconds. Reported: median and worst (slowest run)
per file, then median and worst over every file's runs. Also, per file at quant 1 (steps = QP) and
quant 4: bits per frame of the whole ``.fba`` (header, masks and end check included), the rate at the
file's 25 fps, and the FAP PSNR of the decoded stream against the file over its FAPs.

The coder's model settings (a per-FAP adaptive discrete Laplace law, weight 1/4, floor 0.2 step) were
chosen on anger, beg, disgust and fear (marked "tuning" below); the other five files are reporting
data the choice never saw. Writes ``benchmarks/results/fap_codec_speed.md``.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from report import publish  # noqa: E402

from faceanim.mpeg4.fapcoder import decode_faps, encode_faps, fap_psnr  # noqa: E402
from faceanim.mpeg4.fapfile import read_fap  # noqa: E402
from faceanim.mpeg4.fapstream import FapStream  # noqa: E402

FAPS = Path(__file__).resolve().parents[2] / "shared" / "data" / "xface" / "Faps"
TUNING = ("anger", "beg", "disgust", "fear")
GOAL = 5000.0


def joined(streams: list[FapStream]) -> FapStream:
    return FapStream(np.concatenate([s.values for s in streams]), np.concatenate([s.mask for s in streams]),
                     fps=streams[0].fps, name="all_nine")


def timed(fn, runs: int) -> list[float]:
    seconds = []
    for _ in range(runs):
        start = time.perf_counter()
        fn()
        seconds.append(time.perf_counter() - start)
    return seconds


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=20)
    args = parser.parse_args(argv)
    if not FAPS.is_dir():
        print(f"needs {FAPS} (the shared data folder beside the checkout)")
        return 1
    paths = sorted(FAPS.glob("*.fap"))
    streams = [read_fap(p) for p in paths]
    names = [p.stem for p in paths]
    streams.append(joined(streams))
    names.append("all nine joined")

    rows, all_encode, all_decode = [], [], []
    for name, stream in zip(names, streams, strict=True):
        data = encode_faps(stream, quant=1.0)
        encode_faps(stream, quant=1.0), decode_faps(data)  # warm (imports, caches)
        enc = [len(stream) / s for s in timed(lambda s=stream: encode_faps(s, quant=1.0), args.runs)]
        dec = [len(stream) / s for s in timed(lambda d=data: decode_faps(d), args.runs)]
        if name != "all nine joined":
            all_encode += enc
            all_decode += dec
        rate = []
        for quant in (1.0, 4.0):
            coded = encode_faps(stream, quant=quant)
            decoded = decode_faps(coded)
            bits = len(coded) * 8 / len(stream)
            rate.append((bits, bits * stream.fps / 1000, fap_psnr(stream, decoded)))
        active = int(stream.mask[:, 2:].any(axis=0).sum())
        kind = "tuning" if name in TUNING else ("both" if name.startswith("all") else "reporting")
        rows.append(f"| {name} | {kind} | {len(stream)} | {active} | {np.median(enc):,.0f} | {min(enc):,.0f} | "
                    f"{np.median(dec):,.0f} | {min(dec):,.0f} | "
                    + " | ".join(f"{b:.1f} | {k:.2f} | {p:.1f}" for b, k, p in rate) + " |")

    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    lines = [
        "# FAP stream coder: speed and rate",
        "",
        f"`flock /tmp/faceanim-bench.lock python benchmarks/fap_codec_speed.py --runs {args.runs}` on "
        f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, 1-minute load {load:.2f} at the end. "
        "Frames/s = frames / seconds of one `encode_faps` or `decode_faps` call (bytes in memory, container and "
        f"end check included), {args.runs} runs per file; median and worst (slowest run). Bits per frame: the "
        "whole .fba (header, masks, end check) over the frames; kbit/s at the file's 25 fps; PSNR = 20 log10("
        "peak-to-peak range of the file's FAPs / RMS error), pooled over the FAPs the file carries. "
        "Tuning files chose the coder's model settings; reporting files never informed them.",
        "",
        "| file | data | frames | FAPs | encode frames/s median | worst | decode frames/s median | worst | "
        "q1 bits/frame | q1 kbit/s | q1 PSNR dB | q4 bits/frame | q4 kbit/s | q4 PSNR dB |",
        "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
        *rows,
        "",
        f"Over the 9 files' {len(all_encode)} runs each: encode median {np.median(all_encode):,.0f} frames/s, "
        f"worst {min(all_encode):,.0f}; decode median {np.median(all_decode):,.0f} frames/s, worst "
        f"{min(all_decode):,.0f} (goal >= {GOAL:,.0f} each: "
        f"{'met' if min(min(all_encode), min(all_decode)) >= GOAL else 'not met in the worst run'}).",
    ]
    publish("fap_codec_speed.md", lines)
    return 0


if __name__ == "__main__":
    sys.exit(main())
