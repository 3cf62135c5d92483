"""An offscreen OpenGL rasteriser (moderngl on EGL): runs headless on Mesa's software renderer on a
CPU-only machine and on the GPU where there is one.

Modes: ``shaded`` (flat shading, one colour), ``textured`` (the mesh's texture, lit), ``wireframe``
(shaded with edges drawn over). A background image (the source video frame) makes an overlay.
"""

from __future__ import annotations

import numpy as np

from ..geometry.mesh import Mesh
from .camera import Camera
from .context import egl_context

__all__ = ["Renderer", "MODES"]

MODES = ("shaded", "textured", "wireframe")

_VERTEX = """
#version 330
uniform mat4 clip_from_world;
in vec3 position;
in vec2 uv;
in vec3 paint;
out vec3 world;
out vec2 texcoord;
out vec3 painted;
void main() {
    world = position;
    texcoord = uv;
    painted = paint;
    gl_Position = clip_from_world * vec4(position, 1.0);
}
"""
_FRAGMENT = """
#version 330
uniform sampler2D image;
uniform bool use_texture;
uniform bool use_paint;
uniform vec3 colour;
uniform vec3 light;
uniform vec3 eye;
in vec3 world;
in vec2 texcoord;
in vec3 painted;
out vec4 result;
void main() {
    vec3 normal = normalize(cross(dFdx(world), dFdy(world)));
    if (dot(normal, eye - world) < 0.0) normal = -normal;  // two-sided: every surface seen faces the eye
    float diffuse = max(dot(normal, light), 0.0);
    vec3 base = use_texture ? texture(image, texcoord).rgb : (use_paint ? painted : colour);
    result = vec4(base * (0.35 + 0.65 * diffuse), 1.0);
}
"""
_EDGE = """
#version 330
out vec4 result;
void main() { result = vec4(0.1, 0.1, 0.1, 1.0); }
"""
_QUAD_VERTEX = """
#version 330
in vec2 corner;
out vec2 texcoord;
void main() { texcoord = vec2(corner.x * 0.5 + 0.5, 0.5 - corner.y * 0.5); gl_Position = vec4(corner, 0.0, 1.0); }
"""
_QUAD_FRAGMENT = """
#version 330
uniform sampler2D image;
in vec2 texcoord;
out vec4 result;
void main() { result = texture(image, texcoord); }
"""


