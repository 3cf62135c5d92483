"""Semantic rigs: the 52 ARKit blendshapes made on any target face from ICT-FaceKit's shapes."""

from .arkit import ARKIT_NAMES, EMPTY_IN_ICT, ICT_SHAPES, arkit_of_ict
from .ictface import IctFaceKit, find_ict, load_ict
from .make import ArkitRig, control_pairs, make_arkit_rig

__all__ = ["ARKIT_NAMES", "EMPTY_IN_ICT", "ICT_SHAPES", "ArkitRig", "IctFaceKit", "arkit_of_ict", "control_pairs",
           "find_ict", "load_ict", "make_arkit_rig"]
