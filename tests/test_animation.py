"""`Animation` held or streamed, and the morph compression reading a streamed one in bounded memory."""

import os
import tracemalloc

import numpy as np
import pytest

from faceanim.export import morphs_from_animation
from faceanim.geometry import Mesh
from faceanim.geometry.animation import Animation


def wave_mesh(vertices: int = 600) -> Mesh:
    rng = np.random.default_rng(0)
    return Mesh(rng.normal(size=(vertices, 3)), [[0, 1, 2]])


def wave_source(mesh: Mesh, calls: list | None = None):
    """Frames of three travelling modes, made from the frame number alone (as a deformer makes them)."""
    rng = np.random.default_rng(1)
    shapes = rng.normal(size=(3, len(mesh.vertices), 3)) * [[[1.0]], [[0.3]], [[0.05]]]

    def frames(start, stop):
        if calls is not None:
            calls.append((start, stop))
        t = np.arange(start, stop)[:, None] / 25.0
        curves = np.hstack([np.sin(t), np.cos(3 * t), np.sin(7 * t + 1)])
        return mesh.vertices + np.einsum("tk,kvc->tvc", curves, shapes)

    return frames


def test_a_streamed_animation_gives_what_a_held_one_gives():
    mesh = wave_mesh()
    streamed = Animation.streamed(mesh, wave_source(mesh), 100, 25.0)
    held = Animation(mesh, streamed.positions, 25.0)
    assert streamed.is_streamed and not held.is_streamed and len(streamed) == len(held) == 100
    np.testing.assert_array_equal(np.concatenate(list(streamed.chunks(7))), held.positions)
    np.testing.assert_array_equal(np.stack(list(streamed.frames())), held.positions)
    np.testing.assert_array_equal(streamed.chunk(40, 43), held.positions[40:43])
    a, b = morphs_from_animation(streamed), morphs_from_animation(held)
    assert a.names == b.names and a.max_error == b.max_error
    np.testing.assert_array_equal(a.weights, b.weights)


def test_an_animation_cannot_be_changed_once_made():
    mesh = wave_mesh(10)
    positions = np.repeat(mesh.vertices[None], 3, axis=0)
    held = Animation(mesh, positions, 25.0)
    positions[0, 0] = 99.0  # the caller's array: the animation holds its own copy
    assert held.positions[0, 0, 0] != 99.0
    with pytest.raises(ValueError, match="read-only"):
        held.positions[1, 1] = 5.0
    with pytest.raises(AttributeError, match="immutable"):
        held.fps = 30.0


def test_reading_outside_the_frames_or_a_bad_source_is_refused():
    mesh = wave_mesh(10)
    animation = Animation.streamed(mesh, lambda a, b: np.zeros((b - a, 4, 3)), 5, 25.0)
    with pytest.raises(IndexError, match="frames 3:9 are outside the animation's 0:5"):
        animation.chunk(3, 9)
    with pytest.raises(ValueError, match=r"made shape \(2, 4, 3\) for frames 0:2, expected \(2, 10, 3\)"):
        animation.chunk(0, 2)
    with pytest.raises(ValueError, match="length must be a whole number of at least 1, got 0"):
        Animation.streamed(mesh, lambda a, b: None, 0, 25.0)
    with pytest.raises(ValueError, match="fps must be positive"):
        Animation.streamed(mesh, lambda a, b: None, 3, 0.0)


def test_map_changes_every_frame_and_keeps_streaming():
    mesh = wave_mesh(20)
    calls = []
    lifted = Animation.streamed(mesh, wave_source(mesh, calls), 50, 25.0).map(
        lambda a, b, positions: positions + np.arange(a, b)[:, None, None])
    assert lifted.is_streamed and not calls  # nothing made until read
    plain = Animation.streamed(mesh, wave_source(mesh), 50, 25.0).positions
    np.testing.assert_allclose(lifted.positions, plain + np.arange(50)[:, None, None])


def test_the_compression_reads_a_streamed_animation_twice_in_chunks_never_whole():
    mesh = wave_mesh()
    calls = []
    morphs_from_animation(Animation.streamed(mesh, wave_source(mesh, calls), 500, 25.0))
    assert max(stop - start for start, stop in calls) <= 96
    assert sum(stop - start for start, stop in calls) == 2 * 500  # two passes, each frame made once in each


def test_the_compressions_memory_does_not_grow_with_the_number_of_frames():
    """Peak memory (tracemalloc sees numpy's buffers) of compressing 500 and 3,000 frames: the extra
    2,500 frames would hold 36 MB of positions; the compression's extra is the weights (T x K), < 1 MB.
    (Below a few hundred frames the running SVD has not yet reached its rank, so it holds less.)"""
    mesh = wave_mesh(600)

    def traced_peak(frames: int) -> int:
        animation = Animation.streamed(mesh, wave_source(mesh), frames, 25.0)
        tracemalloc.start()
        try:
            morphs_from_animation(animation)
            return tracemalloc.get_traced_memory()[1]
        finally:
            tracemalloc.stop()

    growth = traced_peak(3000) - traced_peak(500)
    assert growth < 1e6, growth


