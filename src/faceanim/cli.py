"""The ``faceanim`` command: argument parsing only; each subcommand calls one pipeline function."""

from __future__ import annotations

import argparse
import contextlib
import os
import signal
import sys
import threading
import warnings

from .errors import InputError

__all__ = ["main"]


def _target_arguments(p) -> None:
    """``--target MESH`` and where its control points come from (``--points`` or ``--fdp``)."""
    p.add_argument("--target", metavar="MESH",
                   help="the face to move (.obj, .glb, .ply; default: the avatar of the embedded portrait)")
    group = p.add_mutually_exclusive_group()
    group.add_argument("--points", metavar="POINTS.json",
                       help='control points as {"8.3": vertex id, ...} (default: those a faceanim .glb carries, '
                            'else placed automatically)')
    group.add_argument("--fdp", metavar="FILE.fdp", help="control points and FAPU from an XfaceEd .fdp file")


def _capture_arguments(p, *, image: bool = True, filters: str = "the One Euro temporal filter",
                       floor_help: bool = True) -> None:
    """``--neutral`` (where the face is at rest) and ``--no-filter``, for the commands that track a video;
    ``floor_help``: say that ``--no-filter`` turns the noise floor off too, for the commands whose capture
    has it (not the speaker's, whose jobs capture without it)."""
    p.add_argument("--neutral", metavar="FRAME|START:END" + ("|IMAGE" if image else ""),
                   help="the face at rest (default: the most relaxed half second, found automatically)")
    if floor_help:
        # In words, not NOISE_FLOOR's number: the CLI imports only the jobs (../shared/ARCHITECTURE.md).
        filters += " and the noise floor (a point's motion under about a millimetre dropped; lips and irises kept)"
    p.add_argument("--no-filter", action="store_true", help=f"turn {filters} off")


def _force_argument(p) -> None:
    """``--force``, for the commands whose ``.obj`` output brings side files."""
    p.add_argument("--force", action="store_true",
                   help="an .obj output's material and texture (OUT.mtl, OUT_texture.png) may replace files of those "
                        "names that faceanim did not write")


class _Parser(argparse.ArgumentParser):
    """argparse, with a mistake on the command line said in one line like every other user error
    (argparse prints its whole usage block first), pointing at the command's ``--help``."""

    def error(self, message):
        self.exit(2, f"faceanim: error: {message} (see {self.prog} --help)\n")


