"""The speaker's articulatory model (faceanim.speaker) and its jobs (faceanim.speech)."""

import numpy as np
import pytest
from conftest import SHARED

from faceanim.capture.headframe import landmark_names
from faceanim.capture.metric import canonical_face
from faceanim.cli import main
from faceanim.errors import FileFormatError, InputError
from faceanim.motion import Motion, motion_to_faps
from faceanim.mpeg4 import FAP_COUNT, Fapu, fap_table
from faceanim.mpeg4.fapfile import read_fap
from faceanim.mpeg4.fapstream import FapStream
from faceanim.speaker import build_model, mobile_names, read_speaker, write_speaker

TABLE = fap_table()
FAPU = Fapu(irisd0=1.0, es0=6.4, ens0=4.4, mns0=2.0, mw0=5.2)
EIGHT = [3, 14, 16, 17, 51, 52, 53, 54]  # the FAPs the ICP figure sends


def synthetic(frames=240, count=3, seed=0, noise=0.0, scale=1.0):
    """A Motion of MediaPipe's canonical face (cm, times ``scale``) whose mobile points move by a known
    linear model of ``count`` parameters; returns the motion, the true vectors (count, P, 3) and the
    true parameters (frames, count)."""
    rng = np.random.default_rng(seed)
    neutral = canonical_face().vertices * scale
    names = landmark_names(len(neutral))
    stand_in = Motion(names, neutral, np.zeros((1, len(names), 3)), np.eye(4)[None], 25.0, FAPU)
    index = stand_in.index(mobile_names(stand_in))
    vectors = rng.normal(scale=0.1 * scale, size=(count, len(index), 3))
    parameters = rng.normal(size=(frames, count))
    parameters[:, 0] = np.abs(parameters[:, 0])  # the first opens the jaw (chin at or below rest)
    vectors[0, :, 1] -= 0.2 * scale
    d = np.zeros((frames, len(names), 3))
    d[:, index] = np.einsum("tk,kpc->tpc", parameters, vectors) + rng.normal(scale=noise * scale,
                                                                               size=(frames, len(index), 3))
    fapu = Fapu(*(scale * v for v in (FAPU.irisd0, FAPU.es0, FAPU.ens0, FAPU.mns0, FAPU.mw0)))
    return Motion(names, neutral, d, np.tile(np.eye(4), (frames, 1, 1)), 25.0, fapu), vectors, parameters


def columns(numbers):
    return np.array(numbers) - 1


def principal_angles(a, b) -> np.ndarray:
    qa, _ = np.linalg.qr(a.reshape(len(a), -1).T)
    qb, _ = np.linalg.qr(b.reshape(len(b), -1).T)
    return np.arccos(np.clip(np.linalg.svd(qa.T @ qb, compute_uv=False), -1, 1))


@pytest.mark.parametrize("method", ["pca", "guided"])
def test_a_model_built_from_a_known_linear_model_recovers_its_subspace(method):
    motion, vectors, _ = synthetic()
    model = build_model(motion, parameters=3, method=method)
    assert principal_angles(model.basis, vectors).max() < 1e-6
    np.testing.assert_allclose(model.points(model.fit_points(motion.displacements[:, motion.index(model.names)])),
                               motion.neutral[motion.index(model.names)] + motion.displacements[:, motion.index(
                                   model.names)], atol=1e-9)
    seen = model.fit_points(motion.displacements[:, motion.index(model.names)])
    np.testing.assert_allclose(seen.std(axis=0), 1.0, atol=1e-9)  # parameters of unit variance
    np.testing.assert_allclose(model.ranges, np.stack([seen.min(axis=0), seen.max(axis=0)], axis=1))
    assert model.method == method and len(model.parameter_names) == 3


def test_guided_parameters_are_named_and_the_jaw_opens_downwards():
    motion, _, _ = synthetic(count=6)
    model = build_model(motion, parameters=6, method="guided")
    assert model.parameter_names == ("jaw", "protrusion", "opening", "upper_lip", "lower_lip", "corners")
    chin = model.names.index("2.1")
    assert model.basis[0, chin, 1] < 0  # a positive jaw parameter drops the chin