@pytest.mark.parametrize("workers", [2, 3])
def test_frames_made_by_several_processes_are_the_frames_made_by_one(tmp_path, workers):
    from faceanim.geometry.animation import PARALLEL_RUN, spilled
    from faceanim.progress import Quiet

    mesh = wave_mesh()
    streamed = Animation.streamed(mesh, wave_source(mesh), 5 * PARALLEL_RUN + 3, 25.0)
    shown = []

    class Counting(Quiet):
        def bar(self, iterable, *, total=None, desc, unit="frame"):
            shown.append(total)
            return (shown.append(item) or item for item in iterable)

    with spilled(streamed, folder=tmp_path, workers=1) as one, \
            spilled(streamed, folder=tmp_path, workers=workers, progress=Counting()) as several:
        np.testing.assert_array_equal(several.positions, one.positions)
    assert shown[0] == len(streamed) and len(shown) == 1 + len(streamed)  # one step shown per frame, by anyone


def test_an_error_in_a_process_making_frames_is_raised_and_nothing_is_kept(tmp_path):
    from faceanim.geometry.animation import PARALLEL_RUN, spilled

    mesh = wave_mesh()
    made = wave_source(mesh)

    def broken(start, stop):
        if start >= 3 * PARALLEL_RUN:  # a run the forked worker or this process takes
            raise ValueError(f"frame {start} cannot be made")
        return made(start, stop)

    with pytest.raises(ValueError, match="cannot be made"):
        with spilled(Animation.streamed(mesh, broken, 6 * PARALLEL_RUN, 25.0), folder=tmp_path, workers=2):
            pytest.fail("the frames were yielded although some could not be made")
    assert list(tmp_path.iterdir()) == []  # the store has no name: nothing is left behind


def test_a_workers_error_reaches_the_job_as_the_kind_the_command_reports_in_one_line():
    """A FileFormatError (whose constructor takes a path and a message) and the command's Interrupted
    do not unpickle as they are; they are carried as the nearest class that does, words kept, with the
    worker's traceback as a note."""
    import pickle

    from faceanim.errors import FileFormatError, InputError
    from faceanim.geometry.animation import _carried
    from faceanim.progress import Interrupted

    for error, kind in ((FileFormatError("head.obj", "no faces", line=3), InputError),
                        (Interrupted(15), KeyboardInterrupt), (ValueError("bad frame"), ValueError)):
        carried = pickle.loads(pickle.dumps(_carried(error, "Traceback: here")))
        assert isinstance(carried, kind) and str(carried) == str(error)
        assert "Traceback: here" in carried.__notes__[0]


@pytest.mark.parametrize("workers", [0, 2.5, True, "2"])
def test_a_bad_number_of_workers_is_refused(tmp_path, workers):
    """0, a fraction, a bool or a word: refused before any frame is made."""
    from faceanim.geometry.animation import spilled

    mesh = wave_mesh()
    with pytest.raises(ValueError, match="workers must be a whole number"):
        with spilled(Animation.streamed(mesh, wave_source(mesh), 20, 25.0), folder=tmp_path, workers=workers):
            pass


@pytest.mark.parametrize("files, quota", [
    ({"cpu.max": "50000 100000\n"}, 1),  # cgroup v2: half a CPU's time
    ({"cpu.max": "150000 100000\n"}, 2),  # one and a half: a second worker has time to run
    ({"cpu.max": "max 100000\n"}, None),  # v2, unlimited
    ({"cpu.max": "max\n", "cpu/cpu.cfs_quota_us": "50000\n", "cpu/cpu.cfs_period_us": "100000\n"}, None),
    ({"cpu.max": "50000\n"}, None),  # no period: unreadable
    ({"cpu/cpu.cfs_quota_us": "50000\n", "cpu/cpu.cfs_period_us": "100000\n"}, 1),  # v1
    ({"cpu/cpu.cfs_quota_us": "-1\n", "cpu/cpu.cfs_period_us": "100000\n"}, None),  # v1, unlimited
    ({"cpu.max": "garbled\n"}, None),
    ({}, None),
])
def test_the_default_number_of_workers_keeps_within_a_containers_cpu_quota(tmp_path, files, quota):
    """A container given half a CPU on a many-core host forks no second worker; no quota, or one that
    cannot be read, leaves the CPUs the process may run on."""
    from faceanim.cpus import usable_cpus

    for name, text in files.items():
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text(text)
    affinity = len(os.sched_getaffinity(0))
    assert usable_cpus(str(tmp_path)) == (affinity if quota is None else min(affinity, quota))