class Renderer:
    """Renders meshes to ``(height, width, 3)`` uint8 images; a context manager (holds a GL context).

    >>> from faceanim.render.camera import front_camera
    >>> square = Mesh([[-1., -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], [[0, 1, 2], [0, 2, 3]])
    >>> with Renderer(64, 64) as r:
    ...     image = r.render(square, front_camera(square.vertices, 64, 64))
    >>> image.shape, bool(image[32, 32].sum() < image[0, 0].sum())  # the square, darker than white
    ((64, 64, 3), True)
    """

    def __init__(self, width: int, height: int, *, background=(255, 255, 255)):
        if width <= 0 or height <= 0:
            raise ValueError(f"image size must be positive, got {width}x{height}")
        self._ctx = egl_context()
        self.width, self.height = int(width), int(height)
        self.background = np.asarray(background, dtype=np.float64) / 255.0
        ctx = self._ctx
        self._fbo = ctx.framebuffer(color_attachments=[ctx.renderbuffer((width, height), 4)],
                                    depth_attachment=ctx.depth_renderbuffer((width, height)))
        self._mesh_program = ctx.program(vertex_shader=_VERTEX, fragment_shader=_FRAGMENT)
        self._edge_program = ctx.program(vertex_shader=_VERTEX.replace("out vec2 texcoord;", "").replace(
            "texcoord = uv;", "").replace("out vec3 painted;", "").replace("painted = paint;", ""),
            fragment_shader=_EDGE)
        self._quad_program = ctx.program(vertex_shader=_QUAD_VERTEX, fragment_shader=_QUAD_FRAGMENT)
        corners = np.array([-1, -1, 1, -1, 1, 1, -1, -1, 1, 1, -1, 1], dtype="f4")
        self._quad = ctx.vertex_array(self._quad_program, [(ctx.buffer(corners.tobytes()), "2f", "corner")])

    def render(self, mesh: Mesh, camera: Camera, *, positions=None, mode: str = "shaded",
               colour=(200, 170, 150), background: np.ndarray | None = None, depth: bool = False,
               part_colours: dict | None = None, light=(0.0, 0.0, 1.0), vertex_colours=None):
        """Draw ``mesh`` (at ``positions (V, 3)`` if given) seen by ``camera``.

        ``part_colours`` maps part names (``mesh.part_names``, OBJ materials) to RGB colours for the
        shaded mode, or to None to leave a part out (a see-through overlay mesh); parts not named take
        ``colour``.
        ``vertex_colours``: ``(V, 3)`` uint8 RGB per vertex for the shaded mode (paint on a mesh
        without a texture), blended across each triangle; parts ``part_colours`` names keep theirs.
        ``background``: an ``(height, width, 3)`` uint8 image drawn behind the mesh (an overlay).
        ``light``: the direction the light comes from, in the camera's frame (+x right, +y up, +z
        toward the viewer); the default lights the face from the camera.
        With ``depth=True`` also returns ``(height, width)`` float64 distances along the camera's
        viewing axis (inf where no surface is seen): ``(image, depth)``.
        """
        import moderngl

        if mode not in MODES:
            raise ValueError(f"mode must be one of {', '.join(MODES)}, got {mode!r}")
        if (camera.width, camera.height) != (self.width, self.height):
            raise ValueError(f"camera is {camera.width}x{camera.height} but the renderer {self.width}x{self.height}")
        ctx = self._ctx
        split = mesh.split_at_seams()
        vertices = split.vertices if positions is None else np.asarray(positions, dtype=np.float64)[split.source_vertex]
        textured = mode == "textured" and mesh.texture is not None and split.uv is not None
        uv = split.uv if split.uv is not None else np.zeros((len(vertices), 2))
        camera_z = (np.c_[vertices, np.ones(len(vertices))] @ camera.world_to_camera.T)[:, 2]
        near, far = max(1e-3, 0.5 * -camera_z.max()), 2.0 * -camera_z.min() + 1e-3
        clip = camera.gl_matrix(near, far).astype("f4")

        self._fbo.use()
        ctx.viewport = (0, 0, self.width, self.height)
        ctx.clear(*self.background, 1.0)
        resources = []
        if background is not None:
            bg = np.ascontiguousarray(background, dtype=np.uint8)
            if bg.shape != (self.height, self.width, 3):
                raise ValueError(f"background must be a ({self.height}, {self.width}, 3) uint8 image, got {bg.shape}")
            texture = ctx.texture((self.width, self.height), 3, bg.tobytes())
            resources.append(texture)
            texture.use(0)
            self._quad_program["image"].value = 0
            ctx.disable(moderngl.DEPTH_TEST)
            self._quad.render()
        ctx.enable(moderngl.DEPTH_TEST)
        ctx.depth_func = "<="
        paint = np.zeros((len(vertices), 3))
        if vertex_colours is not None:
            given = np.asarray(vertex_colours)
            if given.shape != (len(mesh.vertices), 3):
                raise ValueError(f"vertex_colours must have shape ({len(mesh.vertices)}, 3), got {given.shape}")
            paint = given[split.source_vertex] / 255.0
        data = np.c_[vertices, uv, paint].astype("f4")
        vbo = ctx.buffer(data.tobytes())
        ibo = ctx.buffer(split.triangles.astype("i4").tobytes())
        resources += [vbo, ibo]
        program = self._mesh_program
        program["clip_from_world"].write(clip.T.tobytes())
        program["colour"].value = tuple(np.asarray(colour, dtype=np.float64) / 255.0)
        rotation = camera.world_to_camera[:3, :3]
        toward_light = np.asarray(light, dtype=np.float64)
        program["light"].value = tuple(rotation.T @ (toward_light / np.linalg.norm(toward_light)))
        program["eye"].value = tuple(np.linalg.inv(camera.world_to_camera)[:3, 3])
        program["use_texture"].value = bool(textured)
        if textured:
            image = ctx.texture((mesh.texture.shape[1], mesh.texture.shape[0]), 3,
                                np.ascontiguousarray(mesh.texture[::-1]).tobytes())
            image.build_mipmaps()
            resources.append(image)
            image.use(1)
            program["image"].value = 1
        painted = vertex_colours is not None
        groups = [(split.triangles, colour, painted)]
        if part_colours and mesh.parts is not None and not textured:
            groups = []
            for index, name in enumerate(mesh.part_names):
                chosen = split.triangles[mesh.parts == index]
                rgb = part_colours.get(name, colour)
                if len(chosen) and rgb is not None:
                    groups.append((chosen, rgb, painted and name not in part_colours))
        for triangles, rgb, use_paint in groups:
            part_ibo = ibo if triangles is split.triangles else ctx.buffer(triangles.astype("i4").tobytes())
            if part_ibo is not ibo:
                resources.append(part_ibo)
            program["colour"].value = tuple(np.asarray(rgb, dtype=np.float64) / 255.0)
            program["use_paint"].value = use_paint
            array = ctx.vertex_array(program, [(vbo, "3f 2f 3f", "position", "uv", "paint")], part_ibo)
            resources.append(array)
            array.render(moderngl.TRIANGLES)
        if mode == "wireframe":
            self._edge_program["clip_from_world"].write(clip.T.tobytes())
            edges = ctx.vertex_array(self._edge_program, [(vbo, "3f 20x", "position")], ibo)
            resources.append(edges)
            ctx.wireframe = True
            ctx.polygon_offset = (-1.0, -1.0)
            edges.render(moderngl.TRIANGLES)
            ctx.wireframe = False
            ctx.polygon_offset = (0.0, 0.0)
        pixels = np.frombuffer(self._fbo.read(components=3, alignment=1), dtype=np.uint8)
        image = pixels.reshape(self.height, self.width, 3)[::-1].copy()  # GL's first row is the bottom
        distance = None
        if depth:
            raw = np.frombuffer(self._fbo.read(attachment=-1, components=1, dtype="f4", alignment=1), dtype=np.float32)
            z = 2.0 * raw.reshape(self.height, self.width)[::-1].astype(np.float64) - 1.0
            distance = 2.0 * far * near / ((far + near) - z * (far - near))
            distance[raw.reshape(self.height, self.width)[::-1] >= 1.0] = np.inf
        for resource in resources:
            resource.release()
        return (image, distance) if depth else image

    def close(self):
        if self._ctx is not None:
            self._ctx.release()
            self._ctx = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