def test_the_forward_map_measures_faps_as_motion_to_faps_does():
    motion, _, truth = synthetic()
    model = build_model(motion, parameters=3)
    a = model.fit_points(motion.displacements[:, motion.index(model.names)])
    ours = model.to_faps(a)
    theirs = motion_to_faps(motion)
    j = model.fap_columns
    opening = TABLE.number("open_jaw") - 1
    down = theirs.values[:, opening] >= 0  # motion_to_faps swings the jaw only for a chin at or below rest
    assert down.sum() > 100
    np.testing.assert_allclose(ours.values[down][:, j], theirs.values[down][:, j], atol=1e-8)
    assert set(j + 1) == set(range(3, 19)) | {39, 40, 41, 42} | set(range(51, 65))  # 61-64: the nose
    assert ours.mask[:, j].all() and not np.delete(ours.mask, j, axis=1).any()


def test_faps_do_not_depend_on_the_unit_of_the_face():
    streams = []
    for scale in (1.0, 10.0, 0.01):  # cm, mm, m
        motion, _, _ = synthetic(scale=scale)
        model = build_model(motion, parameters=3)
        streams.append(model.to_faps(model.fit_points(motion.displacements[:, motion.index(model.names)])))
    for other in streams[1:]:
        np.testing.assert_allclose(other.values, streams[0].values, atol=1e-7)


def noisy(stream: FapStream, sigma: float, seed: int = 1) -> FapStream:
    rng = np.random.default_rng(seed)
    return FapStream(stream.values + rng.normal(scale=sigma, size=stream.values.shape) * stream.mask,
                     stream.mask, stream.fps)


def test_regularising_a_noisy_model_stream_brings_it_closer_to_the_truth():
    motion, _, _ = synthetic(count=6)
    model = build_model(motion, parameters=6)
    truth = model.to_faps(np.random.default_rng(2).normal(size=(300, 6)))
    received = noisy(truth, sigma=8.0)
    cleaned = model.regularise(received)
    j = model.fap_columns
    before = np.sqrt(((received.values[:, j] - truth.values[:, j]) ** 2).mean())
    after = np.sqrt(((cleaned.values[:, j] - truth.values[:, j]) ** 2).mean())
    assert after < 0.6 * before
    assert cleaned.mask[:, j].all()


def subset(stream: FapStream, numbers, frames=None) -> FapStream:
    mask = np.zeros_like(stream.mask)
    rows = slice(None) if frames is None else frames
    mask[rows, columns(numbers)] = stream.mask[rows, columns(numbers)]
    return FapStream(stream.values, mask, stream.fps)


def test_missing_faps_are_extrapolated_exactly_from_a_noise_free_model_stream():
    motion, _, _ = synthetic(count=6)
    exact = build_model(motion, parameters=6, ridge=0.0)
    truth = exact.to_faps(np.random.default_rng(3).normal(size=(50, 6)))
    eight = subset(truth, EIGHT)
    np.testing.assert_allclose(exact.regularise(eight).values, truth.values, atol=1e-6)
    np.testing.assert_allclose(exact.to_parameters(eight), exact.to_parameters(truth), atol=1e-8)
    ridged = build_model(motion, parameters=6)  # the default small ridge: close
    error = ridged.regularise(subset(truth, EIGHT)).values - truth.values
    assert np.sqrt((error**2).mean()) < 0.01 * np.ptp(truth.values)