def _parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="faceanim", description="The motion of a real face onto any 3D face.")
    from . import __version__

    parser.add_argument("--version", action="version", version=f"faceanim {__version__}")
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    p = commands.add_parser("transfer", help="put a source face's expression on a target face",
                            description="Move TARGET_NEUTRAL the way SRC_NEUTRAL moved to SRC_EXPRESSION. The output "
                                        "keeps the target's vertices, in order.")
    p.add_argument("source_neutral", metavar="SRC_NEUTRAL")
    p.add_argument("source_expression", metavar="SRC_EXPRESSION")
    p.add_argument("target", metavar="TARGET_NEUTRAL")
    p.add_argument("-o", "--output", required=True, metavar="OUT", help="output mesh (.obj, .ply or .glb)")
    p.add_argument("--correspondence", required=True, metavar="PAIRS.json",
                   help='{"source": [vertex ids], "target": [vertex ids]}')
    p.add_argument("--method", choices=("clone", "rbf"), default="clone",
                   help="clone: use the whole source mesh (default); rbf: only the control points' motion")
    p.add_argument("--mask", metavar="IDS.json", help="JSON list of target vertex ids allowed to move")
    p.add_argument("--region", action="append", default=[], metavar="NAME",
                   help="only move this face region (lips, eyes, brows, nose, cheeks, jaw; repeatable; needs "
                        "68 pairs in iBUG order)")
    _force_argument(p)

    p = commands.add_parser("track", help="track the face through a video",
                            description="Track the face in VIDEO (any file FFmpeg reads, an image, or a folder of "
                                        "images) with MediaPipe's Face Landmarker (478 landmarks and 52 blendshape "
                                        "scores per frame) and save what was seen.")
    p.add_argument("video", metavar="VIDEO")
    p.add_argument("-o", "--output", required=True, metavar="TRACK.npz")
    p.add_argument("--overlay", metavar="OVERLAY.mp4", help="also write the video with landmarks and head axes")
    p.add_argument("--csv", metavar="LANDMARKS.csv", help="also write landmark pixels per frame")
    p.add_argument("--start-face", choices=("largest", "left", "right"), default="largest",
                   help="with several faces, which one to follow (then the nearest in each frame)")
    p.add_argument("--model", metavar="face_landmarker.task",
                   help="another Face Landmarker model bundle (default: the one shipped with faceanim)")

    p = commands.add_parser("encode", help="video or track to an MPEG-4 FAP file",
                            description="Measure the face's motion in VIDEO_OR_TRACK, apart from head motion, as "
                                        "MPEG-4 facial animation parameters.")
    p.add_argument("source", metavar="VIDEO_OR_TRACK")
    p.add_argument("-o", "--output", required=True, metavar="OUT.fap")
    _capture_arguments(p)

    for name, help_text, source in (
            ("animate", "a video of a face drives a 3D face", "VIDEO"),
            ("decode", "an MPEG-4 FAP file drives a 3D face", "FILE.fap")):
        p = commands.add_parser(name, help=help_text, description=help_text[0].upper() + help_text[1:] + (
            "; the result is a glTF binary with morph targets and an animation."))
        p.add_argument("source", metavar=source)
        p.add_argument("-o", "--output", required=True, metavar="OUT.glb")
        _target_arguments(p)
        p.add_argument("--parts", metavar="PARTS.json",
                       help='label the target\'s parts where its file and shape do not tell them apart: '
                            '{"teeth": ["M_Teeth"], "skin": [[0, 9408]], ...} (roles: skin, teeth, upper_teeth, '
                            'lower_teeth, eye, eye_left, eye_right, lid_layer, socket, static; part names or '
                            '[first, last] vertex ranges)')
        p.add_argument("--preview", metavar="PREVIEW.mp4", help="also render the animation to a video")
        p.add_argument("--head-motion", action="store_true", help="turn the head as the FAPs (48-50) say")
        p.add_argument("--obj-sequence", metavar="DIR", help="also write the animation as numbered OBJ files")
        p.add_argument("--csv", metavar="FAPS.csv", help="also write the FAP curves as CSV")
        p.add_argument("--workers", type=int, metavar="N",
                       help="processes deforming the frames at once (default: the CPUs this process may use, "
                            "at most 4)")
        if name == "decode":
            p.add_argument("--speaker", metavar="SPEAKER.npz",
                           help="interpret the FAPs through this speaker model first (faceanim speaker build): "
                                "the lips', jaw's and cheeks' FAPs regenerated from the articulatory parameters "
                                "that best explain those received, missing ones filled in")
        if name == "animate":
            p.description += (" A --target .glb whose morph targets carry ARKit or FACS AU names (faceanim rig's, or "
                              "another tool's) is a named rig: its own targets are animated (weights solved per "
                              "frame), and VIDEO may also be a Live Link Face CSV or an OpenFace / py-feat AU CSV.")
            p.add_argument("--fap", metavar="OUT.fap", help="also write the video's FAPs")
            p.add_argument("--via", choices=("motion", "faps"), default="motion",
                           help="motion (default): every tracked point the target shares moves it, in 3D; "
                                "faps: only what the MPEG-4 FAPs carry, as decode would play the .fap")
            _capture_arguments(p, image=False)

    p = commands.add_parser("speaker", help="a speaker's articulatory model: build it, analyse speech with it",
                            description="A speaker's linear articulatory model (jaw and lips: x = x0 + sum a_k d_k) "
                                        "from a speech video, and the FAPs of a video as that model explains them. "
                                        "faceanim decode --speaker decodes a FAP stream through the model.")
    speaker = p.add_subparsers(dest="speaker_command", required=True, metavar="STEP")
    p = speaker.add_parser("build", help="build the model from a speech video",
                           description="Track VIDEO and build the speaker's model of its mobile points (lips, jaw, "
                                       "chin, cheeks; cm, head frame) from its frames.")
    p.add_argument("video", metavar="VIDEO")
    p.add_argument("-o", "--output", required=True, metavar="SPEAKER.npz")
    p.add_argument("--params", type=int, default=6, metavar="K", help="articulatory parameters (default 6)")
    p.add_argument("--frames", metavar="START:END", help="build from these frames only (end exclusive)")
    p.add_argument("--method", choices=("guided", "pca"), default="guided",
                   help="guided (default): the jaw first, then the lips' protrusion, opening, upper lip, lower lip, "
                        "corners; pca: principal components (see benchmarks/results/speaker_model.md)")
    _capture_arguments(p, image=False, floor_help=False)
    p = speaker.add_parser("analyse", help="a video's FAPs as the speaker model explains them",
                           description="Track VIDEO, fit the model's parameters to each frame's mobile points and "
                                       "write the FAPs of the model's points.")
    p.add_argument("video", metavar="VIDEO")
    p.add_argument("--model", required=True, metavar="SPEAKER.npz")
    p.add_argument("-o", "--output", required=True, metavar="SPEECH.fap")
    p.add_argument("--params-csv", metavar="PARAMS.csv", help="also write the parameters per frame")
    _capture_arguments(p, image=False, floor_help=False)
    p = speaker.add_parser("textures", help="add the clone's key postures, textures and colour model to a model",
                           description="Track VIDEO (the speaker's), fit its camera and the head's rigid motion, "
                                       "choose three key postures (rest, open, rounded), re-project their textures "
                                       "onto the mesh (512x512) and learn the lip/skin colour model; write them into "
                                       "the speaker file (-o may be the --model file itself).")
    p.add_argument("video", metavar="VIDEO")
    p.add_argument("--model", required=True, metavar="SPEAKER.npz")
    p.add_argument("-o", "--output", required=True, metavar="SPEAKER.npz")
    p.add_argument("--frames", metavar="START:END", help="choose key postures among these frames (end exclusive; "
                                                         "give the model's build frames)")
    p.add_argument("--camera-out", metavar="CAM.txt", help="also write the fitted 3x4 camera")
    p.add_argument("--motion-out", metavar="MOTION.csv", help="also write the head's rigid motion per frame")
    _capture_arguments(p, image=False, floor_help=False)
    p = speaker.add_parser("render", help="draw the clone video-realistically from parameters",
                           description="Draw the speaker's clone (a model with textures) at each frame's parameters: "
                                       "the key textures mixed pixel by pixel with weights that follow the posture.")
    p.add_argument("--model", required=True, metavar="SPEAKER.npz")
    p.add_argument("--params", required=True, metavar="P.csv",
                   help="frame, timestamp and one column per parameter (faceanim speaker analyse --params-csv)")
    p.add_argument("--motion", metavar="M.csv", help="the head's rigid motion per frame: frame, rx, ry, rz (rotation "
                                                     "vector, radians), tx, ty, tz (cm); default: still")
    p.add_argument("--camera", metavar="CAM.txt", help="a 3x4 projection (3 lines of 4 numbers); default the model's")
    p.add_argument("--background", metavar="IMAGE|VIDEO", help="drawn behind the clone; its size and rate are the "
                                                                "output's")
    p.add_argument("--wireframe", action="store_true", help="draw the mesh's edges over the clone")
    p.add_argument("-o", "--output", required=True, metavar="OUT.mp4")
    p = speaker.add_parser("track", help="a video's parameters by analysis by synthesis with the clone",
                           description="Analyse VIDEO with the speaker's clone (a model with textures): per frame, the "
                                       "clone's colours drawn over the mouth are compared with the frame's, and the "
                                       "articulatory parameters (with --rigid the head's motion too) move by damped "
                                       "Gauss-Newton steps and the simplex method from the previous frame's answer, "
                                       "pulled toward the frame's landmark-based reading.")
    p.add_argument("video", metavar="VIDEO")
    p.add_argument("--model", required=True, metavar="SPEAKER.npz", help="a speaker model with textures "
                                                                         "(faceanim speaker textures)")
    p.add_argument("-o", "--output", required=True, metavar="P.csv",
                   help="the parameters per frame (the columns of faceanim speaker analyse --params-csv)")
    p.add_argument("--fap", metavar="OUT.fap", help="also write the FAPs the parameters give through the model")
    p.add_argument("--overlay", metavar="OVERLAY.mp4", help="also draw the analysed clone's wireframe on the frames")
    p.add_argument("--motion-out", metavar="MOTION.csv", help="also write the head's rigid motion per frame (as "
                                                              "faceanim speaker render --motion reads it)")
    p.add_argument("--max-evals", type=int, default=150, metavar="N",
                   help="the most evaluations of the difference per frame (default 150)")
    p.add_argument("--rigid", action="store_true", help="also analyse the head's rigid motion (6 more parameters, "
                                                        "a correction of the tracker's pose)")
    p.add_argument("--field", choices=("top", "bottom"), help="interlaced footage: analyse one field's rows only")
    p.add_argument("--supersample", action="store_true",
                   help="compare the mean of every frame pixel under each of the comparison's box pixels with the "
                        "clone read at each (default: the middle one, read exactly as the clone's renderer draws it; "
                        "not closer on the clone's own frames, at 45-70%% of the speed: "
                        "benchmarks/results/clone_tracking.md)")
    p.add_argument("--raster", choices=("gl", "numpy"),
                   help="the lip-probability renderer (default gl where it can run, else numpy; see "
                        "benchmarks/results/clone_tracking.md)")
    _capture_arguments(p, image=False, floor_help=False)

    p = commands.add_parser("avatar", help="a textured 3D face from a portrait",
                            description="Make an animatable 3D face from a portrait photo: the tracker's face "
                                        "mesh, smoothly subdivided, textured from the photo, eyes and mouth open. "
                                        "The .glb carries its control points, so animate and decode take it as "
                                        "--target without placement.")
    p.add_argument("photo", metavar="PHOTO", help="an image (or a video, whose first frame is used)")
    p.add_argument("-o", "--output", required=True, metavar="FACE.glb")

    p = commands.add_parser("rig", help="the 52 ARKit blendshapes on any face mesh, as a .glb",
                            description="Make the 52 ARKit blendshapes (browDownLeft ... jawOpen ... tongueOut) on "
                                        "a face mesh by carrying ICT-FaceKit's expression shapes through a dense "
                                        "registration of ICT's head onto it. The .glb keeps the mesh's vertices in "
                                        "their order, with the shapes as morph targets named as ARKit names them "
                                        "(tongueOut empty: ICT has no tongue shape) and its control points.")
    p.add_argument("target", metavar="TARGET", help="the face mesh (.obj, .glb, .ply), looking along +z with +y up")
    group = p.add_mutually_exclusive_group()
    group.add_argument("--points", metavar="POINTS.json",
                       help='control points as {"mp33": vertex id, ...} (the 68 iBUG points by MediaPipe index) or '
                            'MPEG-4 feature points (default: those a faceanim .glb carries, else placed automatically)')
    group.add_argument("--fdp", metavar="FILE.fdp", help="control points from an XfaceEd .fdp file")
    p.add_argument("--ict", metavar="DIR", help="ICT-FaceKit's folder (ict_deltas_full.npz, obj/, "
                                                "landmarks_multipie68.json; default: $FACEANIM_ICT_FACEKIT)")
    p.add_argument("-o", "--output", required=True, metavar="RIGGED.glb")

    p = commands.add_parser("demo", help="run the whole chain on embedded material (no downloads)",
                            description="Make a 3D avatar from the astronaut portrait scikit-image ships, film it "
                                        "performing a scripted expression sequence (the photo warped by RBF), then "
                                        "track, encode and retarget that video like any other. Writes demo.glb, "
                                        "preview.mp4, demo.fap, performance.mp4 and report.html.")
    p.add_argument("-o", "--output", default="faceanim-demo", metavar="DIR",
                   help="folder for the outputs (default: ./faceanim-demo)")

    p = commands.add_parser("view", help="watch an animated .glb in the browser",
                            description="Serve a local web page (127.0.0.1 only) that plays FILE.glb, with its source "
                                        "video beside it and its FAP curves under it, and open it in the browser. "
                                        "A model with action-unit morph targets gets sliders to mix expressions.")
    p.add_argument("model", metavar="FILE.glb")
    p.add_argument("--video", metavar="SOURCE", help="the source video, played in step with the face")
    p.add_argument("--fap", metavar="FILE.fap", help="FAP curves to draw under the face")
    p.add_argument("--port", type=int, default=8765, help="port on 127.0.0.1 (default: 8765)")
    p.add_argument("--no-browser", action="store_true", help="only print the address")

    p = commands.add_parser("express", help="make an expression (FACS AUs or an emotion) on a 3D face",
                            description="Make FACS action units (Waters vector muscles placed by the face's feature "
                                        "points) or one of the six emotions on a face. OUT is .obj (the still face), "
                                        ".glb (a still, or an onset-apex-offset animation with --frames; every AU "
                                        "rides along as a named morph target) or .fap.")
    group = p.add_mutually_exclusive_group(required=True)
    group.add_argument("--au", metavar="RECIPE", help="AU intensities, like 6:0.8,12:1.0 (0-1; up to 2 exaggerates; "
                                                      "12L for one side; FACS letters A-E also work)")
    group.add_argument("--emotion", metavar="NAME", help="joy, sadness, anger, fear, disgust or surprise")
    p.add_argument("--intensity", type=float, metavar="X", help="scales an --emotion (default 1; above 1 exaggerates)")
    _target_arguments(p)
    p.add_argument("--frames", type=int, metavar="N", help="an onset-apex-offset animation of N frames (on a --target "
                   ".glb whose morph targets carry AU or ARKit names: those sliders are animated)")
    p.add_argument("--fps", type=float, default=25.0, help="frame rate of the animation (default 25)")
    p.add_argument("--route", choices=("direct", "generic"), default="direct",
                   help="direct: muscles on the target itself (default); generic: made on the generic face and "
                        "projected onto the target")
    p.add_argument("-o", "--output", required=True, metavar="OUT")
    _force_argument(p)

    p = commands.add_parser("aus", help="FACS action-unit intensities of a video, as CSV",
                            description="Track the face, take head motion out, and fit the muscles' action units "
                                        "to each frame (bounded least squares). The CSV is OpenFace 2.2's (frame, "
                                        "face_id, timestamp, confidence, success, pose_Rx-Rz, AU01_r, ..., "
                                        "AU01_c, ...; intensities 0-5), timed by the video's own timestamps.")
    p.add_argument("video", metavar="VIDEO")
    p.add_argument("-o", "--output", required=True, metavar="AUS.csv")
    _capture_arguments(p, filters="the temporal filters (landmarks and AU curves)")

    p = commands.add_parser("blendshapes", help="ARKit-52 blendshape weights of a video, as a Live Link Face CSV",
                            description="Track the face with MediaPipe's Face Landmarker and write its blendshape "
                                        "scores as a Live Link Face take: Timecode (HH:MM:SS:FF.mmm from the video's "
                                        "own times), BlendShapeCount, the 52 ARKit shapes in Live Link's order "
                                        "(weights 0-1; TongueOut is 0), head and eye yaw/pitch/roll (radians). "
                                        "Prints the most active shapes.")
    p.add_argument("video", metavar="VIDEO")
    p.add_argument("-o", "--output", required=True, metavar="TAKE.csv")
    p.add_argument("--neutral", metavar="FRAME|START:END",
                   help="the face at rest: its scores are taken off every frame (clipped at 0) and it is the eyes' "
                        "zero (default: scores as MediaPipe gives them, rest found automatically)")
    p.add_argument("--no-filter", action="store_true", help="turn the One Euro filter (head and eye angles) off")

    p = commands.add_parser("plot", help="draw FAP, AU or blendshape curves as a PNG",
                            description="Draw FILE's curves (a .fap file, an AU CSV from faceanim aus or OpenFace, a "
                                        "FAP CSV, or a take of blendshapes such as a Live Link Face CSV) as one PNG: "
                                        "a panel per group of the face (jaw, lips, brows, lids, eyes, cheeks and "
                                        "nose, head), each on its own scale and unit, over time.")
    p.add_argument("source", metavar="FILE.fap|AUS.csv|take.csv")
    p.add_argument("-o", "--output", required=True, metavar="CURVES.png")
    p.add_argument("--title", help="the figure's title (default: the file's name)")

    p = commands.add_parser("batch", help="process many videos on Ray (locally or on a cluster)",
                            description="Run encode, aus, blendshapes and/or animate on every video INPUTS name "
                                        "(files, folders, globs, or a .csv/.jsonl manifest with a path column and "
                                        "per-row name, neutral, no_filter, target), one Ray task per video. Each "
                                        "video's outputs (NAME.fap, NAME_aus.csv, NAME_take.csv, NAME.glb) appear "
                                        "complete or not at all; a video that fails is listed with its reason and the "
                                        "rest go on; outputs already in OUTDIR are not made again. Writes "
                                        "OUTDIR/batch_summary.csv.")
    p.add_argument("inputs", nargs="+", metavar="INPUTS")
    p.add_argument("-o", "--output", required=True, metavar="OUTDIR")
    p.add_argument("--do", default="encode", metavar="STEPS",
                   help="comma-separated: encode, aus, blendshapes, animate, plot (the FAPs drawn; with encode) "
                        "(default: encode)")
    p.add_argument("--target", metavar="MESH", help="the face animate moves (default: the avatar), loaded once")
    p.add_argument("--workers", type=int, metavar="N",
                   help="videos at once on this machine (default: the CPUs this process may use)")
    p.add_argument("--address", metavar="ray://HOST:PORT|auto", help="run on this Ray cluster instead")
    p.add_argument("--force", action="store_true", help="make outputs again even where they are already there")

    p = commands.add_parser("fap-compress", help="code a .fap into a compact FAP stream (.fba)",
                            description="Code the FAPs of IN.fap with MPEG-4's low-delay scheme (steps QP x quant, "
                                        "an intra frame, then differences from the decoder's reconstruction, "
                                        "adaptive arithmetic coding) into faceanim's .fba container; prints the "
                                        "size, the rate at the file's frame rate and the FAP PSNR against the input.")
    p.add_argument("source", metavar="IN.fap")
    p.add_argument("-o", "--output", required=True, metavar="OUT.fba")
    p.add_argument("--quant", type=float, default=1.0, metavar="Q",
                   help="scale of the quantiser steps QP x Q (default 1; larger is coarser and smaller)")
    p.add_argument("--faps", metavar="LIST", help="the FAPs to send, like 3,14,16,17,51-54 (default: all the file "
                                                  "carries, 3-68)")
    p.add_argument("--packet", type=int, metavar="FRAMES",
                   help="frames per packet, the delay of a decoder that reads the stream as it arrives (default: "
                        "1 s of frames; a packet costs ~5 bytes)")

    p = commands.add_parser("fap-decompress", help="decode a .fba back into a .fap",
                            description="Decode IN.fba (faceanim fap-compress) into a .fap as it is read, a packet "
                                        "at a time; with --speaker, the FAPs are interpreted through a speaker model "
                                        "(regularised, the FAPs not sent filled in), each frame with the frames "
                                        "before it and those after it in its packet through the model's temporal "
                                        "prior, kept within the quantiser's cells.")
    p.add_argument("source", metavar="IN.fba")
    p.add_argument("-o", "--output", required=True, metavar="OUT.fap")
    p.add_argument("--speaker", metavar="SPEAKER.npz", help="a speaker model (faceanim speaker build)")
    p.add_argument("--frame-by-frame", action="store_true",
                   help="with --speaker: interpret each frame alone, without the model's temporal prior (a model "
                        "file of version 1 has none and is always read so)")
    p.add_argument("--causal", action="store_true",
                   help="with --speaker: the temporal prior as a causal filter, frame by frame (default: smoothed "
                        "within each packet, every FAP kept within its quantiser cell)")

    p = commands.add_parser("fap-info", help="summarise a .fap file",
                            description="Frames, fps, active FAPs with their ranges, and values outside MPEG-4's.")
    p.add_argument("fap", metavar="FILE.fap")
    return parser


