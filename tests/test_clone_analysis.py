"""Analysis by synthesis with the speaker's clone (issue 18): the lip-probability rasteriser, the
simplex tracker on frames rendered by a synthetic clone, and ``faceanim speaker track``'s bad input."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import shared
from scipy.ndimage import gaussian_filter

from faceanim.cli import main
from faceanim.errors import InputError
from faceanim.landmarks import landmark_names
from faceanim.mpeg4 import Fapu
from faceanim.speaker import read_speaker, write_speaker
from faceanim.speaker.analysis import DEFAULT_ANCHOR, CloneAnalyser
from faceanim.speaker.appearance import Appearance, influence_of, posture_points
from faceanim.speaker.camera import pose_matrix, project_posed
from faceanim.speaker.colour import ColourModel
from faceanim.speaker.lipraster import NumpyLipRaster, prefilter, prefilter_block
from faceanim.speaker.model import SpeakerModel
from faceanim.speaker.mouthmesh import MAX_TRIANGLES, analysis_mesh
from faceanim.speakertrack import frame_ranges, track_speaker

LIP, SKIN, MOUTH = np.array([170.0, 55, 70]), np.array([210.0, 165, 135]), np.array([245.0, 240, 230])
_OUTER = (61, 40, 37, 0, 267, 270, 291, 321, 314, 17, 84, 91)
_INNER = (78, 191, 80, 81, 13, 311, 310, 415, 308, 318, 402, 14, 178, 88)


def _ellipse(count, a, b, start=np.pi):
    angle = start - np.arange(count) * 2 * np.pi / count
    return np.c_[a * np.cos(angle), b * np.sin(angle), np.zeros(count)]


def synthetic_model() -> SpeakerModel:
    """A mouth of 5 cm in the head frame's x-y plane: MediaPipe's lip points on two ellipses, a ring
    of mobile points around them, static points beyond; six displacement patterns (jaw, opening,
    rounding, upper lip, lower lip, corners)."""
    names = landmark_names(478)
    outer, inner = _ellipse(12, 2.5, 1.0), _ellipse(14, 1.9, 0.35)
    around = _ellipse(10, 3.4, 1.9, start=0.3)
    mobile = np.vstack([outer, inner, around])
    mobile_names = [names[i] for i in _OUTER] + [names[i] for i in _INNER] + [f"c{i}" for i in range(10)]
    static = np.vstack([_ellipse(16, 5.2, 3.6, start=0.1), [[-7, -5, 0], [7, -5, 0], [7, 5, 0], [-7, 5, 0]]])
    x, y = mobile[:, 0], mobile[:, 1]
    L = len(_OUTER) + len(_INNER)
    lips = np.arange(len(mobile)) < L
    lower, upper = y < -1e-9, y > 1e-9
    basis = np.zeros((6, len(mobile), 3))
    outer_lip, inner_lip = np.arange(len(mobile)) < 12, (np.arange(len(mobile)) >= 12) & lips
    basis[0, lips & lower, 1] = -0.35  # jaw: the lower lip and the opening's lower edge
    basis[0, ~lips & lower, 1] = -0.2
    basis[1, inner_lip, 1] = np.sign(y[inner_lip]) * 0.18  # opening: the inner contour only
    basis[2, lips, 0] = -0.12 * x[lips]  # rounding
    basis[2, lips, 2] = 0.2
    basis[3, lips & upper, 1] = 0.2  # upper lip
    basis[4, outer_lip & lower, 1] = -0.2  # lower lip: its outer edge
    basis[4, outer_lip & lower, 2] = 0.15
    basis[5, lips, 1] = 0.25 * (x[lips] / 2.5) ** 2  # corners
    from scipy.spatial import Delaunay

    everything = np.vstack([mobile, static])
    triangles = Delaunay(everything[:, :2]).simplices
    fapu = Fapu(0.6, 6.5, 4.4, 2.0, 5.0)
    return SpeakerModel(tuple(mobile_names), mobile, mobile, basis, ("jaw", "opening", "rounding", "upper", "lower",
                                                                     "corners"),
                        tuple(f"s{i}" for i in range(len(static))), static, triangles, fapu,
                        np.tile([-2.0, 2.0], (6, 1)), 25.0)


def synthetic_appearance(model: SpeakerModel, camera, size: int = 128) -> Appearance:
    """Three key postures, each texture the lips (red), the mouth's opening (dark) and skin over a
    frontal UV of the rest shape; the colour model learnt from those colours."""
    rest = np.vstack([model.rest, model.static_points])
    lo, hi = rest[:, :2].min(axis=0), rest[:, :2].max(axis=0)
    uv = np.c_[(rest[:, 0] - lo[0]) / (hi[0] - lo[0]), (hi[1] - rest[:, 1]) / (hi[1] - lo[1])]
    u, v = np.meshgrid((np.arange(size) + 0.5) / size, (np.arange(size) + 0.5) / size)
    x, y = lo[0] + u * (hi[0] - lo[0]), hi[1] - v * (hi[1] - lo[1])
    outside = (x / 2.5) ** 2 + (y / 1.0) ** 2
    opening = (x / 1.9) ** 2 + (y / 0.35) ** 2
    texture = np.where((outside <= 1)[..., None], LIP, SKIN)
    texture = np.where((opening <= 1)[..., None], MOUTH, texture)
    texture = gaussian_filter(texture, sigma=(2.0, 2.0, 0))  # a photograph's soft edges
    keys = np.array([np.zeros(6), [0, 2.0, 0, 0, 0, 0], [0, 0, 2.0, 0, 0, 0]])
    textures = np.stack([texture, texture * 0.97, texture * 1.02]).clip(0, 255).astype(np.uint8)
    lips = (outside <= 1) & (opening > 1.3)
    skin = (outside > 1.5) & (outside < 4)
    colour = ColourModel.fit(texture[lips], texture[skin])  # as the appearance learns it: from its key frames
    key_points = posture_points(model, keys)
    return Appearance(uv.astype(np.float32), keys, key_points, textures,
                      np.stack([colour.probability(t) for t in textures]), influence_of(key_points), colour, camera)


def synthetic_camera(width: int = 160, height: int = 160, distance: float = 30.0) -> np.ndarray:
    """(3, 4) to normalised screen coordinates, looking at the mouth from +z."""
    from faceanim.render.camera import Camera, look_at

    pixels = Camera(look_at((0, 0, distance), (0, 0, 0)), 22.0, width, height).projection
    return np.diag([1.0 / width, 1.0 / height, 1.0]) @ pixels


def render_frame(model, appearance, parameters, pose, width, height, *, gain=1.0, background=None,
                 analysis=True) -> np.ndarray:
    """``(height, width, 3) uint8``: the clone at ``parameters`` and ``pose``, its textures mixed by the
    appearance's weights, over ``background`` (skin), lit by ``gain``; drawn on the analysis mesh (the
    tracker's own model of the image: a noise-free known answer), or on the whole mesh."""
    full = posture_points(model, np.asarray(parameters)[None])[0]
    xy = project_posed(np.asarray(appearance.camera), pose, full) * [width, height]
    weights = appearance.weights(full)
    image = np.empty((height, width, 3))
    points, triangles = np.arange(len(full)), model.triangles
    if analysis:
        mesh = analysis_mesh(model)
        points, triangles = mesh.points, mesh.triangles
    for c in range(3):
        raster = NumpyLipRaster(triangles, appearance.uv[points], appearance.textures[..., c].astype(np.float32),
                                width=width, height=height, background=np.nan)
        image[..., c] = raster(xy[points], weights)
    back = np.broadcast_to(SKIN, image.shape) if background is None else background
    image = np.where(np.isnan(image), back, image)
    return np.clip(image * gain, 0, 255).astype(np.uint8)