@pytest.mark.parametrize("quant", [None, 2.0])
def test_the_cached_solver_equals_a_fresh_least_squares_solve(quant):
    motion, _, _ = synthetic(count=6)
    model = build_model(motion, parameters=6, ridge=1e-3)
    received = np.isin(model.fap_columns + 1, EIGHT)
    solver = model.solver(received, quant=quant)
    assert model.solver(received.copy(), quant=quant) is solver  # kept per subset mask, whatever the values
    f = np.random.default_rng(4).normal(size=received.sum()) * 50
    if quant is None:  # errors weighed in cm, the model's ridge
        w, ridge = FAPU.scale()[model.fap_columns][received], model.ridge
    else:  # in quantiser steps, the variance of rounding as the ridge
        w, ridge = 1 / (TABLE.quant_step[model.fap_columns][received] * quant), 1 / 12
    A = np.vstack([w[:, None] * model.fap_matrix[received], np.sqrt(ridge) * np.eye(6)])
    b = np.concatenate([w * (f - model.fap_offset[received]), np.zeros(6)])
    fresh = np.linalg.lstsq(A, b, rcond=None)[0]
    np.testing.assert_allclose(solver @ (f - model.fap_offset[received]), fresh, rtol=1e-9, atol=1e-12)
    stream = FapStream(np.zeros((1, FAP_COUNT)), np.zeros((1, FAP_COUNT), bool), 25.0)
    values, mask = stream.values.copy(), stream.mask.copy()
    values[0, model.fap_columns[received]], mask[0, model.fap_columns[received]] = f, True
    np.testing.assert_allclose(model.to_parameters(FapStream(values, mask, 25.0), quant=quant)[0], fresh, rtol=1e-9)


def test_frames_with_too_few_faps_keep_what_arrived_and_other_faps_pass_through():
    motion, _, _ = synthetic(count=6)
    model = build_model(motion, parameters=6)
    truth = model.to_faps(np.random.default_rng(5).normal(size=(4, 6)))
    values, mask = truth.values.copy(), truth.mask.copy()
    mask[1] = False
    mask[1, columns([3, 4, 5])] = True  # three FAPs: fewer than the six parameters
    mask[2] = False  # a frame without a face
    head = TABLE.number("head_yaw") - 1
    values[:, head], mask[:, head] = 1234.0, True
    mask[2, head] = False
    stream = FapStream(values, mask, 25.0)
    out = model.regularise(stream)
    for t in (1, 2):
        np.testing.assert_array_equal(out.mask[t], stream.mask[t])
        np.testing.assert_array_equal(out.values[t], stream.values[t])
    assert out.mask[[0, 3]][:, model.fap_columns].all()
    np.testing.assert_array_equal(out.values[[0, 1, 3], head], 1234.0)
    assert np.isnan(model.to_parameters(stream)[[1, 2]]).all()


def smooth_synthetic(frames=600, seed=0, persistence=0.95):
    """``synthetic``'s face whose six parameters follow a first-order autoregression of unit variance:
    the motion, and a model built on its first 400 frames."""
    motion, vectors, _ = synthetic(frames=frames, count=6, seed=seed)
    rng = np.random.default_rng(seed + 10)
    a = np.zeros((frames, 6))
    a[0] = rng.normal(size=6)
    for t in range(1, frames):
        a[t] = persistence * a[t - 1] + np.sqrt(1 - persistence**2) * rng.normal(size=6)
    index = motion.index(mobile_names(motion))
    d = np.zeros_like(motion.displacements)
    d[:, index] = np.einsum("tk,kpc->tpc", a, vectors)
    smooth = Motion(motion.names, motion.neutral, d, motion.pose, motion.fps, motion.fapu)
    return smooth, build_model(smooth, parameters=6, frames=np.arange(400))


def test_the_persistence_is_each_parameters_lag_one_correlation_over_consecutive_frames():
    motion, model = smooth_synthetic(persistence=0.95)
    assert model.persistence.shape == (6,) and np.all(np.abs(model.persistence - 0.95) < 0.05)
    every_other = build_model(motion, parameters=6, frames=np.arange(0, 400, 2))  # no two frames follow
    np.testing.assert_array_equal(every_other.persistence, 0.0)


