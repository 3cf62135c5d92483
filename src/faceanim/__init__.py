"""faceanim: the motion of a real face onto any 3D face.

The core (meshes, MPEG-4 tables, RBF warps, projection, expression transfer) needs only numpy and
scipy. See ``shared/ARCHITECTURE.md`` for the house plan.
"""

from .errors import FileFormatError, InputError
from .geometry import Mesh, RbfWarp, read_mesh, write_mesh

__version__ = "0.1.0"
__all__ = ["FileFormatError", "InputError", "Mesh", "RbfWarp", "__version__", "read_mesh", "write_mesh"]