def main(argv=None) -> int:
    """Run the command line; returns the exit status.

    One policy for what goes wrong: an input or argument faceanim cannot use (its declared errors,
    and the operating system's refusals: a missing file, no permission, a full disk) is one line on
    stderr and exit status 2; an interrupt (Ctrl-C, SIGINT, or SIGTERM) removes the job's temporary
    files and whatever outputs it had finished, prints ``faceanim: interrupted`` and returns 130
    (SIGINT) or 143 (SIGTERM), 128 plus the signal's number as shells do, also when a library the
    interrupt cut short raises its own error on the way out; anything else is a bug in faceanim and shows
    its traceback. A job's outputs appear together when it ends without error
    (:func:`faceanim.atomic.output_group`), so a failure or an interrupt leaves none of them, and the
    files that were at their paths before stay as they were (the demo puts each step's outputs in
    place when the step ends, so it loses only the step it was in).

    The declared errors are :class:`~faceanim.errors.InputError` and its :class:`~faceanim.errors.FileFormatError`;
    a plain ``ValueError`` (a library function's contract on its arrays, broken by faceanim's own code)
    is a bug like any other. An interrupt while faceanim is still importing its parts (before any job
    starts; ``import faceanim.cli`` itself imports nothing heavy) ends the same way: one line, 130.
    """
    try:
        return _main(argv)
    except KeyboardInterrupt:  # during parsing or the imports, before the job's own handlers are set
        print("faceanim: interrupted", file=sys.stderr)
        return 128 + signal.SIGINT


