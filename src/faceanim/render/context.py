"""The one way faceanim opens an offscreen OpenGL context: moderngl on EGL (Mesa's software
rasteriser on a CPU-only machine, the GPU's driver where there is one)."""

from __future__ import annotations

__all__ = ["egl_context"]


def egl_context(purpose: str = "rendering"):
    """A standalone moderngl context on EGL.

    Raises
    ------
    ImportError
        moderngl is not installed (named with the extra that installs it).
    RuntimeError
        No EGL display could be made (named with what installs Mesa's EGL).
    """
    try:
        import moderngl
    except ImportError:
        raise ImportError(f"{purpose} needs moderngl: pip install 'faceanim[render]'") from None
    try:
        return moderngl.create_context(standalone=True, backend="egl")
    except Exception as exc:  # moderngl raises plain Exception when no EGL display can be made
        raise RuntimeError(f"no OpenGL context (EGL) could be made: {exc}; install Mesa's EGL "
                           "(scripts/setup.sh does)") from None
