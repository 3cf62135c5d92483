"""Files other tools open: glTF 2.0 binary with morph targets and animation, OBJ sequences, FAP curves
as CSV."""

from .curves import read_curve_csv, write_au_csv, write_fap_csv, write_landmark_csv
from .gltf import write_glb
from .morphs import MorphSet, morphs_from_animation
from .objseq import write_obj_sequence

__all__ = ["MorphSet", "morphs_from_animation", "read_curve_csv", "write_au_csv", "write_fap_csv", "write_glb",
           "write_landmark_csv", "write_obj_sequence"]
