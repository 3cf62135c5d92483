"""Files other tools open: glTF 2.0 binary with morph targets and animation."""

from .gltf import MorphSet, morphs_from_animation, write_glb

__all__ = ["MorphSet", "morphs_from_animation", "write_glb"]