@pytest.mark.parametrize("sent", [None, EIGHT])
@pytest.mark.parametrize("quant", [None, 256.0])
def test_the_temporal_prior_brings_a_noisy_smooth_stream_closer_than_frame_by_frame(sent, quant):
    """Noise of the size each weighing assumes (cm: the ridge's variance; a quantiser: a rounding error,
    uniform over a step) on a stream whose parameters persist from frame to frame as the model measured.
    The past helps where a frame's own FAPs leave the parameters uncertain beside their change from one
    frame to the next: coarse steps, or few FAPs (at a ridge of 1e-3 cm^2 and all FAPs it gains ~2%)."""
    from dataclasses import replace

    motion, model = smooth_synthetic()
    model = replace(model, ridge=0.03)
    truth = model.to_faps(model.fit_points(motion.displacements[400:][:, motion.index(model.names)]))
    j = model.fap_columns
    rng = np.random.default_rng(9)
    values = truth.values.copy()
    if quant is None:
        values[:, j] += rng.normal(size=(len(truth), len(j))) * np.sqrt(model.ridge) / FAPU.scale()[j]
    else:
        values[:, j] += rng.uniform(-0.5, 0.5, size=(len(truth), len(j))) * TABLE.quant_step[j] * quant
    received = FapStream(values, truth.mask, truth.fps)
    received = received if sent is None else subset(received, sent)

    def error(stream):
        return np.sqrt(((stream.values[:, j] - truth.values[:, j]) ** 2).mean())

    alone = error(model.regularise(received, quant=quant))
    together = error(model.regularise(received, quant=quant, temporal=True))
    assert together < 0.9 * alone


def test_the_temporal_prior_is_causal_and_the_frame_by_frame_solve_without_persistence():
    motion, model = smooth_synthetic()
    truth = noisy(model.to_faps(np.random.default_rng(7).normal(size=(60, 6))), sigma=5.0)
    a = model.to_parameters(truth, temporal=True)
    later = FapStream(truth.values.copy(), truth.mask, truth.fps)
    later.values[30:] += 40.0  # what comes after frame 29 does not change frames up to 29
    np.testing.assert_array_equal(model.to_parameters(later, temporal=True)[:30], a[:30])
    assert not np.allclose(model.to_parameters(later, temporal=True)[30:], a[30:])
    from dataclasses import replace

    forgetful = replace(model, persistence=np.zeros(6))
    for quant in (None, 2.0):
        np.testing.assert_allclose(forgetful.to_parameters(truth, quant=quant, temporal=True),
                                   model.to_parameters(truth, quant=quant), atol=1e-10)


def test_a_still_noise_free_stream_through_the_temporal_prior():
    """Exact with a ridge of 0 (FAPs taken as exact); with the ridge, it settles nearer the truth than
    the frame-by-frame solve (the past's evidence outweighs the prior), at the filter's fixed point."""
    from dataclasses import replace

    motion, model = smooth_synthetic()
    true = np.array([0.5, -1.0, 0.3, 0.8, -0.2, 1.1])
    still = model.to_faps(np.tile(true, (300, 1)))
    for stream in (still, subset(still, EIGHT)):
        exact = replace(model, ridge=0.0)
        np.testing.assert_allclose(exact.to_parameters(stream, temporal=True), np.tile(true, (300, 1)), atol=1e-9)
        settled = model.to_parameters(stream, temporal=True)[-1]
        alone = model.to_parameters(stream)[-1]
        assert np.linalg.norm(settled - true) < np.linalg.norm(alone - true)
        received = stream.mask[0, model.fap_columns]
        A, B = model.filter_gain(received)
        fixed = np.linalg.solve(np.eye(6) - A, B @ (stream.values[0, model.fap_columns][received]
                                                    - model.fap_offset[received]))
        np.testing.assert_allclose(settled, fixed, atol=1e-9)


def test_the_temporal_prior_starts_afresh_after_a_frame_with_too_few_faps():
    motion, model = smooth_synthetic()
    truth = noisy(model.to_faps(np.random.default_rng(8).normal(size=(40, 6))), sigma=5.0)
    mask = truth.mask.copy()
    mask[20] = False  # a frame without a face
    cut = FapStream(truth.values, mask, truth.fps)
    a = model.to_parameters(cut, temporal=True)
    assert np.isnan(a[20]).all() and np.isfinite(a[[19, 21]]).all()
    tail = FapStream(truth.values[21:], truth.mask[21:], truth.fps)
    np.testing.assert_allclose(a[21:], model.to_parameters(tail, temporal=True), atol=1e-12)
    np.testing.assert_allclose(a[21], model.to_parameters(tail)[0], atol=1e-12)  # its own solve, no past


