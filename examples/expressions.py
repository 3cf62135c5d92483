"""Expressions made, not captured: a FACS recipe on a face, as a still, an animation and FAPs, then the
FAPs played back on the face, through the Python API.

    python3 examples/expressions.py [OUTDIR]

With no ``target_mesh`` the face is the avatar of the astronaut portrait scikit-image ships; give
``target_mesh="head.obj"`` (and ``points=`` or ``fdp=``) for your own.
"""

import sys
from pathlib import Path

import faceanim


def main(folder) -> dict:
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    # faceanim express --au 6:0.8,12:1.0 --frames 20 -o smile.fap
    _, recipe = faceanim.express(folder / "smile.fap", au="6:0.8,12:1.0", frames=20)
    print("made AUs", recipe)
    # faceanim decode smile.fap -o smile.glb   (the FAPs on the same avatar, as morph targets)
    animation = faceanim.decode(folder / "smile.fap", folder / "smile.glb", csv=folder / "smile_faps.csv")
    print(f"decoded {len(animation)} frames onto {len(animation.mesh.vertices):,} vertices")
    return {"recipe": recipe, "animation": animation}


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "expressions-example")