@pytest.fixture(scope="module")
def clone():
    model = synthetic_model()
    camera = synthetic_camera()
    return model, synthetic_appearance(model, camera)


# ---- the rasteriser


def test_a_triangle_covers_the_pixel_centres_inside_it():
    """A right triangle with legs of 10 pixels on pixel corners covers the 55 pixel centres under its
    hypotenuse (10 + 9 + ... + 1), half its area up to the diagonal's pixels."""
    raster = NumpyLipRaster([[0, 1, 2]], [[0, 0], [1, 0], [0, 1]], np.ones((1, 2, 2), np.float32), width=16,
                            height=16)
    image = raster([[2.0, 3.0], [12.0, 3.0], [2.0, 13.0]], [1.0])
    assert image.sum() == 55
    assert image[3, 2] == 1 and image[12, 2] == 1 and image[3, 11] == 1 and image[12, 11] == 0


def test_the_texture_is_read_bilinearly_at_the_interpolated_uv():
    """A texture that is a linear ramp comes back as the same ramp over a square mapped onto it."""
    s = 32
    ramp = np.tile(((np.arange(s) + 0.5) / s).astype(np.float32), (s, 1))[None]  # value = u
    raster = NumpyLipRaster([[0, 1, 2], [0, 2, 3]], [[0, 0], [1, 0], [1, 1], [0, 1]], ramp, width=20, height=20)
    image = raster([[0, 0], [20, 0], [20, 20], [0, 20]], [1.0])
    u = (np.arange(20) + 0.5) / 20
    inner = (u > 1 / s) & (u < 1 - 1 / s)  # away from the clamped edge texels
    assert np.allclose(image[:, inner], u[inner], atol=1e-5)


def test_the_mix_follows_the_weights():
    textures = np.stack([np.full((4, 4), 0.2), np.full((4, 4), 1.0)]).astype(np.float32)
    raster = NumpyLipRaster([[0, 1, 2]], [[0, 0], [1, 0], [0, 1]], textures, width=8, height=8)
    image = raster([[0, 0], [8, 0], [0, 8]], [0.25, 0.75])
    assert np.allclose(image[image > 0], 0.8)


def test_prefilter_keeps_the_mean_and_a_ramp():
    ramp = np.tile(np.arange(32, dtype=np.float32), (32, 1))[None]
    filtered = prefilter(ramp, 9.0)  # blurred, then averaged over blocks of 3 texels
    assert filtered.shape == (1, 10, 10)
    assert np.allclose(filtered[0, :, 3:7], 3 * np.arange(3, 7) + 1, atol=1e-3)  # linear: the blocks' centres
    assert np.array_equal(prefilter(ramp, 0.5), ramp)  # under a texel: bilinear reading is the filter