@pytest.mark.parametrize("temporal, window", [(False, None), (True, None), (True, 10), (True, 7)])
@pytest.mark.parametrize("quant", [None, 2.0])
def test_the_interpreter_on_pieces_equals_regularise_on_the_whole(temporal, window, quant):
    """A stream that arrives in pieces (a decoder's packets), with subsets changing and frames without
    a face, some cut across the pieces' bounds: the pieces joined are the whole stream regularised."""
    motion, model = smooth_synthetic()
    truth = noisy(model.to_faps(np.random.default_rng(11).normal(size=(90, 6))), sigma=5.0)
    mask = truth.mask.copy()
    mask[30:45] &= np.isin(np.arange(68) + 1, EIGHT)
    mask[[12, 13, 60]] = False
    stream = FapStream(truth.values, mask, truth.fps)
    whole = model.regularise(stream, quant=quant, temporal=temporal, window=window)
    interpret = model.interpreter(quant=quant, temporal=temporal, window=window)
    bounds = [0, 1, 12, 13, 14, 29, 44, 61, 90]
    pieces = [interpret(FapStream(stream.values[a:b], stream.mask[a:b], stream.fps, frame_numbers=np.arange(a, b)))
              for a, b in zip(bounds[:-1], bounds[1:], strict=True)]
    pieces = [p for p in [*pieces, interpret.finish()] if p is not None]
    if window:  # a window's frames come out once it is whole
        assert all(len(p) % window == 0 for p in pieces[:-1])
    np.testing.assert_allclose(np.concatenate([p.values for p in pieces]), whole.values, atol=1e-9)
    np.testing.assert_array_equal(np.concatenate([p.mask for p in pieces]), whole.mask)
    lonely = model.interpreter(temporal=temporal)
    lonely(subset(truth, [3, 14, 16, 17, 51]))  # a piece with too few FAPs passes through ...
    with pytest.raises(InputError, match="carries at most 5 of the speaker model's 34 FAPs"):
        lonely.finish()  # ... but a whole stream of them is refused, as regularise refuses it


def _trajectory_solve(model, stream, *, window=None):
    """The smoother's objective without cells, built and solved densely, run by run of the windows:
    the known answer of regularise(temporal=True, window=...) on a stream in cm."""
    j, G, F = model.fap_columns, model.fap_matrix, model.persistence
    weight, noise = model.fapu.scale()[j], model.ridge
    K, T = model.parameter_count, len(stream)
    window = window or T
    a, state = np.zeros((T, K)), None
    for start in range(0, T, window):
        n = min(T, start + window) - start
        mean0, cov0 = (np.zeros(K), np.eye(K)) if state is None else (F * state[0], np.diag(F) @ state[1] @ np.diag(F)
                                                                       + np.diag(1 - F**2))
        rows, rhs = [], []
        root0 = np.linalg.cholesky(np.linalg.inv(cov0)).T
        block = np.zeros((K, n * K))
        block[:, :K] = root0
        rows.append(block)
        rhs.append(root0 @ mean0)
        for t in range(1, n):
            block = np.zeros((K, n * K))
            block[:, t * K:(t + 1) * K] = np.diag(1 / np.sqrt(1 - F**2))
            block[:, (t - 1) * K:t * K] = -np.diag(F / np.sqrt(1 - F**2))
            rows.append(block)
            rhs.append(np.zeros(K))
        for t in range(n):
            received = stream.mask[start + t, j]
            block = np.zeros((received.sum(), n * K))
            block[:, t * K:(t + 1) * K] = (weight[:, None] * G)[received] / np.sqrt(noise)
            rows.append(block)
            rhs.append(weight[received] * (stream.values[start + t, j] - model.fap_offset)[received] / np.sqrt(noise))
        A, b = np.vstack(rows), np.concatenate(rhs)
        x = np.linalg.lstsq(A, b, rcond=None)[0]
        a[start:start + n] = x.reshape(n, K)
        state = (x[-K:], np.linalg.inv(A.T @ A)[-K:, -K:])
    return a


