"""The analysis's image of the clone: textured triangles drawn over a small box (lip probability, or
colour with textures of several channels).

Analysis by synthesis renders the clone's mouth (the synthesis mesh around it, a few hundred
triangles, or a reduced mesh of at most 50) hundreds of times a frame, into a box of a few thousand
pixels, with a texture that is a per-pixel mix of the key postures' textures (their colours, or their
lip probabilities). Two implementations draw exactly that:

* :class:`NumpyLipRaster`: every triangle's pixels found at once (each triangle's bounding box
  expanded into candidate pixels, kept where the barycentric coordinates are all >= 0), the texture
  read bilinearly at the interpolated UV; no context, so it runs wherever numpy does.
* :class:`GlLipRaster` (the tracker's default where a context can be made): moderngl on EGL (Mesa's
  software rasteriser on a CPU, the GPU where there is one), one float framebuffer, the textures in
  one float texture array mixed in the fragment shader; triangles beside the box are not drawn. It
  measured faster on the speech clips (``benchmarks/clone_tracking.py``: 11.4-11.6 against 7.4-7.6
  frames/s for the colour comparison on a 2-core machine at a load of about 1).

Both take vertices in box pixels (x right, y down, pixel ``(i, j)`` covering ``[j, j+1) x [i, i+1)``,
sampled at its centre ``(j + 0.5, i + 0.5)``), texture coordinates ``uv`` in ``[0, 1]`` (``u`` along
a texture's columns, ``v`` along its rows, row 0 first) and return ``(height, width) float32``, with
``background`` where no triangle covers a pixel.

With ``offsets`` (n points of a pixel, as shares of it from its centre) a covered pixel's value is
the mean of the texture read at those points, each through the texture map of the triangle covering
the pixel's centre; which pixels are covered does not change. The analysis's box pixel spans
``factor x factor`` frame pixels (:class:`faceanim.speaker.analysis.CloneAnalyser`); it reads the
clone at the centres of the frame pixels it compares under each box pixel, where the clone's renderer
reads the texture for those pixels: the middle one (the mesh moved so that its centre is the box
pixel's, an exact match), or all of them (through ``offsets``; where a box pixel straddles two
triangles, the reads go through the map of the one covering its centre). With textures no finer than
a frame pixel these are the renderer's values (finer, the analyser blurs them to a pixel's scale, as a
camera's pixel integrates its area). A blur of the textures to the box pixel's scale instead (read
once at its centre, against the frame averaged over the box pixel) is one isotropic blur for the whole
mouth, while the texture map's stretch varies from triangle to triangle (on the speech clips by 1.3x
between its axes on a median triangle, 1.9x on the 90th percentile): on the clone's own frames the
cost's minimum lay about three times as far from the truth (0.17 against 0.06 of a parameter's
spread, ``benchmarks/results/clone_tracking.md``). The texels read cost n times more; the triangles
and pixels drawn, the same.
"""

from __future__ import annotations

import numpy as np

from ..render.context import egl_context
from ..validation import as_array, as_index_array

__all__ = ["NumpyLipRaster", "GlLipRaster", "RASTERS", "prefilter", "prefilter_block"]

RASTERS = ("numpy", "gl")


def prefilter_block(footprint: float) -> int:
    """``k``, the texels :func:`prefilter` averages into one along each side for a pixel
    ``footprint`` texels wide (1: not averaged), about a third of the footprint. Its texel ``J`` is
    centred on the original's texel coordinate ``(J + 0.5) k``: texture coordinates ``uv`` read it at
    ``uv S / k`` of its texels (not ``uv (S // k)``, which would shift what is read by up to ``k / 2``
    texels at the far side)."""
    if float(footprint) / np.sqrt(12.0) < 0.5:
        return 1
    return max(1, int(round(float(footprint) / 3.0)))


