"""The rig job: ``faceanim rig TARGET -o rigged.glb``, the 52 ARKit blendshapes made on any face mesh.

Composed from :mod:`faceanim.rig` (the shapes carried from ICT-FaceKit through a dense registration,
see :mod:`faceanim.rig.make`), :func:`~faceanim.inputs.load_target` (the mesh and its control points)
and the glTF writer. The ``.glb`` holds the target's own vertices in their order, the 52 shapes as
morph targets named as ARKit names them (:data:`~faceanim.rig.arkit.ARKIT_NAMES`, in that order),
every weight 0, in metres; its extras carry the control points (so the file animates without
placement again) and ``"arkit"``: the shapes' source and the ones made empty (``tongueOut``).
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["make_rig"]


def make_rig(target_mesh, output, *, points=None, fdp=None, ict=None, progress=None):
    """``faceanim rig``: write ``target_mesh`` with the 52 ARKit shapes as morph targets to ``output``
    (``.glb``). ``points`` / ``fdp``: the target's control points (as for ``animate``; placed
    automatically when neither is given); ``ict``: ICT-FaceKit's folder (see
    :func:`~faceanim.rig.ictface.find_ict`). Returns the :class:`~faceanim.rig.make.ArkitRig`.

    Raises
    ------
    InputError
        A bad output path (before any work), no ICT-FaceKit, a mesh with no face found on it, control
        points that do not name the face's points, or a registration that did not converge.
    """
    from .export import MorphSet, write_glb
    from .inputs import load_target, target_unit
    from .outputs import check_outputs
    from .progress import as_progress
    from .rig.arkit import EMPTY_IN_ICT
    from .rig.ictface import load_ict
    from .rig.make import make_arkit_rig

    output = Path(output)
    check_outputs({"-o": (output, ".glb")}, inputs={"TARGET": target_mesh, "--points": points, "--fdp": fdp})
    shown = as_progress(progress)
    model = load_ict(ict)
    target = load_target(target_mesh, points=points, fdp=fdp, progress=shown)
    unit = target_unit(target, str(target_mesh))
    shown.status(f"registering ICT-FaceKit onto {Path(target_mesh).name} and carrying its 52 ARKit shapes "
                 "(about a minute)")
    made = make_arkit_rig(target, model)
    shown.status(f"writing {output}")
    extras = {"points": dict(target.points),
              "arkit": {"source": "ICT-FaceKit expression shapes through dense registration",
                        "layout": made.layout, "empty": list(EMPTY_IN_ICT)}}
    write_glb(output, target.mesh, MorphSet(made.shapes, made.names), extras=extras, metres_per_unit=unit)
    return made
