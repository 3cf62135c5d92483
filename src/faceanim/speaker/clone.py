"""Drawing the speaker's clone video-realistically: the key textures mixed pixel by pixel with the
posture's blending weights, over the mesh moved by the articulatory model, the head's rigid motion and
the video's camera, over a background (the video's frame), with an optional wireframe.

:class:`CloneRenderer` holds an offscreen OpenGL context (moderngl on EGL, as
:class:`faceanim.render.rasterizer.Renderer`) with the key textures loaded once as one texture array.
Two ways to mix, measured by ``benchmarks/clone_realism.py``: ``"shader"`` (the default: the fragment
shader samples the Q textures and mixes them with the weights, a uniform per frame) and ``"cpu"``
(numpy mixes the textures, one texture upload and one textured pass per frame).

The mesh's vertices are projected in numpy through the 3x4 camera (:mod:`.camera`) and handed to GL
as clip coordinates with their depth as ``w``, so the texture is interpolated with perspective.
"""

from __future__ import annotations

import numpy as np

from ..render.context import egl_context
from .appearance import Appearance, posture_points
from .camera import from_rigid, moved, to_rigid

__all__ = ["CloneRenderer", "BLENDS", "mesh_edges"]

BLENDS = ("shader", "cpu")
_MAX_KEYS = 8

_VERTEX = """
#version 330
in vec4 position;
in vec2 uv;
out vec2 texcoord;
void main() { texcoord = uv; gl_Position = position; }
"""
_BLEND = """
#version 330
uniform sampler2DArray keys;
uniform float weights[MAX_KEYS];
uniform int count;
in vec2 texcoord;
out vec4 result;
void main() {
    vec3 mixed = vec3(0.0);
    for (int q = 0; q < count; ++q) mixed += weights[q] * texture(keys, vec3(texcoord, float(q))).rgb;
    result = vec4(mixed, 1.0);
}
""".replace("MAX_KEYS", str(_MAX_KEYS))
_SINGLE = """
#version 330
uniform sampler2D image;
in vec2 texcoord;
out vec4 result;
void main() { result = vec4(texture(image, texcoord).rgb, 1.0); }
"""
_EDGE = """
#version 330
uniform vec3 colour;
out vec4 result;
void main() { result = vec4(colour, 1.0); }
"""


def mesh_edges(triangles) -> np.ndarray:
    """``(E, 2)`` the distinct edges of ``triangles (F, 3)``."""
    t = np.asarray(triangles, dtype=np.int64)
    edges = np.sort(np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]]), axis=1)
    return np.unique(edges, axis=0)