@pytest.mark.parametrize("window", [1, 9, None])
def test_the_smoother_is_the_trajectorys_least_squares_solution(window):
    """Without cells (a stream in cm), regularise(window=W) is the most probable trajectory under the
    temporal prior: the least-squares solution of the whitened prior and FAPs, window by window, each
    started from the one before (its last frame's mean and covariance)."""
    motion, model = smooth_synthetic()
    stream = subset(noisy(model.to_faps(np.random.default_rng(3).normal(size=(30, 6))), sigma=3.0), EIGHT)
    expected = _trajectory_solve(model, stream, window=window)
    a = model.regularise(stream, temporal=True, window=window or len(stream))
    np.testing.assert_allclose(a.values[:, model.fap_columns], expected @ model.fap_matrix.T + model.fap_offset,
                               atol=1e-6)


def test_the_smoother_keeps_each_coded_fap_within_its_cell_and_beats_the_filter_at_coarse_steps():
    """A stream the model makes, coarsely coded: the smoother's FAPs lie within their cells (half a step
    and CELL_MARGIN; the penalty is soft, so within a tenth of a step more), and it is closer to
    the truth than the causal filter."""
    from faceanim.mpeg4.fapcoder import decode_faps, encode_faps
    from faceanim.speaker.model import CELL_MARGIN

    motion, model = smooth_synthetic()
    truth = model.to_faps(model.fit_points(motion.displacements[400:][:, motion.index(model.names)]))
    truth = FapStream(np.rint(truth.values), truth.mask, truth.fps)
    j = model.fap_columns
    for quant in (16.0, 64.0):
        coded = decode_faps(encode_faps(truth, quant=quant))
        smooth = model.regularise(coded, quant=quant, temporal=True, window=25)
        step = TABLE.quant_step[j] * quant
        outside = np.abs(smooth.values[:, j] - coded.values[:, j]) - (step / 2 + CELL_MARGIN)
        assert (outside / step).max() < 0.1

        def error(stream):
            return np.sqrt(((stream.values[:, j] - truth.values[:, j]) ** 2).mean())

        assert error(smooth) < error(model.regularise(coded, quant=quant, temporal=True))
    with pytest.raises(ValueError, match="window smooths with the temporal prior"):
        model.regularise(coded, quant=quant, window=25)


def test_a_subset_too_small_on_every_frame_is_refused_in_one_line():
    motion, _, _ = synthetic(count=6)
    model = build_model(motion, parameters=6)
    truth = model.to_faps(np.zeros((5, 6)))
    with pytest.raises(InputError, match=r"carries at most 5 of the speaker model's 34 FAPs on a frame; its 6 "
                                         r"parameters need at least 6") as caught:
        model.regularise(subset(truth, [3, 14, 16, 17, 51]))
    assert "\n" not in str(caught.value)
    with pytest.raises(InputError, match="carries none of the speaker model's FAPs"):
        model.to_parameters(subset(truth, [19, 20]))


def test_the_model_file_round_trips(tmp_path):
    motion, _, _ = synthetic()
    model = build_model(motion, parameters=3, method="guided", ridge=2e-4)
    write_speaker(tmp_path / "s.npz", model)
    back = read_speaker(tmp_path / "s.npz")
    for field in ("names", "parameter_names", "static_names", "method", "ridge", "fps", "fapu"):
        assert getattr(back, field) == getattr(model, field)
    for field in ("neutral", "rest", "basis", "static_points", "triangles", "ranges"):
        np.testing.assert_array_equal(getattr(back, field), getattr(model, field))
    assert back.triangles.max() < len(back.names) + len(back.static_names)
    np.testing.assert_array_equal(back.fap_matrix, model.fap_matrix)
    np.testing.assert_array_equal(back.persistence, model.persistence)