@pytest.mark.parametrize("footprint", [2.0, 4.5, 7.0, 12.0])
def test_the_prefiltered_texture_read_bilinearly_spreads_a_texel_as_a_box_pixel_does(footprint):
    """One bright texel, prefiltered and read bilinearly (at the filtered texels' own coordinates, as the
    rasteriser reads it), spreads over a variance of ``footprint^2 / 12`` texels squared, a box pixel's,
    plus the sixth of a texel squared the renderer's own bilinear reads add: the clone drawn in the box
    is blurred as the frame averaged into it is. (Blurring by the footprint's spread and then averaging the
    blocks and reading bilinearly on top, as before, spread it 1.5-2.3 times wider.)"""
    S = 96
    impulse = np.zeros((1, S, S), np.float32)
    impulse[0, S // 2, S // 2] = 1.0
    k = prefilter_block(footprint)
    filtered = prefilter(impulse, footprint)
    raster = NumpyLipRaster([[0, 1, 2]], [[0, 0], [1, 0], [0, 1]], filtered, width=4, height=4)
    x = np.arange(S * 4) / 4 + 0.125  # the original's texel coordinates, finely
    read = raster.sample(np.c_[x / k / filtered.shape[2], np.full_like(x, (S // 2 + 0.5) / k / filtered.shape[1])])
    profile = read[:, 0] / read[:, 0].sum()
    mean = (profile * x).sum()
    variance = (profile * (x - mean) ** 2).sum()
    assert variance == pytest.approx(footprint ** 2 / 12 + 1 / 6, rel=0.05), (k, variance)


def test_a_prefiltered_texture_is_read_where_the_original_is():
    """A texture whose value is its own texel coordinate (a ramp), prefiltered into blocks of k = 3
    texels (32 is not a multiple of 3): read at ``uv S / k`` of the filtered texels it gives back ``uv S``,
    the original's coordinate; reading at ``uv`` over the filtered width (the old mapping) was off by up
    to a texel."""
    S = 32
    ramp = np.tile(np.arange(S, dtype=np.float32) + 0.5, (S, 1))[None]  # value = the texel coordinate
    k = prefilter_block(9.0)
    filtered = prefilter(ramp, 9.0)
    assert k == 3 and filtered.shape == (1, 10, 10)
    raster = NumpyLipRaster([[0, 1, 2]], [[0, 0], [1, 0], [0, 1]], filtered, width=4, height=4)
    u = np.linspace(0.4, 0.6, 11)  # away from the edges the blur reaches
    at = u * S / k / filtered.shape[2]  # the filtered texture's own texture coordinate
    read = raster.sample(np.c_[at, np.full_like(at, 0.5)])[:, 0]
    assert np.allclose(read, u * S, atol=1e-3)
    assert np.abs(raster.sample(np.c_[u, np.full_like(u, 0.5)])[:, 0] - u * S).max() > 0.3


def _grid(n: int) -> np.ndarray:
    """(n * n, 2) the centres of a pixel's n x n sub-pixels, as shares of it from its centre."""
    along = (np.arange(n) + 0.5) / n - 0.5
    return np.stack(np.meshgrid(along, along), axis=-1).reshape(-1, 2)


def test_reads_off_the_centre_average_the_texture_over_the_pixel_and_keep_its_coverage():
    """A checkerboard texture over a mesh: drawn with reads at the centres of 3 x 3 sub-pixels, each
    covered pixel is the mean of the same mesh drawn 3 times larger over those sub-pixels (where those
    are all covered); with one read at the centre of the bottom-right sub-pixel, that sub-pixel; the
    covered pixels are those the plain drawing covers."""
    rng = np.random.default_rng(4)
    from scipy.spatial import Delaunay

    xy = np.r_[rng.uniform(3, 21, (12, 2)), [[1.2, 1.1], [22.7, 1.4], [22.5, 16.8], [1.6, 16.6]]]
    triangles = Delaunay(xy).simplices
    uv = (xy - 1) / 22
    checker = (np.indices((24, 24)).sum(axis=0) % 2).astype(np.float32)
    textures = np.stack([checker, 1 - checker, rng.uniform(0, 1, (24, 24)).astype(np.float32)])
    weights = [0.5, 0.2, 0.3]
    plain = NumpyLipRaster(triangles, uv, textures, width=24, height=18, background=-1.0)(xy, weights)
    fine = NumpyLipRaster(triangles, uv, textures, width=72, height=54, background=-1.0)(xy * 3, weights)
    super_ = NumpyLipRaster(triangles, uv, textures, width=24, height=18, background=-1.0,
                            offsets=_grid(3))(xy, weights)
    corner = NumpyLipRaster(triangles, uv, textures, width=24, height=18, background=-1.0,
                            offsets=[[1 / 3, 1 / 3]])(xy, weights)
    assert np.array_equal(super_ >= 0, plain >= 0) and np.array_equal(corner >= 0, plain >= 0)
    blocks = fine.reshape(18, 3, 24, 3)
    whole = (blocks >= 0).all(axis=(1, 3))
    assert whole.sum() > 250
    assert np.allclose(super_[whole], blocks.mean(axis=(1, 3))[whole], atol=1e-5)
    assert np.allclose(corner[whole], blocks[:, 2, :, 2][whole], atol=1e-5)
    assert np.abs(plain[whole] - super_[whole]).max() > 0.1  # the checker's texels are finer than a pixel
    assert np.abs(plain[whole] - corner[whole]).max() > 0.1
    for bad in ([[0.6, 0.0]], [0.1, 0.2, 0.3], np.zeros((0, 2)), [[np.nan, 0.0]]):
        with pytest.raises(ValueError, match="offsets must be"):
            NumpyLipRaster(triangles, uv, textures, width=24, height=18, offsets=bad)


def test_colour_textures_are_drawn_channel_by_channel():
    """Textures of 3 channels give the same image as each channel drawn on its own."""
    rng = np.random.default_rng(1)
    textures = rng.uniform(0, 255, (2, 8, 8, 3)).astype(np.float32)
    triangles, uv = [[0, 1, 2], [0, 2, 3]], [[0, 0], [1, 0], [1, 1], [0, 1]]
    xy = [[1.3, 2.0], [14.2, 1.1], [15.0, 13.7], [0.4, 12.9]]
    colour = NumpyLipRaster(triangles, uv, textures, width=16, height=16, background=-1.0)(xy, [0.3, 0.7])
    assert colour.shape == (16, 16, 3)
    for c in range(3):
        one = NumpyLipRaster(triangles, uv, textures[..., c], width=16, height=16, background=-1.0)(xy, [0.3, 0.7])
        assert np.allclose(colour[..., c], one, atol=1e-4)


def test_numpy_and_gl_rasterisers_agree():
    """The same mesh and textures give the same image to float precision (pixels whose centre lies
    exactly on an edge aside)."""
    pytest.importorskip("moderngl")
    from scipy.spatial import Delaunay

    from faceanim.speaker.lipraster import GlLipRaster

    rng = np.random.default_rng(0)
    xy = np.r_[rng.uniform(4, 44, (20, 2)), [[1, 1], [47, 1], [47, 35], [1, 35]]]
    xy[:, 1] *= 35 / 47
    triangles = Delaunay(xy).simplices
    uv = xy / [48, 36]
    textures = rng.uniform(0, 1, (3, 16, 16)).astype(np.float32)
    weights = [0.5, 0.3, 0.2]
    mine = NumpyLipRaster(triangles, uv, textures, width=48, height=36)(xy, weights)
    try:
        gl = GlLipRaster(triangles, uv, textures, width=48, height=36)
    except RuntimeError as exc:
        pytest.skip(f"no OpenGL context: {exc}")
    with gl:
        theirs = gl(xy, weights)
    assert np.abs(mine - theirs).max() < 1e-5
    colours = rng.uniform(0, 255, (3, 16, 16, 3)).astype(np.float32)  # RGB, the colour comparison's
    mine = NumpyLipRaster(triangles, uv, colours, width=48, height=36, background=-1.0)(xy, weights)
    with GlLipRaster(triangles, uv, colours, width=48, height=36, background=-1.0) as gl:
        theirs = gl(xy, weights)
    assert theirs.shape == (36, 48, 3) and np.abs(mine - theirs).max() < 1e-2
    for offsets in (_grid(3), [[0.25, 0.25]], [[-0.4, 0.1], [0.3, -0.2]]):
        mine = NumpyLipRaster(triangles, uv, colours, width=48, height=36, background=-1.0,
                              offsets=offsets)(xy, weights)
        with GlLipRaster(triangles, uv, colours, width=48, height=36, background=-1.0, offsets=offsets) as gl:
            theirs = gl(xy, weights)
        assert np.abs(mine - theirs).max() < 1e-3, offsets


def test_the_gl_rasteriser_leaves_out_only_triangles_that_cover_no_pixel():
    """A mesh reaching well beyond the box (triangles wholly outside on each side, others across its
    edges): GL, which leaves the outside ones undrawn, gives numpy's image; the box's every pixel drawn
    once the mesh covers it, none where it does not."""
    pytest.importorskip("moderngl")
    from scipy.spatial import Delaunay

    from faceanim.speaker.lipraster import GlLipRaster, _reaching

    rng = np.random.default_rng(1)
    xy = np.r_[rng.uniform(-30, 60, (600, 2)), [[-40, -40], [70, -40], [70, 60], [-40, 60]]]
    triangles = Delaunay(xy).simplices
    uv = (xy + 40) / [110, 100]
    colours = rng.uniform(0, 255, (2, 16, 16, 3)).astype(np.float32)
    seen = _reaching(xy, triangles, 24, 20)
    assert 0 < seen.sum() < len(triangles) // 2  # most are left out
    low, high = xy[triangles].min(axis=1), xy[triangles].max(axis=1)  # over the span of the pixel centres
    assert np.array_equal(seen, ((high >= 0.5) & (low <= [23.5, 19.5])).all(axis=1))
    _, covering, _ = NumpyLipRaster(triangles, uv, colours, width=24, height=20).coverage(xy)
    assert seen[covering].all()
    mine = NumpyLipRaster(triangles, uv, colours, width=24, height=20, background=-1.0)(xy, [0.6, 0.4])
    try:
        gl = GlLipRaster(triangles, uv, colours, width=24, height=20, background=-1.0)
    except RuntimeError as exc:
        pytest.skip(f"no OpenGL context: {exc}")
    with gl:
        theirs = gl(xy, [0.6, 0.4])
        away = gl(xy + 100.0, [0.6, 0.4])  # the whole mesh beside the box: nothing drawn
    assert (mine > -1).all() and np.abs(mine - theirs).max() < 1e-2
    assert (away == -1.0).all()


# ---- the analysis mesh and the tracker


def test_the_analysis_mesh_is_small_and_holds_the_lips(clone):
    model, _ = clone
    mesh = analysis_mesh(model)
    assert len(mesh.triangles) <= MAX_TRIANGLES
    assert len(mesh.outer) == 12 and 8 <= len(mesh.inner) <= 14
    names = tuple(model.names) + tuple(model.static_names)
    assert names[mesh.points[mesh.outer[3]]] == "8.1"  # the upper lip's middle


def _analyser(model, appearance, **options):
    width = 160
    lips = posture_points(model, np.zeros((1, 6)))[0][:12]
    xy = project_posed(np.asarray(appearance.camera), np.eye(4), lips) * width
    options.setdefault("raster", "numpy")  # the same pixels everywhere (GL's agreement is tested above)
    return CloneAnalyser(model, appearance, width=width, height=160, mouth_width=float(np.ptp(xy[:, 0])), **options)


def _sequence(count=8):
    t = np.linspace(0, 1, count)[:, None]
    return np.c_[np.sin(3 * t), 0.8 * np.sin(5 * t + 1), -0.6 * t, 0.5 * np.cos(4 * t), 0.4 * t, -0.3 * np.sin(6 * t)]


@pytest.mark.parametrize("compare", ["colour", "probability"])
def test_the_tracker_recovers_known_parameters_from_noise_free_frames(clone, compare):
    """Frames drawn as the analysis draws (the whole mesh for the colour comparison, the reduced mesh for
    lip probability) track back within 0.1 from a start 0.3 off."""
    model, appearance = clone
    truth = _sequence()
    with _analyser(model, appearance, max_evals=400, prior=0.0, compare=compare) as analyser:  # the image alone
        found, start = [], truth[0] + 0.3
        for a in truth:
            frame = render_frame(model, appearance, a, np.eye(4), 160, 160, analysis=compare == "probability")
            answer = analyser.analyse(frame, start, np.eye(4))
            found.append(answer.parameters)
            start = answer.parameters
    error = np.sqrt(((np.array(found) - truth) ** 2).mean(axis=0))
    assert error.max() < 0.1, error


def test_the_tracker_follows_a_lighting_change_once_adapted(clone):
    """Frames 25% darker: with the colour model adapted on the first frame the parameters come back
    within 0.4 (in their standard deviations; the textures' probabilities and the adapted model's are
    no longer the same function of colour), without it they are lost."""
    model, appearance = clone
    truth = _sequence(6)
    frames = [render_frame(model, appearance, a, np.eye(4), 160, 160, gain=0.75) for a in truth]
    errors = []
    for adapt in (True, False):
        with _analyser(model, appearance, max_evals=300, prior=0.0, compare="probability") as analyser:
            if adapt:
                analyser.adapt(frames[:1], truth[:1], [np.eye(4)])
            found, start = [], truth[0]
            for frame in frames:
                answer = analyser.analyse(frame, start, np.eye(4))
                found.append(answer.parameters)
                start = answer.parameters
        errors.append(np.sqrt(((np.array(found) - truth) ** 2).mean(axis=0)))
    assert errors[0].max() < 0.4, errors[0]
    assert errors[0].max() < 0.5 * errors[1].max(), errors


def test_the_colour_comparison_tracks_through_a_tinted_lighting_change_without_adapting(clone):
    """Frames drawn on the whole mesh, lit by a gain falling to 70% with a warm tint (a different gain per
    channel) and an offset: the colour comparison's gain and offset per channel absorb it, so the
    parameters come back within 0.1 as on the unlit frames, with no colour model adapted."""
    model, appearance = clone
    truth = _sequence(6)
    found = []
    with _analyser(model, appearance, max_evals=400, prior=0.0) as analyser:
        start = truth[0] + 0.3
        for a, level in zip(truth, np.linspace(1.0, 0.7, len(truth)), strict=True):
            frame = render_frame(model, appearance, a, np.eye(4), 160, 160, analysis=False).astype(np.float64)
            frame = np.clip(frame * level * np.array([1.0, 0.93, 0.85]) + 6.0, 0, 255).astype(np.uint8)
            start = analyser.analyse(frame, start, np.eye(4)).parameters
            found.append(start)
    error = np.sqrt(((np.array(found) - truth) ** 2).mean(axis=0))
    assert error.max() < 0.1, error


def test_the_colour_costs_least_at_the_truth_along_each_parameter(clone):
    """The cost landscape on a frame the clone drew: along each parameter (the others at the truth) the
    difference is smallest at the true value and grows on both sides."""
    model, appearance = clone
    truth = _sequence()[3]
    frame = render_frame(model, appearance, truth, np.eye(4), 160, 160, analysis=False)
    steps = np.linspace(-1.0, 1.0, 9)
    with _analyser(model, appearance, prior=0.0) as analyser:
        origin = analyser.box_origin(truth, np.eye(4))
        target = analyser.frame_image(frame, origin)
        analyser._set_target(target)
        for k in range(model.parameter_count):
            costs = []
            for step in steps:
                a = truth.copy()
                a[k] += step
                costs.append(analyser._difference(analyser.clone_image(a, np.eye(4), origin), target))
            assert np.argmin(costs) == 4, (k, np.round(costs, 4))
            assert costs[0] > costs[4] and costs[-1] > costs[4]


def test_the_compared_frame_pixels_are_the_middle_ones_of_each_box_pixel(clone):
    """A frame whose pixels hold their own column and row: under each box pixel of factor 1 to 4, the
    box holds the pixel ``f // 2`` along each side of its block (the clone's mesh moved by that
    pixel's place, ``(f // 2 + 0.5) / f - 0.5`` box pixels, where it is off the centre), or the block's
    mean with ``supersample``."""
    model, appearance = clone
    y, x = np.mgrid[0:160, 0:160]
    frame = np.stack([x, y, np.zeros_like(x)], axis=-1).astype(np.uint8)
    for box_pixels, f in ((200, 1), (64, 2), (32, 3), (24, 4)):
        for supersample in (False, True):
            with _analyser(model, appearance, box_pixels=box_pixels, supersample=supersample) as analyser:
                assert analyser.factor == f
                x0, y0 = 7, 11
                seen = analyser.frame_image(frame, (x0, y0))
                at = f // 2 if not supersample else (f - 1) / 2
                columns = x0 + f * np.arange(analyser.box_width) + at
                rows = y0 + f * np.arange(analyser.box_height) + at
                assert np.array_equal(seen[..., 0], np.broadcast_to(columns, seen.shape[:2]))
                assert np.array_equal(seen[..., 1], np.broadcast_to(rows[:, None], seen.shape[:2]))
                nudge = 0.0 if supersample else (f // 2 + 0.5) / f - 0.5
                assert np.allclose(analyser._nudge, nudge)


def test_the_analysed_clone_is_its_own_frame_at_the_pixels_compared(clone):
    """The clone drawn at the frame's full size (the whole mesh; levels cut to whole numbers), against
    the analyser's clone at the same parameters, over 8 postures: the box holds the frame's middle pixel
    under each box pixel (by default; factor 2: the second of each 2 x 2), or their mean
    (``supersample``); the analyser's clone is the same to the frame's cut (0 to 1 level above it) on at
    least 99% of the box's pixels by default (each read through the triangle covering the frame pixel's
    centre, as the frame's renderer reads it), 95% supersampled (the reads off a box pixel's centre go
    through the map of the triangle covering its centre: where it straddles two triangles at the
    moving inner lips, their maps differ)."""
    model, appearance = clone
    shares = {True: [], False: []}
    for truth in _sequence():
        frame = render_frame(model, appearance, truth, np.eye(4), 160, 160, analysis=False)
        for supersample in shares:
            with _analyser(model, appearance, supersample=supersample) as analyser:
                assert analyser.factor == 2 and analyser.supersample == (2 if supersample else 1)
                x0, y0 = origin = analyser.box_origin(truth, np.eye(4))
                seen = analyser.frame_image(frame, origin)
                crop = frame[y0:y0 + 2 * analyser.box_height, x0:x0 + 2 * analyser.box_width].astype(np.float32)
                expected = (crop.reshape(analyser.box_height, 2, analyser.box_width, 2, 3).mean(axis=(1, 3))
                            if supersample else crop[1::2, 1::2])
                assert np.allclose(seen, expected, atol=1e-4)
                above = analyser.clone_image(truth, np.eye(4), origin) - seen
            shares[supersample].append(((above > -1e-3) & (above < 1 + 1e-3)).all(axis=2).mean())
    assert min(shares[True]) >= 0.95 and min(shares[False]) >= 0.99, shares
    with _analyser(model, appearance, supersample=True, box_pixels=32) as analyser:  # a smaller box: 3 x 3 reads
        assert analyser.factor == 3 and analyser.supersample == 3
    with _analyser(model, appearance) as colour, _analyser(model, appearance, compare="probability") as probability:
        assert colour.supersample == 1 and probability.supersample == 2  # the defaults: see CloneAnalyser
    with pytest.raises(ValueError, match="supersample must be True or False, got 'no'"):
        _analyser(model, appearance, supersample="no")


def _polygon_centroid(xy):
    x, y = xy[:, 0], xy[:, 1]
    cross = x * np.roll(y, -1) - np.roll(x, -1) * y
    area = cross.sum() / 2
    return area, np.array([((x + np.roll(x, -1)) * cross).sum(), ((y + np.roll(y, -1)) * cross).sum()]) / (6 * area)


def test_the_colour_adaptation_mask_is_centred_on_the_lips(clone):
    """The lips' mask (pixel centres between the outer and inner contours) has the centroid of the region
    between the two polygons: not half a pixel off."""
    model, appearance = clone
    a = _sequence()[2]
    with _analyser(model, appearance, compare="probability") as analyser:
        origin = analyser.box_origin(a, np.eye(4))
        shape = (analyser.box_height * analyser.factor, analyser.box_width * analyser.factor)
        mask = analyser.lip_mask(a, np.eye(4), origin, shape)
        xy = analyser.pixels(analyser.full_points(a)[analyser.mesh.points], np.eye(4)) - origin
        outer, inner = _polygon_centroid(xy[analyser.mesh.outer]), _polygon_centroid(xy[analyser.mesh.inner])
    ring = (outer[0] * outer[1] - inner[0] * inner[1]) / (outer[0] - inner[0])
    rows, columns = np.nonzero(mask)
    found = np.array([columns.mean() + 0.5, rows.mean() + 0.5])
    assert np.abs(found - ring).max() < 0.15, (found, ring)


def test_the_landmark_reading_pulls_the_answer_as_its_weight_says(clone):
    """The MAP pull toward the frame's reading: no weight, no change; an overwhelming weight, the
    reading; the default weight with the true reading no worse than the image alone."""
    model, appearance = clone
    truth = np.array([0.6, -0.4, 0.3, 0.5, -0.2, 0.3])
    frame = render_frame(model, appearance, truth, np.eye(4), 160, 160)
    start = truth + 0.3
    with _analyser(model, appearance, max_evals=150, anchor=0.0) as analyser:
        alone = analyser.analyse(frame, start, np.eye(4))
        unweighted = analyser.analyse(frame, start, np.eye(4), reading=np.zeros(6))
    assert np.array_equal(alone.parameters, unweighted.parameters) and alone.cost == unweighted.cost
    with _analyser(model, appearance, max_evals=150, anchor=1e4) as analyser:
        held = analyser.analyse(frame, start, np.eye(4), reading=np.zeros(6))
    assert np.abs(held.parameters).max() < 0.05
    with _analyser(model, appearance, max_evals=150) as analyser:  # the default weight
        assert analyser.anchor == DEFAULT_ANCHOR
        read = analyser.analyse(frame, start, np.eye(4), reading=truth)
    assert np.abs(read.parameters - truth).max() <= np.abs(alone.parameters - truth).max() + 1e-3


def test_the_previous_answer_pulls_as_the_continuity_weight_says(clone):
    """The pull toward the previous frame's answer: no weight (or no previous answer), no change; an
    overwhelming weight, the previous answer; with a reading too, the two pulls act as one toward
    their weighted mean."""
    model, appearance = clone
    truth = np.array([0.6, -0.4, 0.3, 0.5, -0.2, 0.3])
    frame = render_frame(model, appearance, truth, np.eye(4), 160, 160)
    start, before = truth + 0.3, np.full(6, -0.5)
    with _analyser(model, appearance, max_evals=150, anchor=0.0, continuity=0.0) as analyser:
        alone = analyser.analyse(frame, start, np.eye(4))
        unweighted = analyser.analyse(frame, start, np.eye(4), previous=before)
    assert np.array_equal(alone.parameters, unweighted.parameters) and alone.cost == unweighted.cost
    with _analyser(model, appearance, max_evals=150, anchor=0.0, continuity=1e4) as analyser:
        held = analyser.analyse(frame, start, np.eye(4), previous=before)
        free = analyser.analyse(frame, start, np.eye(4))
    assert np.abs(held.parameters - before).max() < 0.05
    assert np.array_equal(free.parameters, alone.parameters)  # no previous answer: no pull
    with _analyser(model, appearance, max_evals=150, anchor=3e3, continuity=1e4) as analyser:
        both = analyser.analyse(frame, start, np.eye(4), reading=np.zeros(6), previous=before)
    assert np.abs(both.parameters - before * 1e4 / 1.3e4).max() < 0.05


def test_gauss_newton_rounds_reach_the_truth_from_afar_within_the_cap(clone):
    """Several damped Gauss-Newton rounds before the simplex: from a start 0.8 std off in every
    parameter, the answer within 150 evaluations is closer than one round's (0.20 against 0.73 std;
    comparing every frame pixel, 0.20 against 0.46)."""
    model, appearance = clone
    truth = np.array([0.6, -0.4, 0.3, 0.5, -0.2, 0.3])
    frame = render_frame(model, appearance, truth, np.eye(4), 160, 160)
    errors = {}
    for supersample in (False, True):
        for rounds in (1, 6):
            with _analyser(model, appearance, max_evals=150, rounds=rounds, supersample=supersample) as analyser:
                answer = analyser.analyse(frame, truth + 0.8 * np.array([1, -1, 1, -1, 1, -1]), np.eye(4))
            assert answer.evaluations <= 150
            errors[rounds] = np.abs(answer.parameters - truth).max()
        assert errors[6] < 0.75 * errors[1], (supersample, errors)
    with pytest.raises(ValueError, match="rounds"):
        CloneAnalyser(model, appearance, width=160, height=160, mouth_width=50, rounds=0)
    with pytest.raises(ValueError, match="continuity"):
        CloneAnalyser(model, appearance, width=160, height=160, mouth_width=50, continuity=-1)


def test_a_posture_beyond_the_walls_is_found_without_them_and_pulled_back_with_them(clone):
    """Rounding at 5 std, beyond the model's range (-2..2) and the walls' margin: by default (no walls)
    the tracker finds it; walls pull it back toward the range."""
    model, appearance = clone
    truth = np.array([0.0, 0.0, 5.0, 0.0, 0.0, 0.0])
    frame = render_frame(model, appearance, truth, np.eye(4), 160, 160)
    with _analyser(model, appearance, max_evals=150) as analyser:
        assert analyser.walls == 0.0
        free = analyser.analyse(frame, truth, np.eye(4)).parameters
    with _analyser(model, appearance, max_evals=150, walls=0.05) as analyser:
        walled = analyser.analyse(frame, truth, np.eye(4)).parameters
    assert abs(free[2] - 5.0) < 0.1 and walled[2] < 5.0 - 0.1, (free, walled)


def test_evaluations_never_exceed_the_cap(clone):
    model, appearance = clone
    frame = render_frame(model, appearance, np.full(6, 0.8), np.eye(4), 160, 160)
    for cap in (7, 20, 57):
        with _analyser(model, appearance, max_evals=cap) as analyser:
            answer = analyser.analyse(frame, np.zeros(6), np.eye(4))
        assert answer.evaluations <= cap
    with _analyser(model, appearance, max_evals=40, rigid=True) as analyser:
        answer = analyser.analyse(frame, np.zeros(6), np.eye(4))
    assert answer.evaluations <= 40 and answer.correction.shape == (6,)


def test_pose_matrix_of_no_motion_is_the_identity():
    assert np.allclose(pose_matrix(np.zeros(6)), np.eye(4))


# ---- faceanim speaker track


def test_the_frames_outside_are_named_as_runs():
    assert frame_ranges([0, 1, 2, 7, 9, 10]) == "0-2, 7, 9-10"


def test_track_refuses_a_model_without_textures_in_one_line_and_writes_nothing(tmp_path, capsys):
    write_speaker(tmp_path / "bare.npz", synthetic_model())
    (tmp_path / "v.mp4").write_bytes(b"not read: the model is refused first")
    out = tmp_path / "out"
    out.mkdir()
    assert main(["speaker", "track", str(tmp_path / "v.mp4"), "--model", str(tmp_path / "bare.npz"),
                 "-o", str(out / "p.csv"), "--fap", str(out / "p.fap"), "--overlay", str(out / "o.mp4")]) == 2
    err = capsys.readouterr().err
    assert "has no textures" in err and len(err.strip().splitlines()) == 1
    assert list(out.iterdir()) == []
    parameters = synthetic_model().parameter_count
    with pytest.raises(InputError, match=f"--max-evals 3: the simplex over {parameters} parameters"):
        track_speaker(tmp_path / "v.mp4", out / "p.csv", model=tmp_path / "bare.npz", max_evals=3)
    with pytest.raises(InputError, match="supersample must be True or False, got 2"):
        track_speaker(tmp_path / "v.mp4", out / "p.csv", model=tmp_path / "bare.npz", supersample=2)
    with pytest.raises(InputError, match=f"over {parameters + 6} parameters \\(with --rigid\\)"):
        track_speaker(tmp_path / "v.mp4", out / "p.csv", model=tmp_path / "bare.npz", max_evals=parameters + 1,
                      rigid=True)


@pytest.mark.parametrize("flag", [[], ["--supersample"]])
def test_track_passes_supersample_to_the_analysis(tmp_path, monkeypatch, capsys, flag):
    """``speaker track --supersample`` reaches ``track_speaker`` (and so the analyser); without it, not."""
    import faceanim.speakertrack

    seen = {}

    def spy(video, output, **options):
        seen.update(options)
        raise InputError("stopped by the test")

    monkeypatch.setattr(faceanim.speakertrack, "track_speaker", spy)
    assert main(["speaker", "track", str(tmp_path / "v.mp4"), "--model", str(tmp_path / "m.npz"),
                 "-o", str(tmp_path / "p.csv"), *flag]) == 2
    assert seen["supersample"] is bool(flag)
    assert "stopped by the test" in capsys.readouterr().err


@pytest.fixture(scope="module")
def real(tmp_path_factory):
    """A model with textures built on speech_man's first 87 frames, and its first 16 frames as a clip."""
    pytest.importorskip("moderngl")
    video = shared("videos", "speech_man.mp4")
    from faceanim.capture.video import open_frames
    from faceanim.speakerclone import make_textures
    from faceanim.speech import build_speaker

    folder = tmp_path_factory.mktemp("track")
    model = folder / "man.npz"
    build_speaker(video, model, frames="0:87")
    make_textures(video, model, model=model, frames="0:87")
    with open_frames(video) as source:
        frames = [image for _, (_, image) in zip(range(16), source, strict=False)]
    return folder, model, frames


def _write_clip(path, frames, fps=25):
    from faceanim.render.video import video_writer

    height, width = frames[0].shape[:2]
    with video_writer(path, fps, width, height) as write:
        for image in frames:
            write(image)


def test_track_names_the_frames_where_the_mouth_leaves_and_writes_nothing(real, tmp_path):
    folder, model, frames = real
    height = frames[0].shape[0]
    shift = int(0.36 * height)  # the mouth near the bottom edge, the box beyond it, the face still found
    moved = [image if t < 8 else np.vstack([np.zeros_like(image[:shift]), image[:height - shift]])
             for t, image in enumerate(frames)]
    _write_clip(tmp_path / "clip.mp4", moved)
    out = tmp_path / "out"
    out.mkdir()
    # the capture's smoothing may follow the jump a frame late
    with pytest.raises(InputError, match=r"the mouth leaves the frame on frames (8|9)-15 of 16; track a video"):
        track_speaker(tmp_path / "clip.mp4", out / "p.csv", model=model, fap=out / "p.fap", overlay=out / "o.mp4")
    assert list(out.iterdir()) == []


def test_track_marks_a_stretch_without_a_face_and_carries_on(real, tmp_path):
    """Frames 5-11 blanked (no face; longer than the capture fills, 0.2 s): tracked, marked invalid,
    holding frame 4's answer; the frames after them analysed again (from their own landmarks); every
    output written."""
    folder, model, frames = real
    blank = [np.full_like(image, 128) if 5 <= t <= 11 else image for t, image in enumerate(frames)]
    _write_clip(tmp_path / "clip.mp4", blank)
    tracked = track_speaker(tmp_path / "clip.mp4", tmp_path / "p.csv", model=model, fap=tmp_path / "p.fap")
    assert tracked.valid.tolist() == [not 5 <= t <= 11 for t in range(16)]
    assert np.array_equal(tracked.parameters[5:12], np.repeat(tracked.parameters[4:5], 7, axis=0))
    assert (tracked.evaluations[5:12] == 0).all() and (tracked.evaluations[tracked.valid] > 0).all()
    assert np.isfinite(tracked.parameters).all() and not np.allclose(tracked.parameters[12], tracked.parameters[4])
    rows = (tmp_path / "p.csv").read_text().splitlines()
    assert len(rows) == 17 and (tmp_path / "p.fap").is_file()


def test_track_writes_parameters_faps_and_an_overlay_of_one_field(real, tmp_path, capsys):
    av = pytest.importorskip("av")
    folder, model, frames = real
    _write_clip(tmp_path / "clip.mp4", frames[:8])
    out = tmp_path / "p.csv"
    assert main(["speaker", "track", str(tmp_path / "clip.mp4"), "--model", str(model), "-o", str(out),
                 "--fap", str(tmp_path / "p.fap"), "--overlay", str(tmp_path / "o.mp4"), "--field", "top",
                 "--max-evals", "40", "--motion-out", str(tmp_path / "m.csv")]) == 0
    assert "8 frames" in capsys.readouterr().out
    rows = out.read_text().splitlines()
    assert rows[0] == "frame,timestamp," + ",".join(read_speaker(model).parameter_names) and len(rows) == 9
    from faceanim.mpeg4.fapfile import read_fap
    from faceanim.speakerclone import read_motion_csv, read_parameters_csv

    assert len(read_fap(tmp_path / "p.fap")) == 8
    assert read_parameters_csv(out, 6).shape == (8, 6) and read_motion_csv(tmp_path / "m.csv").shape == (8, 6)
    with av.open(str(tmp_path / "o.mp4")) as container:
        shapes = [f.to_ndarray(format="rgb24").shape for f in container.decode(video=0)]
    assert len(shapes) == 8 and shapes[0][0] == frames[0].shape[0] // 2  # one field: half the rows


def test_the_analysers_weights_are_the_appearances(clone):
    model, appearance = clone
    with _analyser(model, appearance) as analyser:
        for a in (np.zeros(6), appearance.key_parameters[1], _sequence(3)[2]):
            points = posture_points(model, a[None])[0]
            assert np.allclose(analyser.weights(a), appearance.weights(points), atol=1e-9)


@pytest.mark.parametrize("field", [None, "top", "bottom"])
def test_the_frames_projection_folded_once_places_the_mesh_as_the_plain_projection(clone, field):
    """The analysis draws the mesh through the camera and pose folded into the rest shape and basis once
    a frame (``_projector``); it gives the same box image as projecting the moved points each time
    (``pixels``), less the compared frame pixel's place in its box pixel (factor 2: the second of 2 x 2,
    a quarter of a box pixel right and down), on either field and under a head turned and moved, to
    rounding."""
    model, appearance = clone
    pose = pose_matrix(np.array([0.05, -0.08, 0.03, 0.2, -0.1, 0.4]))
    with _analyser(model, appearance, field=field) as analyser:
        assert analyser.factor == 2 and np.array_equal(analyser._nudge, [0.25, 0.25])
        for a in _sequence(4):
            origin = analyser.box_origin(a, pose)
            plain = (analyser.pixels(analyser.full_points(a)[analyser.mesh.points], pose) - origin) / analyser.factor
            expected = analyser.raster(plain - [0.25, 0.25] + [0.3, -0.2], analyser.weights(a))
            found = analyser._draw(a, analyser._projector(pose, origin), np.array([0.3, -0.2]))
            assert np.abs(found - expected).max() < 1e-3


def test_the_colour_difference_is_the_residuals_sum_of_squares(clone):
    """The colour comparison's cost, summed from two small products over the box, equals the sum of
    squares of its residual pixel by pixel (gain and offset per channel over the covered pixels, the
    rest about its own mean), for the clone at and away from the frame's parameters."""
    model, appearance = clone
    truth = _sequence()[3]
    frame = render_frame(model, appearance, truth, np.eye(4), 160, 160, analysis=False)
    with _analyser(model, appearance) as analyser:
        origin = analyser.box_origin(truth, np.eye(4))
        target = analyser.frame_image(frame, origin)
        analyser._set_target(target)
        for step in (0.0, 0.4, -1.0):
            clone_image = analyser.clone_image(truth + step, np.eye(4), origin)
            r = analyser._colour_residual(clone_image)
            assert abs(analyser._colour_difference(clone_image, target) - r @ r / analyser._scale) < 1e-9