def _main(argv) -> int:
    """:func:`main` once the interrupts before the job are caught."""
    args = _parser().parse_args(argv)
    from .atomic import output_group
    from .progress import Interrupted, Progress, Quiet

    received: list[int] = []  # the signals the job was sent; its frame loops stop on the first
    # Long steps shown on stderr when it is a terminal (as git does): a bar per frame loop, a line per step;
    # off a terminal (a pipe, a log, a test), only the result and the errors.
    shown = sys.stderr.isatty()
    progress = Progress(interrupts=received) if shown else Quiet(interrupts=received)

    warnings.formatwarning = lambda message, *_, **__: f"faceanim: warning: {message}\n"

    try:
        with _interrupts_raised(received), output_group():
            said = _run(args, progress)
            if received and args.command != "view":  # the viewer stops on an interrupt by design (exit 0)
                # The interrupt was raised but swallowed on the way (trimesh's optional imports catch
                # BaseException) and no frame loop came after: the job still ends interrupted, its
                # outputs unmade.
                raise Interrupted(received[0])
    except KeyboardInterrupt as exc:  # the group has removed the temporary files and the finished outputs
        return _interrupted(shown, getattr(exc, "signum", signal.SIGINT))
    except Exception as exc:
        if received and _raised_by_an_interrupt(exc):
            # The interrupt broke a library mid-write, which raised its own error on the way out: in a full
            # test run, `faceanim track` interrupted while numpy's savez wrote its track ended in a traceback,
            # zipfile's "... Close the writing handle before closing the zip." The job was still
            # interrupted, and ends as one.
            return _interrupted(shown, received[0])
        if isinstance(exc, (InputError, OSError)):
            print(f"faceanim: error: {exc}", file=sys.stderr)
            return 2
        raise
    if said:
        try:
            print(said, flush=True)
        except BrokenPipeError:  # the reader left (``| head``): quiet, as for any signal, 128 + SIGPIPE
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # no second error at exit
            return 128 + signal.SIGPIPE
    return 0


