"""Files other tools open: glTF 2.0 binary with morph targets and animation, OBJ sequences, FAP curves
as CSV."""

from .curves import write_au_csv, write_fap_csv
from .gltf import MorphSet, morphs_from_animation, write_glb
from .objseq import write_obj_sequence

__all__ = ["MorphSet", "morphs_from_animation", "write_au_csv", "write_fap_csv", "write_glb", "write_obj_sequence"]
