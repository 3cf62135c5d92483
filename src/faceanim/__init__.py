"""faceanim: the motion of a real face onto any 3D face.

The core (meshes, MPEG-4 tables, RBF warps, projection, expression transfer) needs only numpy and
scipy. See ``shared/ARCHITECTURE.md`` for the house plan.

The jobs the ``faceanim`` command runs are functions here, with the command's options as keyword
arguments (``--no-filter`` is ``smoothing=False``, ``--start-face`` is ``start_face=``); each writes
its outputs complete or not at all and returns what it made. They import lazily, so ``import
faceanim`` stays light (the standard library alone; numpy and scipy come with the first job or type used)::

    import faceanim

    track = faceanim.track("d0.mp4", "d0.npz", csv="d0_landmarks.csv")   # a Track
    stream, clipped = faceanim.encode("d0.npz", "d0.fap")                # a FapStream
    numbers, intensities = faceanim.aus("d0.mp4", "d0_aus.csv")          # OpenFace's columns
    faceanim.plot("d0_aus.csv", "d0_aus.png")                            # one panel per group
    result = faceanim.batch(["videos/"], "out", do="encode,aus", workers=2)   # on Ray; result.table()

>>> import faceanim
>>> sorted(set(faceanim.JOBS) - set(faceanim.__all__))
[]
>>> faceanim.encode.__module__
'faceanim.pipeline'
"""

from __future__ import annotations

import importlib

from .errors import FileFormatError, InputError

# The core's types and readers, by name: imported on first use too, so that ``import faceanim`` (and the
# command's ``import faceanim.cli``) loads nothing beyond the standard library, and a Ctrl-C while numpy
# and scipy load lands inside the command, which says so in one line.
_CORE = {"Mesh": "faceanim.geometry", "RbfWarp": "faceanim.geometry", "read_mesh": "faceanim.geometry",
         "write_mesh": "faceanim.geometry", "read_livelink_csv": "faceanim.rig.livelink"}

__version__ = "0.1.0"

# The jobs, by name: (module, function), imported on first use.
JOBS = {
    "track": ("faceanim.pipeline", "track"),
    "encode": ("faceanim.pipeline", "encode"),
    "decode": ("faceanim.pipeline", "decode"),
    "animate": ("faceanim.pipeline", "animate"),
    "transfer": ("faceanim.pipeline", "transfer"),
    "avatar": ("faceanim.pipeline", "avatar"),
    "fap_info": ("faceanim.pipeline", "fap_info"),
    "view": ("faceanim.pipeline", "view"),
    "express": ("faceanim.expressions", "express"),
    "aus": ("faceanim.expressions", "aus"),
    "plot": ("faceanim.export.plots", "plot"),
    "batch": ("faceanim.dataset", "run_batch"),
    "fap_compress": ("faceanim.compression", "fap_compress"),
    "fap_decompress": ("faceanim.compression", "fap_decompress"),
    "build_speaker": ("faceanim.speech", "build_speaker"),
    "analyse_speech": ("faceanim.speech", "analyse_speech"),
    "blendshapes": ("faceanim.arkit", "blendshapes"),
    "make_rig": ("faceanim.rigging", "make_rig"),
}  # no job shares its name with a module of the package (``faceanim.demo`` is the module; its job is run_demo)

__all__ = ["FileFormatError", "InputError", "JOBS", "Mesh", "RbfWarp", "__version__", "read_livelink_csv", "read_mesh",
           "write_mesh", *JOBS]


def __getattr__(name: str):
    if name in JOBS or name in _CORE:
        module, attribute = JOBS[name] if name in JOBS else (_CORE[name], name)
        job = getattr(importlib.import_module(module), attribute)
        globals()[name] = job  # once imported, an ordinary attribute
        return job
    raise AttributeError(f"module 'faceanim' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(JOBS) | set(_CORE))
