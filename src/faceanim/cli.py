"""The ``faceanim`` command: argument parsing only; each subcommand calls one pipeline function."""

from __future__ import annotations

import argparse
import sys

from .errors import InputError

__all__ = ["main"]


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="faceanim", description="The motion of a real face onto any 3D face.")
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
    return parser


def main(argv=None) -> int:
    """Run the command line; returns the exit status."""
    args = _parser().parse_args(argv)
    from . import pipeline

    try:
        if args.command == "transfer":
            out = pipeline.transfer(args.source_neutral, args.source_expression, args.target, args.output,
                                    correspondence=args.correspondence, method=args.method, mask=args.mask,
                                    regions=tuple(args.region))
            print(f"wrote {out}")
    except (InputError, FileNotFoundError, IsADirectoryError, PermissionError) as exc:
        print(f"faceanim: error: {exc}", file=sys.stderr)
        return 2
    except ValueError as exc:  # an argument the library rejected (shapes, ids, settings)
        print(f"faceanim: error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
