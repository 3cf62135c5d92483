"""The 52 ARKit blendshape names, and how ICT-FaceKit's 53 expression shapes make them.

:data:`ARKIT_NAMES` is Apple's ``ARFaceAnchor.BlendShapeLocation`` list in the order Live Link Face
writes its CSV columns (eyes, jaw, mouth, brows, cheeks, nose, tongue). Left and right are the
subject's own sides, as in ARKit: ``eyeBlinkLeft`` closes the subject's left eye.

ICT-FaceKit names its shapes the ARKit way with ``_L``/``_R`` for the subject's left and right
(checked on the data: ``eyeBlink_L`` moves the lid on the +x side, the subject's left, and
``mouthLeft`` moves the lips towards +x). :data:`ICT_SHAPES` says which ICT shapes make each ARKit
shape, summed:

* 49 ARKit shapes are one ICT shape each (``browDown_L`` -> ``browDownLeft``, ``jawOpen`` -> ``jawOpen``).
* ``browInnerUp`` and ``cheekPuff`` are one shape in ARKit and two halves in ICT: the sum of
  ``_L`` and ``_R``.
* ``tongueOut`` has no ICT shape (ICT's tongue has no expression): it is made as an empty shape
  (no displacement), so a rig still has all 52 names and a take that sends ``tongueOut`` plays.
  :data:`EMPTY_IN_ICT` names it.

ICT's eyeball meshes do not move in its ``eyeLook*`` shapes (only the lids follow the gaze), so the
rig's ``eyeLook*`` shapes move the lids only as well.

>>> len(ARKIT_NAMES), ICT_SHAPES["browInnerUp"], ICT_SHAPES["eyeBlinkLeft"], ICT_SHAPES["tongueOut"]
(52, ('browInnerUp_L', 'browInnerUp_R'), ('eyeBlink_L',), ())
"""

from __future__ import annotations

from types import MappingProxyType

__all__ = ["ARKIT_NAMES", "ICT_SHAPES", "EMPTY_IN_ICT", "arkit_of_ict"]

ARKIT_NAMES: tuple[str, ...] = (
    "eyeBlinkLeft", "eyeLookDownLeft", "eyeLookInLeft", "eyeLookOutLeft", "eyeLookUpLeft", "eyeSquintLeft",
    "eyeWideLeft", "eyeBlinkRight", "eyeLookDownRight", "eyeLookInRight", "eyeLookOutRight", "eyeLookUpRight",
    "eyeSquintRight", "eyeWideRight", "jawForward", "jawRight", "jawLeft", "jawOpen", "mouthClose",
    "mouthFunnel", "mouthPucker", "mouthRight", "mouthLeft", "mouthSmileLeft", "mouthSmileRight",
    "mouthFrownLeft", "mouthFrownRight", "mouthDimpleLeft", "mouthDimpleRight", "mouthStretchLeft",
    "mouthStretchRight", "mouthRollLower", "mouthRollUpper", "mouthShrugLower", "mouthShrugUpper",
    "mouthPressLeft", "mouthPressRight", "mouthLowerDownLeft", "mouthLowerDownRight", "mouthUpperUpLeft",
    "mouthUpperUpRight", "browDownLeft", "browDownRight", "browInnerUp", "browOuterUpLeft", "browOuterUpRight",
    "cheekPuff", "cheekSquintLeft", "cheekSquintRight", "noseSneerLeft", "noseSneerRight", "tongueOut",
)

_SPLIT_IN_ICT = ("browInnerUp", "cheekPuff")
_SIDEWAYS = ("jawLeft", "jawRight", "mouthLeft", "mouthRight")  # a motion towards a side, not a side's shape
EMPTY_IN_ICT: tuple[str, ...] = ("tongueOut",)


def arkit_of_ict(name: str) -> str:
    """The ARKit name of an ICT-FaceKit shape's side: ``browDown_L`` -> ``browDownLeft``; a name
    without a side is its own (``jawOpen``).

    >>> arkit_of_ict("mouthSmile_R"), arkit_of_ict("jawOpen")
    ('mouthSmileRight', 'jawOpen')
    """
    for suffix, side in (("_L", "Left"), ("_R", "Right")):
        if name.endswith(suffix):
            return name[:-len(suffix)] + side
    return name


def _ict_shapes() -> dict[str, tuple[str, ...]]:
    table = {}
    for name in ARKIT_NAMES:
        if name in _SPLIT_IN_ICT:
            table[name] = (f"{name}_L", f"{name}_R")
        elif name in EMPTY_IN_ICT:
            table[name] = ()
        elif name in _SIDEWAYS:
            table[name] = (name,)
        elif name.endswith("Left"):
            table[name] = (name[:-4] + "_L",)
        elif name.endswith("Right"):
            table[name] = (name[:-5] + "_R",)
        else:
            table[name] = (name,)
    return table


#: ARKit name -> the ICT-FaceKit shapes summed to make it (empty for :data:`EMPTY_IN_ICT`).
ICT_SHAPES: MappingProxyType = MappingProxyType(_ict_shapes())
