"""Long calls release the GIL, stop on Ctrl-C, and report progress."""

import os
import signal
import threading
import time

import pytest

import btfsynth
from conftest import PHOTO


def test_another_python_thread_runs_during_a_synthesis(analysis):
    counts, stop = [0], threading.Event()

    def count():
        while not stop.is_set():
            counts[0] += 1

    thread = threading.Thread(target=count)
    thread.start()
    try:
        before = counts[0]
        started = time.perf_counter()
        btfsynth.synthesize_plane(analysis, (256, 256))
        seconds = time.perf_counter() - started
        during = counts[0] - before
    finally:
        stop.set()
        thread.join()
    # Holding the GIL, the synthesis would leave the counter a few 5 ms switch slices
    # (the waiting thread takes the GIL back only to poll, 20 times a second).
    assert seconds > 0.2 and during > 10_000, (during, seconds)


@pytest.mark.skipif(threading.current_thread() is not threading.main_thread(), reason="signals reach the main thread")
def test_ctrl_c_interrupts_a_long_synthesis(analysis):
    timer = threading.Timer(0.5, lambda: os.kill(os.getpid(), signal.SIGINT))
    started = time.perf_counter()
    timer.start()
    with pytest.raises(KeyboardInterrupt):
        btfsynth.synthesize_plane(analysis, (2048, 2048))
    # The call returns at its next 50 ms poll (measured well under a second); the bound is
    # loose for a loaded machine, and far below the synthesis' own time (26 s quiet).
    latency = time.perf_counter() - started - 0.5
    assert latency < 5.0, latency
    # The abandoned work stops at its next progress report (the end of a pass), and frees
    # its threads; a pass of the finest level may take a minute on a loaded machine.
    deadline = time.perf_counter() + 300
    while btfsynth._native._running() and time.perf_counter() < deadline:
        time.sleep(0.05)
    assert btfsynth._native._running() == 0


def test_progress_reaches_the_callback_in_order():
    seen = []
    btfsynth.analyze(PHOTO, textons=32, levels=2, progress=lambda done, total, stage: seen.append((done, total, stage)))
    assert seen, "no progress reported"
    assert all(0 <= d <= t for d, t, _ in seen) and all(isinstance(s, str) and s for _, _, s in seen)
    stages = {s for _, _, s in seen}
    assert len(stages) >= 2, stages
    # Each stage's count never goes back.
    last = {}
    for done, _, stage in seen:
        assert done >= last.get(stage, 0) or done == 0
        last[stage] = done


def test_an_exception_in_the_callback_stops_the_call(analysis):
    def fail(done, total, stage):
        raise RuntimeError("stop here")

    with pytest.raises(RuntimeError, match="stop here"):
        btfsynth.synthesize_plane(analysis, (512, 512), progress=fail)


def test_tqdm_bars_when_asked(analysis, capsys):
    pytest.importorskip("tqdm")
    btfsynth.synthesize_plane(analysis, (64, 64), progress="tqdm")
    assert "synthesizing" in capsys.readouterr().err
    with pytest.raises(TypeError, match="progress"):
        btfsynth.synthesize_plane(analysis, (64, 64), progress=3)