def test_a_version_1_file_is_read_without_a_temporal_prior_which_is_then_refused(tmp_path):
    """Version 2 added the temporal prior's persistence; a version 1 file (without it) still decodes
    frame by frame as before, and asking it for the temporal prior is refused in one line."""
    path = rewritten(tmp_path, version=np.array(1), persistence=None)
    old = read_speaker(path)
    assert old.persistence is None
    truth = old.to_faps(np.random.default_rng(6).normal(size=(5, 3)))
    np.testing.assert_allclose(old.regularise(truth).values, read_speaker(tmp_path / "good.npz").regularise(
        truth).values)
    with pytest.raises(InputError, match="has no temporal prior \\(a version 1 file\\): build it again") as caught:
        old.regularise(truth, temporal=True)
    assert "\n" not in str(caught.value)
    write_speaker(tmp_path / "again.npz", old)  # written back as what it is: version 1
    with np.load(tmp_path / "again.npz") as archive:
        assert int(archive["version"]) == 1 and "persistence" not in archive.files
    assert read_speaker(tmp_path / "again.npz").persistence is None


def rewritten(tmp_path, **changes):
    motion, _, _ = synthetic()
    write_speaker(tmp_path / "good.npz", build_model(motion, parameters=3))
    with np.load(tmp_path / "good.npz") as archive:
        data = {k: archive[k] for k in archive.files}
    data.update(changes)
    for key in [k for k, v in changes.items() if v is None]:
        del data[key]
    np.savez(tmp_path / "bad.npz", **data)
    return tmp_path / "bad.npz"


@pytest.mark.parametrize("changes, match", [
    ({"version": np.array(7)}, "is a speaker model of version 7; this faceanim reads versions 1 to 2"),
    ({"persistence": None}, "lacks the speaker model's persistence"),
    ({"persistence": np.ones(3)}, "persistence must hold correlations from 0 to below 1"),
    ({"basis": np.zeros((3, 5, 3))}, r"basis must have shape \(K, \d+, 3\), got \(3, 5, 3\)"),
    ({"neutral": np.zeros((4, 3))}, r"neutral must have shape \(\d+, 3\), got \(4, 3\)"),
    ({"ranges": np.zeros((2, 2))}, r"ranges must have shape \(3, 2\)"),
    ({"fapu": np.ones(4)}, "fapu must hold 5 distances"),
    ({"triangles": np.full((2, 3), 10**6)}, "triangles"),
    ({"method": np.array("magic")}, "method must be pca or guided"),
    ({"rest": None}, "lacks the speaker model's rest"),
])
def test_bad_model_files_are_refused_in_one_line(tmp_path, changes, match):
    with pytest.raises(FileFormatError, match=match) as caught:
        read_speaker(rewritten(tmp_path, **changes))
    assert "\n" not in str(caught.value) and "bad.npz" in str(caught.value)


def test_a_file_that_is_no_npz_is_refused(tmp_path):
    (tmp_path / "x.npz").write_text("hello")
    with pytest.raises(FileFormatError, match="is not a speaker model"):
        read_speaker(tmp_path / "x.npz")
    np.save(tmp_path / "y.npz", np.zeros(3))  # a .npy under an .npz name
    with pytest.raises(FileFormatError, match="is not a speaker model"):
        read_speaker(tmp_path / "y.npz.npy")
    with pytest.raises(InputError, match="no such file"):
        read_speaker(tmp_path / "absent.npz")


# ---- the commands on a real speech clip

VIDEO = SHARED / "videos" / "speech_man.mp4"


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    if not VIDEO.exists():
        pytest.skip(f"needs {VIDEO} (the shared data folder beside the checkout)")
    folder = tmp_path_factory.mktemp("speaker")
    assert main(["speaker", "build", str(VIDEO), "-o", str(folder / "man.npz"), "--frames", "0:60"]) == 0
    return folder


