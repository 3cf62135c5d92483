"""Long work shown on stderr (faceanim.progress), and the jobs that show it only when asked."""

import io
import sys

import pytest

from faceanim import pipeline
from faceanim.cli import main
from faceanim.progress import QUIET, Interrupted, Progress, Quiet, as_progress


def test_a_step_is_one_line():
    shown = io.StringIO()
    Progress(shown).status("placing control points on head.obj")
    assert shown.getvalue() == "faceanim: placing control points on head.obj...\n"


def test_a_loop_off_a_terminal_is_one_line_and_yields_everything_in_order():
    shown = io.StringIO()  # not a terminal
    assert list(Progress(shown).bar(iter("abc"), total=3, desc="rendering the preview")) == ["a", "b", "c"]
    assert shown.getvalue() == "faceanim: rendering the preview (3 frames)...\n"
    shown = io.StringIO()
    assert list(Progress(shown).bar(iter("ab"), desc="tracking")) == ["a", "b"]  # a video that states no length
    assert shown.getvalue() == "faceanim: tracking...\n"


def test_a_loop_gets_a_bar_when_asked():
    shown = io.StringIO()
    assert list(Progress(shown, bars=True).bar(range(5), total=5, desc="tracking")) == list(range(5))
    assert "tracking" in shown.getvalue() and "5/5" in shown.getvalue()


def test_a_step_said_while_a_bar_runs_gets_a_line_of_its_own():
    """A job's placement says its steps while the tracking's bar is drawn: the bar is cleared, the
    step is written on a clean line, and the bar is drawn again below it (on a terminal, a line
    whose text follows a carriage return shows only that text)."""
    shown = io.StringIO()
    progress = Progress(shown, bars=True)
    frames = iter(progress.bar(range(5), total=5, desc="tracking"))
    next(frames), next(frames)
    progress.status("placing control points on head.obj")
    assert list(frames) == [2, 3, 4]
    seen = [line.rsplit("\r", 1)[-1] for line in shown.getvalue().split("\n")]
    assert "faceanim: placing control points on head.obj..." in seen
    assert seen[-2].startswith("tracking: 100%") and seen[-1] == ""


def test_quiet_unless_given_a_progress():
    assert as_progress(None) is QUIET and as_progress(False) is QUIET
    assert type(as_progress(True)) is Progress
    shown = Progress(io.StringIO())
    assert as_progress(shown) is shown
    assert list(QUIET.bar(range(3), total=3, desc="x")) == [0, 1, 2]
    with pytest.raises(TypeError, match="progress must be a Progress, True, False or None, got str"):
        as_progress("yes")


def test_the_command_shows_each_long_step_on_a_terminal_only(tmp_path, capsys, monkeypatch):
    assert main(["express", "--au", "12:1.0", "--frames", "3", "-o", str(tmp_path / "a.glb")]) == 0
    assert capsys.readouterr().err == ""  # off a terminal: only the result (on stdout) and errors
    monkeypatch.setattr(sys.stderr, "isatty", lambda: True)
    assert main(["express", "--au", "12:1.0", "--frames", "3", "-o", str(tmp_path / "b.glb")]) == 0
    err = capsys.readouterr().err
    assert "faceanim: making the avatar of the embedded portrait" in err
    assert "making the expression" in err and "3/3" in err  # a bar
    assert f"faceanim: writing {tmp_path / 'b.glb'} with" in err
    pipeline.express(tmp_path / "c.glb", au="12:1.0", frames=3)  # the library job stays quiet
    assert capsys.readouterr().err == ""


@pytest.mark.parametrize("progress", [Quiet, lambda **kw: Progress(io.StringIO(), bars=False, **kw)])
def test_a_frame_loop_stops_at_the_next_frame_once_an_interrupt_was_received(progress):
    """The command line raises an interrupt where it lands; a library catching BaseException can swallow
    it (trimesh's optional imports do), and the job used to run to its end. The loops now stop."""
    import signal

    received = []
    seen = []
    with pytest.raises(Interrupted) as stop:
        for i in progress(interrupts=received).bar(range(10), total=10, desc="deforming"):
            seen.append(i)
            if i == 3:
                received.append(signal.SIGTERM)  # what the handler records before raising
    assert seen == [0, 1, 2, 3] and stop.value.signum == signal.SIGTERM
    assert list(Progress(io.StringIO(), bars=False).bar(range(3), total=3, desc="x")) == [0, 1, 2]  # unwatched


def test_work_beside_the_job_stops_at_its_next_frame_when_the_job_fails():
    """``animate`` tracks the video in a thread while it places the control points: a bad target stops
    the tracking instead of waiting for the whole video."""
    import threading
    import time

    from faceanim.errors import InputError

    seen = []
    started = threading.Event()

    def tracking(shown):
        for i in shown.bar(range(10_000), total=10_000, desc="tracking"):
            seen.append(i)
            started.set()
            time.sleep(0.001)
        return "tracked"

    def placement():
        started.wait(5)
        raise InputError("head.obj: its parts cannot be told apart")

    with pytest.raises(InputError, match="parts"):
        pipeline._beside(placement, tracking, Quiet())
    assert 0 < len(seen) < 10_000
    assert pipeline._beside(lambda: "placed", lambda shown: list(shown.bar(range(3), desc="t")), Quiet()) == \
        ("placed", [0, 1, 2])


def test_an_interrupt_while_the_job_waits_for_the_work_beside_it_stops_that_work():
    """The placement is usually done first; a Ctrl-C then lands while ``animate`` waits for the
    tracking, which must stop at its next frame (and not run on through the video)."""
    import signal
    import threading
    import time

    seen = []

    def tracking(shown):
        for i in shown.bar(range(20_000), total=20_000, desc="tracking"):
            seen.append(i)
            time.sleep(0.001)

    def interrupted(signum, frame):
        raise Interrupted(signum)

    before = signal.signal(signal.SIGALRM, interrupted)
    signal.setitimer(signal.ITIMER_REAL, 0.3)
    try:
        with pytest.raises(Interrupted):
            pipeline._beside(lambda: "placed", tracking, Quiet(interrupts=[]))
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, before)
    assert 0 < len(seen) < 20_000
    assert not [t for t in threading.enumerate() if t.name.startswith("faceanim")]  # the thread has ended
