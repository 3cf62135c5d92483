"""Pictures of meshes: a pinhole camera and an offscreen OpenGL rasteriser (moderngl on EGL).

moderngl is imported only when a Renderer is made; install it with ``pip install faceanim[render]``.
"""

from .camera import Camera, front_camera, look_at

__all__ = ["Camera", "front_camera", "look_at"]