def test_speaker_build_and_analyse_on_a_real_clip(built, capsys):
    model = read_speaker(built / "man.npz")
    assert model.parameter_count == 6 and model.method == "guided" and len(model.fap_columns) == 34
    assert main(["speaker", "analyse", str(VIDEO), "--model", str(built / "man.npz"), "-o", str(built / "man.fap"),
                 "--params-csv", str(built / "p.csv")]) == 0
    assert "wrote" in capsys.readouterr().out
    stream = read_fap(built / "man.fap")
    assert len(stream) == 125 and stream.mask[:, model.fap_columns].all()
    lines = (built / "p.csv").read_text().splitlines()
    assert lines[0] == "frame,timestamp,jaw,protrusion,opening,upper_lip,lower_lip,corners" and len(lines) == 126
    # the written stream is the model's own: interpreting it changes it by its rounding (and the ridge) alone
    again = model.regularise(stream, quant=1.0)
    assert np.abs(again.values - stream.values)[:, model.fap_columns].max() < 2.0


def test_decode_through_the_speaker_model(built, tmp_path):
    from conftest import grid_mesh

    from faceanim.pipeline import decode
    from faceanim.target import Target

    model = read_speaker(built / "man.npz")
    truth = model.to_faps(np.zeros((3, 6)) + [1, 0, 0, 0, 0, 0])
    eight = subset(truth, EIGHT)
    from faceanim.mpeg4.fapfile import write_fap

    write_fap(tmp_path / "eight.fap", eight)
    at = {"2.1": 4, "2.3": 13, "2.2": 22, "8.3": 24, "8.4": 20, "9.15": 40, "3.1": 61, "3.3": 52, "3.2": 55,
          "3.4": 46, "3.5": 60, "3.6": 56, "2.4": 23, "8.2": 5}
    target = Target(grid_mesh(9, size=8.0), at, Fapu(irisd0=1.0, es0=4.0, ens0=2.0, mns0=2.0, mw0=4.0))
    plain = decode(tmp_path / "eight.fap", tmp_path / "plain.glb", target=target).positions
    through = decode(tmp_path / "eight.fap", tmp_path / "through.glb", target=target,
                     speaker=built / "man.npz").positions
    corner = target.points["2.4"]  # no FAP of 2.4 was sent: only the model moves it
    assert np.abs(plain[:, corner] - target.mesh.vertices[corner]).max() == 0
    assert np.abs(through[:, corner] - target.mesh.vertices[corner]).max() > 1e-3


@pytest.mark.parametrize("argv, match", [
    (["--frames", "60:10"], "--frames 60:10: frames must satisfy 0 <= START < END"),
    (["--frames", "0:5000"], "the video has 125 frames"),
    (["--frames", "0:3"], "3 frames with a face are too few for 6 parameters"),
    (["--params", "0"], "--params 0: give a whole number"),
])
def test_speaker_build_refuses_bad_arguments_in_one_line(built, capsys, tmp_path, argv, match):
    assert main(["speaker", "build", str(VIDEO), "-o", str(tmp_path / "x.npz"), *argv]) == 2
    err = capsys.readouterr().err
    assert match in err and err.count("\n") == 1
    assert not (tmp_path / "x.npz").exists()


def test_decode_refuses_a_bad_speaker_file_and_a_too_small_subset(built, capsys, tmp_path):
    (tmp_path / "bad.npz").write_text("no")
    model = read_speaker(built / "man.npz")
    from faceanim.mpeg4.fapfile import write_fap

    write_fap(tmp_path / "few.fap", subset(model.to_faps(np.zeros((2, 6))), [3, 14, 16]))
    few = tmp_path / "few.fap"
    for speaker, match in ((tmp_path / "bad.npz", "is not a speaker model"),
                           (built / "man.npz", f"{few} with --speaker {built / 'man.npz'}: the FAP stream ")):
        code = main(["decode", str(few), "-o", str(tmp_path / "o.glb"), "--speaker", str(speaker)])
        err = capsys.readouterr().err
        assert code == 2 and match in err and err.count("\n") == 1
        assert "is not a speaker model" in err or "carries at most 3 of the speaker model's 34 FAPs" in err
        assert not (tmp_path / "o.glb").exists()
