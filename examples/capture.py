"""From a video of a face to landmarks, MPEG-4 FAPs and FACS action units, through the Python API.

    python3 examples/capture.py [VIDEO] [OUTDIR]

VIDEO defaults to the shared d0.mp4 (78 frames of smiles), OUTDIR to ./capture-example. Each call is
the command of the same name (``faceanim track``, ``encode``, ``aus``) with its options as keywords.
"""

import sys
from pathlib import Path

import faceanim

HERE = Path(__file__).resolve().parent


def main(video, folder) -> dict:
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    # faceanim track VIDEO -o d0.npz --csv d0_landmarks.csv
    track = faceanim.track(video, folder / "track.npz", csv=folder / "landmarks.csv")
    print(f"tracked {len(track)} frames, a face in {int(track.valid.sum())}")
    # faceanim encode d0.npz -o d0.fap   (the saved track is not tracked again)
    stream, clipped = faceanim.encode(folder / "track.npz", folder / "faps.fap")
    print(f"{len(stream)} frames of FAPs, {int(stream.mask.any(axis=0).sum())} FAPs present, {clipped} clipped")
    # faceanim aus VIDEO -o aus.csv   (OpenFace 2.2's columns; intensities 0-5)
    numbers, intensities = faceanim.aus(video, folder / "aus.csv")
    strongest = numbers[int(intensities.max(axis=0).argmax())]
    print(f"{len(numbers)} action units; the strongest is AU{strongest}")
    print(faceanim.fap_info(folder / "faps.fap").splitlines()[0])
    # faceanim plot aus.csv -o aus.png   (a panel per group of the face; needs the plot extra)
    faceanim.plot(folder / "aus.csv", folder / "aus.png")
    return {"track": track, "stream": stream, "aus": (numbers, intensities)}


if __name__ == "__main__":
    video = sys.argv[1] if len(sys.argv) > 1 else HERE.parent.parent / "shared" / "data" / "videos" / "d0.mp4"
    main(video, sys.argv[2] if len(sys.argv) > 2 else "capture-example")