class CloneRenderer:
    """Renders a speaker's clone to ``(height, width, 3)`` uint8 images; a context manager.

    Parameters
    ----------
    model : SpeakerModel
    appearance : Appearance
    width, height : int, optional
        The image size (default: the appearance's video frame size). The camera maps to normalised
        screen coordinates, so any size shows the same view.
    blend : {"shader", "cpu"}
        Where the key textures are mixed (see the module's docstring).
    """

    def __init__(self, model, appearance: Appearance, *, width: int | None = None, height: int | None = None,
                 blend: str = "shader"):
        try:
            import moderngl
        except ImportError:
            raise ImportError("rendering needs moderngl: pip install 'faceanim[render]'") from None
        if blend not in BLENDS:
            raise ValueError(f"blend must be one of {', '.join(BLENDS)}, got {blend!r}")
        if not isinstance(appearance, Appearance):
            raise TypeError(f"appearance must be an Appearance, got {type(appearance).__name__}")
        N = len(model.names) + len(model.static_names)
        if len(appearance.uv) != N or appearance.key_parameters.shape[1] != model.parameter_count:
            raise ValueError(f"the appearance is of another model ({len(appearance.uv)} points, "
                             f"{appearance.key_parameters.shape[1]} parameters; the model has {N} and "
                             f"{model.parameter_count})")
        if len(appearance.key_parameters) > _MAX_KEYS:
            raise ValueError(f"at most {_MAX_KEYS} key postures, got {len(appearance.key_parameters)}")
        width = appearance.frame_size[0] if width is None else width
        height = appearance.frame_size[1] if height is None else height
        if width <= 0 or height <= 0:
            raise ValueError(f"image size must be positive, got {width}x{height}")
        self.model, self.appearance, self.blend = model, appearance, blend
        self.width, self.height = int(width), int(height)
        self.triangles = model.triangles if appearance.triangles is None else appearance.triangles
        self._ctx = None
        ctx = egl_context("the clone's renderer")
        self._ctx = ctx
        self._fbo = ctx.framebuffer(color_attachments=[ctx.renderbuffer((self.width, self.height), 4)],
                                    depth_attachment=ctx.depth_renderbuffer((self.width, self.height)))
        S, Q = appearance.size, len(appearance.key_parameters)
        if blend == "shader":
            self._program = ctx.program(vertex_shader=_VERTEX, fragment_shader=_BLEND)
            self._keys = ctx.texture_array((S, S, Q), 3, np.ascontiguousarray(appearance.textures).tobytes())
            self._keys.filter = (moderngl.LINEAR, moderngl.LINEAR)
            self._keys.repeat_x = self._keys.repeat_y = False
            self._program["keys"].value = 0
            self._program["count"].value = Q
        else:
            self._program = ctx.program(vertex_shader=_VERTEX, fragment_shader=_SINGLE)
            self._keys = ctx.texture((S, S), 3)
            self._keys.filter = (moderngl.LINEAR, moderngl.LINEAR)
            self._keys.repeat_x = self._keys.repeat_y = False
            self._program["image"].value = 0
            self._stack = appearance.textures.astype(np.float32)
        self._edges = ctx.program(vertex_shader=_VERTEX.replace("out vec2 texcoord;", "").replace(
            "texcoord = uv; ", "").replace("in vec2 uv;", ""), fragment_shader=_EDGE)
        self._vbo = ctx.buffer(reserve=N * 6 * 4, dynamic=True)
        self._ibo = ctx.buffer(self.triangles.astype("i4").tobytes())
        self._lines = ctx.buffer(mesh_edges(self.triangles).astype("i4").tobytes())
        self._array = ctx.vertex_array(self._program, [(self._vbo, "4f 2f", "position", "uv")], self._ibo)
        self._edge_array = ctx.vertex_array(self._edges, [(self._vbo, "4f 8x", "position")], self._lines)

    # ---- geometry

    def points(self, parameters) -> np.ndarray:
        """``(N, 3)`` the mesh's points (head frame, cm) at ``parameters (K,)``."""
        return posture_points(self.model, np.asarray(parameters, dtype=np.float64)[None])[0]

    def clip(self, points, rigid, camera=None) -> np.ndarray:
        """``(N, 4)`` float32 GL clip coordinates of head-frame ``points (N, 3)`` moved by ``rigid (6,)``
        through ``camera (3, 4)`` (default: the appearance's); ``w`` is the depth."""
        P = self.appearance.camera if camera is None else np.asarray(camera, dtype=np.float64)
        X = moved(points, rigid)
        h = X @ P[:, :3].T + P[:, 3]
        w = h[:, 2]
        u, v = h[:, 0] / w, h[:, 1] / w
        used = np.unique(self.triangles)
        near, far = w[used].min(), w[used].max()
        z = 2.0 * (w - near) / max(far - near, 1e-12) - 1.0  # the mesh's depths spread over (-0.9, 0.9)
        return (np.c_[2.0 * u - 1.0, 1.0 - 2.0 * v, 0.9 * z, np.ones_like(w)] * w[:, None]).astype(np.float32)

    def rest_rigid(self) -> np.ndarray:
        """``(6,)`` the head's rigid motion in the rest key frame (the default pose)."""
        rigid = self.appearance.key_rigid
        if rigid is None:
            return to_rigid(np.eye(3), np.zeros(3))
        return rigid[0].copy()

    # ---- drawing

    def render(self, parameters, rigid=None, *, camera=None, background=None, wireframe: bool = False,
               wire_colour=(40, 220, 90), mask: bool = False):
        """The clone at ``parameters (K,)`` with the head at ``rigid (6,)`` (rotation vector, translation
        cm; default the rest key frame's) seen by ``camera (3, 4)`` (default the appearance's).

        ``background``: ``(height, width, 3)`` uint8 drawn behind (default black). ``wireframe``: the
        synthesis mesh's edges drawn over. With ``mask=True`` also returns the ``(height, width)`` bool
        coverage of the clone: ``(image, mask)``.
        """
        import moderngl

        if self._ctx is None:
            raise RuntimeError("the renderer is closed")
        a = np.asarray(parameters, dtype=np.float64).reshape(-1)
        if a.shape != (self.model.parameter_count,) or not np.isfinite(a).all():
            raise ValueError(f"parameters must be {self.model.parameter_count} finite numbers, got {a.shape}")
        rigid = self.rest_rigid() if rigid is None else np.asarray(rigid, dtype=np.float64)
        from_rigid(rigid)  # checks its shape
        points = self.points(a)
        weights = self.appearance.weights(points)
        data = np.c_[self.clip(points, rigid, camera), self.appearance.uv].astype("f4")
        ctx = self._ctx
        with ctx:  # this renderer's context made current (another renderer may be open)
            self._vbo.write(data.tobytes())
            self._fbo.use()
            ctx.viewport = (0, 0, self.width, self.height)
            ctx.clear(0.0, 0.0, 0.0, 0.0)
            ctx.enable(moderngl.DEPTH_TEST)
            ctx.depth_func = "<="
            if self.blend == "shader":
                padded = np.zeros(_MAX_KEYS, dtype="f4")
                padded[:len(weights)] = weights
                self._program["weights"].write(padded.tobytes())
            else:
                mixed = np.tensordot(weights.astype(np.float32), self._stack, axes=1)
                self._keys.write(np.clip(mixed + 0.5, 0, 255).astype(np.uint8).tobytes())
            self._keys.use(0)
            self._array.render(moderngl.TRIANGLES)
            if wireframe:
                self._edges["colour"].value = tuple(np.asarray(wire_colour, dtype=np.float64) / 255.0)
                ctx.disable(moderngl.DEPTH_TEST)
                self._edge_array.render(moderngl.LINES)
            raw = np.frombuffer(self._fbo.read(components=4, alignment=1), dtype=np.uint8)
            rgba = raw.reshape(self.height, self.width, 4)[::-1]
        covered = rgba[..., 3] > 0
        if background is None:
            image = np.ascontiguousarray(rgba[..., :3])
        else:
            bg = np.asarray(background)
            if bg.shape != (self.height, self.width, 3) or bg.dtype != np.uint8:
                raise ValueError(f"background must be a ({self.height}, {self.width}, 3) uint8 image, "
                                 f"got {bg.dtype} {bg.shape}")
            image = np.where(covered[..., None], rgba[..., :3], bg)
        return (image, covered) if mask else image

    def close(self):
        if self._ctx is not None:
            with self._ctx:
                for resource in (self._array, self._edge_array, self._vbo, self._ibo, self._lines, self._keys,
                                 self._program, self._edges, self._fbo):
                    resource.release()
            self._ctx.release()
            self._ctx = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
