"""The web viewer: a local page that plays an animated glTF beside its source video and curves, and
mixes action units by hand (see :mod:`.server`; the page itself is in ``assets/``)."""

from .curves import fap_curves
from .server import HOST, ViewerFiles, ViewerServer, free_port

__all__ = ["HOST", "ViewerFiles", "ViewerServer", "fap_curves", "free_port"]