def prefilter(textures, footprint: float) -> np.ndarray:
    """``textures (Q, S, S)`` (or ``(Q, S, S, C)``, C channels) as a pixel ``footprint`` texels wide
    sees them: read at the pixel's centre, they give about the pixel's mean (a camera's pixel
    integrates its area). The pixel spreads a texel over ``footprint^2 / 12`` texels squared (a box's
    variance) plus the sixth of a texel squared of the renderer's own bilinear reads; three blurs make
    up the same here: a Gaussian, then the average over blocks of ``k`` texels
    (:func:`prefilter_block`, about ``footprint / 3``; ``(k^2 - 1) / 12``), then the bilinear read of
    the result (``k^2 / 6``). The result is ``(Q, S // k, S // k[, C])`` float32, about 3 texels a
    pixel: small enough to mix and read quickly. Under 1.73 texels a pixel (a spread under half a
    texel) the textures come back as they are: the bilinear read is the filter.

    >>> t = np.zeros((1, 12, 12), np.float32); t[0, 6, 6] = 1
    >>> small = prefilter(t, 6.0)
    >>> small.shape, bool(abs(small.sum() * 4 - 1) < 1e-2)  # the mean kept (4 texels a block)
    ((1, 6, 6), True)
    >>> bool(np.array_equal(prefilter(t, 1.0), t))
    True
    """
    from scipy.ndimage import gaussian_filter

    t = np.asarray(textures, dtype=np.float32)
    footprint = float(footprint)
    if footprint / np.sqrt(12.0) < 0.5:  # under a texel: bilinear reading is the filter
        return np.ascontiguousarray(t)
    k = prefilter_block(footprint)
    sigma = np.sqrt(max(footprint ** 2 / 12.0 + 1.0 / 6.0 - (k * k - 1) / 12.0 - k * k / 6.0, 0.0))
    if sigma > 0:
        t = gaussian_filter(t, sigma=(0, sigma, sigma) + (0,) * (t.ndim - 3), mode="nearest")
    if k > 1:
        Q, S, R = t.shape[:3]
        t = t[:, :S // k * k, :R // k * k].reshape(Q, S // k, k, R // k, k, *t.shape[3:]).mean(axis=(2, 4))
    return np.ascontiguousarray(t, dtype=np.float32)


def _reaching(xy: np.ndarray, triangles: np.ndarray, width: int, height: int) -> np.ndarray:
    """``(F,) bool``: the ``triangles (F, 3)`` at vertices ``xy (V, 2)`` (box pixels) whose bounding
    box meets the span of the ``width x height`` box's pixel centres (``[0.5, width - 0.5] x [0.5,
    height - 0.5]``); the others cover none of its pixels, so leaving them out changes no pixel. A
    triangle's box misses the span when its three corners lie beyond the same one of its four sides
    (each vertex's side codes, and-ed).

    >>> # inside the box, beside it, thin by its left edge, reaching over that edge
    >>> xy = np.array([[0, 0], [4, 0], [0, 4], [5, 0], [9, 0], [5, 4], [0.6, 1], [1.4, 1], [1, 3], [0, 1], [0.4, 1]])
    >>> _reaching(xy, np.array([[0, 1, 2], [3, 4, 5], [6, 7, 8], [9, 10, 8]]), 4, 4).tolist()
    [True, False, True, True]
    >>> _reaching(xy, np.array([[9, 10, 9]]), 4, 4).tolist()  # left of every centre
    [False]
    """
    x, y = xy[:, 0], xy[:, 1]
    code = ((x < 0.5) | ((x > width - 0.5) << 1) | ((y < 0.5) << 2) | ((y > height - 0.5) << 3)).astype(np.uint8)
    corners = code[triangles]
    return (corners[:, 0] & corners[:, 1] & corners[:, 2]) == 0


class _Raster:
    """What both implementations check and keep: the triangles, the UV, the textures, the box and the
    points of each pixel the texture is read at (``offsets``)."""

    def __init__(self, triangles, uv, textures, *, width: int, height: int, background: float = 0.0,
                 offsets=None):
        self.uv = as_array(uv, "uv", shape=("V", 2), frozen=True)
        self.triangles = as_index_array(triangles, "triangles", upper=len(self.uv), shape=("F", 3), frozen=True)
        t = np.asarray(textures, dtype=np.float32)
        if t.ndim not in (3, 4) or t.shape[0] < 1 or (t.ndim == 4 and not 1 <= t.shape[3] <= 4):
            raise ValueError(f"textures must have shape (Q, S, S) or (Q, S, S, C) with C <= 4, got {t.shape}")
        self.textures = t
        self.channels = 1 if t.ndim == 3 else t.shape[3]
        if int(width) <= 0 or int(height) <= 0:
            raise ValueError(f"box size must be positive, got {width}x{height}")
        self.width, self.height, self.background = int(width), int(height), float(background)
        offsets = np.zeros((1, 2)) if offsets is None else np.asarray(offsets, dtype=np.float64)
        if (offsets.ndim != 2 or offsets.shape[1] != 2 or not len(offsets) or not np.isfinite(offsets).all()
                or np.abs(offsets).max() > 0.5):
            raise ValueError("offsets must be (n, 2) shares of a pixel (x, y) within 0.5 of its centre, "
                             f"got {offsets!r}")
        self.offsets = tuple((float(x), float(y)) for x, y in offsets)

    def _check(self, xy, weights) -> tuple[np.ndarray, np.ndarray]:
        xy = np.asarray(xy, dtype=np.float64)
        if xy.shape != self.uv.shape:
            raise ValueError(f"xy must have shape {self.uv.shape}, got {xy.shape}")
        w = np.asarray(weights, dtype=np.float32).reshape(-1)
        if len(w) != len(self.textures):
            raise ValueError(f"weights must hold {len(self.textures)} values, got {len(w)}")
        return xy, w


class NumpyLipRaster(_Raster):
    """The lip-probability image of a small mesh, rasterised with numpy (see the module's docstring).

    Parameters
    ----------
    triangles : (F, 3) int64
    uv : (V, 2) float64
        Each vertex's texture coordinates in ``[0, 1]``.
    textures : (Q, s, s) or (Q, s, s, C) float32
        The key postures' lip-probability textures, or their colours (C channels), no finer than the
        reads' spacing (:func:`prefilter`).
    width, height : int
        The box, pixels.
    background : float
        The value where no triangle lies.
    offsets : (n, 2) float64, optional
        The points of each pixel the texture is read at and averaged, ``(x, y)`` as shares of the pixel
        from its centre (each within 0.5; see the module's docstring); default its centre.

    >>> square = NumpyLipRaster([[0, 1, 2], [0, 2, 3]], [[0, 0], [1, 0], [1, 1], [0, 1]],
    ...                         np.ones((1, 4, 4), np.float32), width=8, height=8)
    >>> image = square([[2, 2], [6, 2], [6, 6], [2, 6]], [1.0])
    >>> float(image.sum())  # the 4 x 4 pixels whose centres lie in the square
    16.0
    """

    def __init__(self, triangles, uv, textures, *, width: int, height: int, background: float = 0.0,
                 offsets=None):
        super().__init__(triangles, uv, textures, width=width, height=height, background=background,
                         offsets=offsets)
        Q, s, r = self.textures.shape[:3]
        self._flat = np.ascontiguousarray(self.textures.reshape(Q, -1))  # (Q, s*r*C): mixed by one product
        self._size = (s, r)
        self._uv_corners = self.uv[self.triangles]  # (F, 3, 2)

    def _affine(self, xy) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per triangle at vertices ``xy``: its corners ``(F, 3, 2)``, the barycentric coordinates
        ``l1, l2`` as affine functions of a point, ``(F, 6)`` (``l1 = k0 x + k1 y + k2``, ``l2 = k3 x +
        k4 y + k5``), and whether it has an area ``(F,)``."""
        corners = np.asarray(xy, dtype=np.float64)[self.triangles]
        a = corners[:, 0]
        e1, e2 = corners[:, 1] - a, corners[:, 2] - a
        det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
        solid = np.abs(det) > 1e-12  # a degenerate triangle covers nothing
        inv = 1.0 / np.where(solid, det, 1.0)
        coef = np.stack([e2[:, 1] * inv, -e2[:, 0] * inv, (e2[:, 0] * a[:, 1] - e2[:, 1] * a[:, 0]) * inv,
                         -e1[:, 1] * inv, e1[:, 0] * inv, (e1[:, 1] * a[:, 0] - e1[:, 0] * a[:, 1]) * inv], axis=1)
        return corners, coef, solid

    def _spans(self, corners, solid) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(triangle (n,), px (n,), py (n,))``: the pixels whose centres each triangle covers, found
        row by row (each row's span between the triangle's edges), so the candidates are about the
        pixels covered, not the triangles' bounding boxes."""
        W, H = self.width, self.height
        ys = corners[:, :, 1]
        top = np.maximum(np.ceil(ys.min(axis=1) - 0.5), 0).astype(np.int64)
        bottom = np.minimum(np.floor(ys.max(axis=1) - 0.5), H - 1).astype(np.int64)
        xs = corners[:, :, 0]
        seen = solid & (xs.max(axis=1) >= 0.5) & (xs.min(axis=1) <= W - 0.5)  # a triangle beside the box: none
        rows = np.where(seen, np.maximum(bottom - top + 1, 0), 0)
        total = int(rows.sum())
        if total == 0:
            return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, np.int64)
        triangle = np.repeat(np.arange(len(rows)), rows)
        row = top[triangle] + np.arange(total) - np.repeat(np.cumsum(rows) - rows, rows)
        y = row + 0.5
        p = corners[triangle]  # (m, 3, 2)
        q = np.roll(p, -1, axis=1)  # each edge's other end
        py, qy = p[:, :, 1], q[:, :, 1]
        crosses = (np.minimum(py, qy) <= y[:, None]) & (np.maximum(py, qy) >= y[:, None]) & (py != qy)
        t = (y[:, None] - py) / np.where(py != qy, qy - py, 1.0)
        x = p[:, :, 0] + t * (q[:, :, 0] - p[:, :, 0])
        left = np.where(crosses, x, np.inf).min(axis=1)
        right = np.where(crosses, x, -np.inf).max(axis=1)
        first = np.maximum(np.ceil(left - 0.5 - 1e-9), 0).astype(np.int64)
        last = np.minimum(np.floor(right - 0.5 + 1e-9), W - 1).astype(np.int64)
        count = np.maximum(last - first + 1, 0)
        n = int(count.sum())
        pick = np.repeat(np.arange(total), count)
        px = first[pick] + np.arange(n) - np.repeat(np.cumsum(count) - count, count)
        return triangle[pick], px, row[pick]

    def coverage(self, xy) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The pixels the triangles cover at vertices ``xy (V, 2)``: ``(pixel (n,) flat index,
        triangle (n,), barycentric (n, 3))``; a pixel on a shared edge may appear twice."""
        corners, coef, solid = self._affine(xy)
        triangle, px, py = self._spans(corners, solid)
        k = coef[triangle]
        x, y = px + 0.5, py + 0.5
        l1 = k[:, 0] * x + k[:, 1] * y + k[:, 2]
        l2 = k[:, 3] * x + k[:, 4] * y + k[:, 5]
        return py * self.width + px, triangle, np.stack([1.0 - l1 - l2, l1, l2], axis=1)

    def __call__(self, xy, weights) -> np.ndarray:
        """``(height, width) float32`` (``(height, width, C)`` for textures of C channels): the mix
        ``sum_q weights[q] * textures[q]`` drawn on the mesh at vertices ``xy (V, 2)`` (box pixels)."""
        xy, w = self._check(xy, weights)
        corners, coef, solid = self._affine(xy)
        triangle, px, py = self._spans(corners, solid)
        C = self.channels
        image = np.full((self.width * self.height, C), self.background, dtype=np.float32)
        if len(triangle):
            # u and v as affine functions of the pixel centre, per triangle: uv_a + l1 (uv_b - uv_a) + l2 (uv_c - uv_a)
            c = self._uv_corners
            d1, d2 = c[:, 1] - c[:, 0], c[:, 2] - c[:, 0]  # (F, 2)
            au = d1[:, :, None] * coef[:, None, 0:3] + d2[:, :, None] * coef[:, None, 3:6]  # (F, 2, 3)
            au[:, :, 2] += c[:, 0]
            k = au.reshape(-1, 6)[triangle]
            x, y = px + 0.5, py + 0.5
            uv = np.stack([k[:, 0] * x + k[:, 1] * y + k[:, 2], k[:, 3] * x + k[:, 4] * y + k[:, 5]], axis=1)
            # the keys mixed first (reading is linear): one texture of C channels read, not Q of them
            mixed = (w @ self._flat).reshape(-1, C)
            if self.offsets == ((0.0, 0.0),):
                image[py * self.width + px] = self._bilinear(mixed, uv)
            else:  # the read points through the same triangle's map: uv + k's linear part x offset
                total = np.zeros((len(uv), C), np.float64)
                for ox, oy in self.offsets:
                    moved = uv + np.stack([k[:, 0] * ox + k[:, 1] * oy, k[:, 3] * ox + k[:, 4] * oy], axis=1)
                    total += self._bilinear(mixed, moved)
                image[py * self.width + px] = total / len(self.offsets)
        return image.reshape((self.height, self.width) + ((C,) if self.textures.ndim == 4 else ()))

    def _bilinear(self, texture: np.ndarray, uv: np.ndarray) -> np.ndarray:
        """``(n, C)``: the flat ``texture (s*r, C)`` read bilinearly at ``uv (n, 2)`` (texel centres at
        ``(j + 0.5) / s``, clamped at the edges, as GL's linear filter with clamp-to-edge)."""
        s, r = self._size
        fx = np.clip(uv[:, 0] * r - 0.5, 0.0, r - 1.0)
        fy = np.clip(uv[:, 1] * s - 0.5, 0.0, s - 1.0)
        x0 = np.minimum(fx.astype(np.int64), max(r - 2, 0))
        y0 = np.minimum(fy.astype(np.int64), max(s - 2, 0))
        tx, ty = (fx - x0)[:, None], (fy - y0)[:, None]
        dx, dy = (1 if r > 1 else 0), (r if s > 1 else 0)
        at = y0 * r + x0
        top = texture[at] * (1 - tx) + texture[at + dx] * tx
        bottom = texture[at + dy] * (1 - tx) + texture[at + dy + dx] * tx
        return top * (1 - ty) + bottom * ty

    def sample(self, uv) -> np.ndarray:
        """``(n, Q)`` (``(n, Q, C)`` with channels): every texture read bilinearly at ``uv (n, 2)`` (see
        :meth:`_bilinear`)."""
        uv = np.asarray(uv, dtype=np.float64)
        read = np.stack([self._bilinear(t.reshape(-1, self.channels), uv) for t in self._flat], axis=1)
        return read if self.textures.ndim == 4 else read[..., 0]

    def close(self):
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


_GL_VERTEX = """
#version 330
uniform vec2 size;
in vec2 position;
in vec2 uv;
out vec2 texcoord;
void main() {
    texcoord = uv;
    gl_Position = vec4(2.0 * position.x / size.x - 1.0, 2.0 * position.y / size.y - 1.0, 0.0, 1.0);
}
"""
_GL_FRAGMENT = """
#version 330
uniform sampler2DArray lips;
uniform float weights[{count}];
in vec2 texcoord;
out vec4 result;
vec4 mixed(vec2 at) {{
    return {mix};
}}
void main() {{
    {body}
}}
"""
# Reads off the pixel's centre: the texture read at each offset through the triangle's map (its
# derivatives across the pixel; the map is affine within a triangle, so they are exact).
_GL_OFFSET_READS = """vec2 across = dFdx(texcoord), down = dFdy(texcoord);
    const vec2 offsets[{n}] = vec2[{n}]({offsets});
    vec4 total = vec4(0.0);
    for (int i = 0; i < {n}; ++i)
        total += mixed(texcoord + offsets[i].x * across + offsets[i].y * down);
    result = total / {n}.0;"""


def _fragment_shader(count: int, offsets=((0.0, 0.0),)) -> str:
    """The fragment shader mixing ``count`` layers of the texture array, the keys' sum written out (a
    loop over a uniform count ran at half the speed on llvmpipe: 0.38 against 0.18 ms for the clone's
    mouth); read at ``offsets`` (n points of the pixel, shares of it from its centre)."""
    mix = " + ".join(f"weights[{q}] * texture(lips, vec3(at, {q}.0))" for q in range(count))
    points = [(float(x), float(y)) for x, y in offsets]
    body = ("result = mixed(texcoord);" if points == [(0.0, 0.0)] else _GL_OFFSET_READS.format(
        n=len(points), offsets=", ".join(f"vec2({x!r}, {y!r})" for x, y in points)))
    return _GL_FRAGMENT.format(count=count, mix=mix, body=body)


class GlLipRaster(_Raster):
    """The same image as :class:`NumpyLipRaster`, drawn by OpenGL into a float framebuffer (moderngl,
    EGL); a context manager (holds a GL context). At most 8 key postures."""

    def __init__(self, triangles, uv, textures, *, width: int, height: int, background: float = 0.0,
                 offsets=None):
        super().__init__(triangles, uv, textures, width=width, height=height, background=background,
                         offsets=offsets)
        try:
            import moderngl
        except ImportError:
            raise ImportError("the GL rasteriser needs moderngl: pip install 'faceanim[render]'") from None
        if len(self.textures) > 8:
            raise ValueError(f"the GL rasteriser mixes at most 8 textures, got {len(self.textures)}")
        self._ctx = egl_context("the GL rasteriser")
        ctx = self._ctx
        self._fbo = ctx.framebuffer(color_attachments=[ctx.renderbuffer((self.width, self.height), 4, dtype="f4")])
        Q, s, r = self.textures.shape[:3]
        self._program = ctx.program(vertex_shader=_GL_VERTEX, fragment_shader=_fragment_shader(Q, self.offsets))
        # four channels whatever the textures have: llvmpipe reads RGBA float textures faster than RGB
        padded = np.zeros((Q, s, r, 4), np.float32)
        padded[..., :self.channels] = self.textures.reshape(Q, s, r, self.channels)
        self._texture = ctx.texture_array((r, s, Q), 4, padded.tobytes(), dtype="f4")
        self._texture.filter = (moderngl.LINEAR, moderngl.LINEAR)
        self._texture.repeat_x = self._texture.repeat_y = False
        self._texture.use(0)
        self._program["lips"].value = 0
        self._program["size"].value = (float(self.width), float(self.height))
        self._weights = self._program["weights"]
        self._read = np.empty(self.width * self.height * 4, np.float32)
        self._data = np.zeros((len(self.uv), 4), dtype="f4")
        self._data[:, 2:] = self.uv
        self._vbo = ctx.buffer(reserve=self._data.nbytes)
        self._indices = np.ascontiguousarray(self.triangles, dtype="i4")
        self._ibo = ctx.buffer(reserve=max(self._indices.nbytes, 12))
        self._vao = ctx.vertex_array(self._program, [(self._vbo, "2f 2f", "position", "uv")], self._ibo)

    def __call__(self, xy, weights) -> np.ndarray:
        """As :meth:`NumpyLipRaster.__call__`."""
        import moderngl

        xy, w = self._check(xy, weights)
        self._data[:, :2] = xy
        seen = _reaching(xy, self.triangles, self.width, self.height)
        with self._ctx:  # this context made current (another one, a clone renderer's, may be open)
            self._vbo.write(self._data)
            self._ibo.write(self._indices[seen])  # llvmpipe's time goes with the triangles drawn
            self._weights.write(w.tobytes())
            self._fbo.use()
            self._ctx.viewport = (0, 0, self.width, self.height)
            self._fbo.clear(*(self.background,) * 4)
            self._texture.use(0)
            if seen.any():
                self._vao.render(moderngl.TRIANGLES, vertices=3 * int(seen.sum()))
            self._fbo.read_into(self._read, components=4, dtype="f4", alignment=1)
        # drawn upside down (y up the box in the vertex shader), so GL's first row is the box's top
        image = self._read.reshape(self.height, self.width, 4)[..., :self.channels].copy()
        return image if self.textures.ndim == 4 else image[..., 0]

    def close(self):
        if getattr(self, "_ctx", None) is not None:
            self._ctx.release()
            self._ctx = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