def _raised_by_an_interrupt(exc: BaseException) -> bool:
    """Whether ``exc`` was raised while an interrupt was being handled (one is in its context chain)."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return True
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return False


def _interrupted(shown: bool, signum: int) -> int:
    print(("\n" if shown else "") + "faceanim: interrupted", file=sys.stderr)
    return 128 + signum


_SIGNALS = (signal.SIGINT, signal.SIGTERM)


@contextlib.contextmanager
def _interrupts_raised(received: list):
    """SIGINT and SIGTERM raise :class:`~faceanim.progress.Interrupted` inside the block (the handlers
    before it are restored after). A signal ignored when faceanim started (SIGINT in a shell's background
    job) stays ignored; off the main thread, where handlers cannot be set, nothing changes.

    Each signal is added to ``received`` (the first one only: the handler then ignores both, so a
    second Ctrl-C does not cut the clean-up short). A library that catches ``BaseException`` can swallow
    the raised interrupt and let the job run on; the frame loops read ``received`` (through the job's
    :class:`~faceanim.progress.Progress`) and stop at the next frame, and the caller ends the job as
    interrupted anyway."""
    from .progress import Interrupted

    if threading.current_thread() is not threading.main_thread():
        yield received
        return

    def raise_interrupted(signum, frame):
        for number in _SIGNALS:
            signal.signal(number, signal.SIG_IGN)
        received.append(signum)
        raise Interrupted(signum)

    before = {number: signal.getsignal(number) for number in _SIGNALS}
    for number, handler in before.items():
        if handler != signal.SIG_IGN:
            signal.signal(number, raise_interrupted)
    try:
        yield received
    finally:
        for number, handler in before.items():
            signal.signal(number, signal.SIG_DFL if handler is None else handler)


def _run(args, progress) -> str:
    """Run the parsed command; returns what to print once its outputs are in place."""
    from . import pipeline

    if args.command == "transfer":
        out = pipeline.transfer(args.source_neutral, args.source_expression, args.target, args.output,
                                correspondence=args.correspondence, method=args.method, mask=args.mask,
                                regions=tuple(args.region), force=args.force)
        return f"wrote {out}"
    if args.command == "track":
        from .capture.tracker import TrackerOptions

        result = pipeline.track(args.video, args.output, overlay=args.overlay, csv=args.csv,
                                options=TrackerOptions(start_face=args.start_face), model=args.model,
                                progress=progress)
        return (f"wrote {args.output}: {len(result)} frames, face found in {int(result.valid.sum())}, "
                f"filled {int(result.filled.sum())}")
    if args.command == "encode":
        stream, clipped = pipeline.encode(args.source, args.output, neutral=args.neutral,
                                          smoothing=not args.no_filter, progress=progress)
        active = int(stream.mask.any(axis=0).sum())
        note = f"; {clipped} values clipped to their MPEG-4 range" if clipped else ""
        return f"wrote {args.output}: {len(stream)} frames, {active} FAPs{note}"
    if args.command == "decode":
        animation = pipeline.decode(args.source, args.output, target_mesh=args.target, points=args.points,
                                    fdp=args.fdp, preview=args.preview, head_motion=args.head_motion,
                                    obj_sequence=args.obj_sequence, csv=args.csv, progress=progress,
                                    parts=args.parts, speaker=args.speaker, workers=args.workers)
        return f"wrote {args.output}: {len(animation)} frames" + (f", preview {args.preview}" if args.preview else "")
    if args.command == "animate":
        animation, _ = pipeline.animate(args.source, args.output, target_mesh=args.target, points=args.points,
                                        fdp=args.fdp, preview=args.preview, fap=args.fap,
                                        head_motion=args.head_motion, obj_sequence=args.obj_sequence,
                                        csv=args.csv, via=args.via, neutral=args.neutral,
                                        smoothing=not args.no_filter, progress=progress, parts=args.parts,
                                        workers=args.workers)
        if hasattr(animation, "driven"):  # a named rig (faceanim.driving): its own morph targets were animated
            return (f"wrote {args.output}: {len(animation)} frames on {animation.driven} named morph targets "
                    f"({len(animation.names)} of the main mesh's)")
        return f"wrote {args.output}: {len(animation)} frames" + (f", preview {args.preview}" if args.preview else "")
    if args.command == "speaker":
        from . import speech

        if args.speaker_command == "build":
            model, explained = speech.build_speaker(args.video, args.output, params=args.params, frames=args.frames,
                                                    method=args.method, neutral=args.neutral,
                                                    smoothing=not args.no_filter, progress=progress)
            return (f"wrote {args.output}: {model.parameter_count} parameters ({model.method}: "
                    f"{', '.join(model.parameter_names)}) over {len(model.names)} mobile points and "
                    f"{len(model.fap_columns)} FAPs; {100 * explained:.1f}% of their variance on the frames used")
        if args.speaker_command in ("textures", "render"):
            from . import speakerclone

            if args.speaker_command == "textures":
                appearance, fit = speakerclone.make_textures(
                    args.video, args.output, model=args.model, frames=args.frames, neutral=args.neutral,
                    smoothing=not args.no_filter, camera_out=args.camera_out, motion_out=args.motion_out,
                    progress=progress)
                keys = ", ".join(f"{n} {f}" for n, f in zip(appearance.key_names, appearance.key_frames, strict=True))
                return (f"wrote {args.output}: {len(appearance.textures)} textures of {appearance.size}x"
                        f"{appearance.size} (key frames: {keys}); camera reprojection {fit.median_px:.2f} px median, "
                        f"{fit.worst_frame_px:.2f} px worst frame")
            count = speakerclone.render_clone(args.output, model=args.model, params=args.params, motion=args.motion,
                                              camera=args.camera, background=args.background,
                                              wireframe=args.wireframe, progress=progress)
            return f"wrote {args.output}: {count} frames"
        if args.speaker_command == "track":
            import numpy as np

            from .speakertrack import frame_ranges, track_speaker

            tracked = track_speaker(args.video, args.output, model=args.model, fap=args.fap, overlay=args.overlay,
                                    motion_out=args.motion_out, max_evals=args.max_evals, rigid=args.rigid,
                                    field=args.field, raster=args.raster, neutral=args.neutral,
                                    supersample=args.supersample,
                                    smoothing=not args.no_filter, progress=progress)
            T = len(tracked.parameters)
            analysed = int(tracked.valid.sum())
            rate = analysed / max(tracked.seconds, 1e-9)
            missing = np.flatnonzero(~tracked.valid)
            note = (f"; no face on frames {frame_ranges(missing)}: they hold the last analysed frame's parameters"
                    if len(missing) else "")
            return (f"wrote {args.output}: {T} frames, {tracked.parameters.shape[1]} parameters, median "
                    f"{int(np.median(tracked.evaluations[tracked.valid]))} evaluations a frame, {rate:.1f} "
                    f"frames/s analysed{note}")
        stream, parameters, outside = speech.analyse_speech(
            args.video, args.output, model=args.model, params_csv=args.params_csv, neutral=args.neutral,
            smoothing=not args.no_filter, progress=progress)
        note = f"; {outside} values outside their MPEG-4 range (kept: the model's own)" if outside else ""
        return (f"wrote {args.output}: {len(stream)} frames, {int(stream.mask.any(axis=0).sum())} FAPs from "
                f"{parameters.shape[1]} parameters{note}" + (f", parameters in {args.params_csv}"
                                                            if args.params_csv else ""))
    if args.command == "avatar":
        target = pipeline.avatar(args.photo, args.output)
        return f"wrote {args.output}: {len(target.mesh.vertices)} vertices, {len(target.points)} control points"
    if args.command == "rig":
        from .rigging import make_rig

        made = make_rig(args.target, args.output, points=args.points, fdp=args.fdp, ict=args.ict, progress=progress)
        return (f"wrote {args.output}: {len(made.names)} ARKit shapes on {len(made.target.mesh.vertices)} vertices "
                f"(pairs: {made.layout}; registration fit {made.fit:.4f}, landmarks {made.landmark_error:.4f})")
    if args.command == "demo":
        from .demo import run_demo, view_command

        result = run_demo(args.output, progress=progress)
        total = sum(seconds for _, seconds in result.steps)
        lines = [f"{seconds:6.1f} s  {what}" for what, seconds in result.steps]
        lines.append(f"done in {total:.1f} s; outputs in {result.folder}/:")
        lines += [f"  {path}" for path in result.outputs.values()]
        lines.append(f"open {result.outputs['report.html']} in a browser, or watch it: {view_command(result)}")
        return "\n".join(lines)
    if args.command == "view":
        server = pipeline.view(args.model, video=args.video, fap=args.fap, port=args.port)
        print(f"faceanim view: {server.url} (Ctrl-C to stop)", flush=True)
        if not args.no_browser:
            import webbrowser

            webbrowser.open(server.url)
        try:
            server.serve_forever()
        except KeyboardInterrupt:  # Ctrl-C (or SIGTERM) is how the viewer stops: exit 0, nothing to clean up
            pass
        finally:
            server.close()
        return ""
    if args.command == "express":
        animation, made = pipeline.express(args.output, au=args.au, emotion=args.emotion, intensity=args.intensity,
                                           target_mesh=args.target, points=args.points, fdp=args.fdp,
                                           frames=args.frames, fps=args.fps, route=args.route, progress=progress,
                                           force=args.force)
        from .synth.facs import recipe_text

        return f"wrote {args.output}: AUs {recipe_text(made)}" + (f", {len(animation)} frames" if args.frames else "")
    if args.command == "aus":
        numbers, values = pipeline.aus(args.video, args.output, neutral=args.neutral, smoothing=not args.no_filter,
                                       progress=progress)
        return f"wrote {args.output}: {len(values)} frames, {len(numbers)} action units"
    if args.command == "fap-info":
        return pipeline.fap_info(args.fap)
    if args.command == "blendshapes":
        from .arkit import blendshapes

        _, summary = blendshapes(args.video, args.output, neutral=args.neutral, smoothing=not args.no_filter,
                                 progress=progress)
        return f"wrote {summary}"
    if args.command == "fap-compress":
        from .compression import fap_compress

        result = fap_compress(args.source, args.output, quant=args.quant, faps=args.faps, packet=args.packet)
        return f"wrote {args.output}: {result.summary()}"
    if args.command == "fap-decompress":
        from .compression import fap_decompress

        result = fap_decompress(args.source, args.output, speaker=args.speaker,
                                temporal=False if args.frame_by_frame else None, causal=args.causal)
        return f"wrote {args.output}: {result.frames} frames, {len(result.faps)} FAPs" + (
            f", interpreted through {args.speaker}" if args.speaker else "")
    if args.command == "batch":
        from .dataset import run_batch

        result = run_batch(args.inputs, args.output, do=args.do, target_mesh=args.target, workers=args.workers,
                           address=args.address, force=args.force, progress=progress)
        return result.table()
    if args.command == "plot":
        from .export.plots import plot

        panels = plot(args.source, args.output, title=args.title)
        return f"wrote {args.output}: " + ", ".join(f"{p.name} ({len(p.curves)})" for p in panels)
    raise AssertionError(f"no handler for the command {args.command!r}")  # argparse allows only the commands above


if __name__ == "__main__":
    sys.exit(main())
