"""tools/studies/frame_threads.py: each thread's CPU time under its role, and one run's figures."""
from __future__ import annotations

import os
import threading
import time
from pathlib import Path

import pytest

from fastdet.config import PipelineConfig
from fastdet.io.reader import QUEUE_SIZE
from tools.studies.frame_threads import ROLES, cpu_by_role, measure, role_of, table, thread_cpu, thread_names

pytestmark = pytest.mark.skipif(not os.path.isdir("/proc/self/task"), reason="reads Linux's /proc/self/task")


def _spin(seconds: float) -> None:
    end = time.thread_time() + seconds
    while time.thread_time() < end:
        pass


def test_roles_by_python_name():
    assert role_of("fastdet-band_0", False) == "band pool"
    assert role_of("fastdet-decode", False) == "decode"
    assert role_of("fastdet-tail_0", False) == "beside"
    assert role_of("Thread-3", False) == role_of(None, False) == "other"
    assert role_of(None, True) == "main"
    assert role_of(None, False, "av:h264:df0") == "decode"  # FFmpeg's decoding workers
    assert role_of(None, False, "python") == "other"


def test_a_named_thread_s_cpu_goes_to_its_role():
    """A thread named as the decoding thread that burns 0.3 s of CPU shows it under ``decode``;
    the main thread, idle meanwhile, shows little."""
    go, done = threading.Event(), threading.Event()

    def work() -> None:
        go.wait()
        _spin(0.3)
        done.set()
        time.sleep(1.0)  # alive at the second reading

    t = threading.Thread(target=work, name="fastdet-decode", daemon=True)
    t.start()
    before = thread_cpu()
    go.set()
    assert done.wait(10)
    after, names = thread_cpu(), thread_names()
    roles = cpu_by_role(before, after, names)
    assert set(roles) == set(ROLES)
    assert 0.25 <= roles["decode"] <= 0.5
    assert roles["main"] < 0.2
    assert roles["band pool"] == roles["beside"] == 0.0
    t.join()


def test_a_thread_that_ends_between_the_readings_is_under_ended():
    """A thread that burns 0.3 s of CPU and ends before the second reading has no reading of its
    own: the process's CPU time puts it under ``ended``; without it, it is lost."""
    def work() -> None:
        _spin(0.3)

    before, p0 = thread_cpu(), time.process_time()
    t = threading.Thread(target=work, name="fastdet-decode", daemon=True)
    t.start()
    t.join()
    # the kernel may list the task a moment after Python's join: wait until it is gone (5 s at most)
    end = time.monotonic() + 5
    while str(t.native_id) in os.listdir("/proc/self/task") and time.monotonic() < end:
        time.sleep(0.01)
    after, names, p1 = thread_cpu(), thread_names(), time.process_time()
    assert t.native_id not in after
    roles = cpu_by_role(before, after, names, process=p1 - p0)
    assert roles["decode"] == 0.0 and 0.2 <= roles["ended"] <= 0.5
    assert cpu_by_role(before, after, names)["ended"] == 0.0


def test_measure_a_clip(data: Path):
    """At 1 thread the bands are the main thread's (no pool); at 2 the pool takes a share; the
    band phase is part of a frame's wall time and no role's CPU is negative."""
    video = data / "videos" / "test_small1.mp4"
    one = measure(video, PipelineConfig(), threads=1, frames=30, skip=5)
    two = measure(video, PipelineConfig(), threads=2, frames=30, skip=5)
    for r in (one, two):
        assert r.frames == 30 - 5 - 5 - QUEUE_SIZE  # the window ends before the reader's read-ahead
        assert r.cpu_ms["ended"] < 0.5 * sum(r.cpu_ms.values())  # the decoding threads still alive
        assert 0 < r.band_phase_ms <= r.wall_ms
        assert all(v >= 0 for v in r.cpu_ms.values())
        assert r.cpu_ms["main"] > 0
    assert one.cpu_ms["band pool"] == 0.0
    assert two.cpu_ms["band pool"] > 0
    text = table([one, two])
    assert text.count("\n") == 3 and "| 1 |" in text and "| 2 |" in text and "CPU ended" in text


def test_too_short_a_clip(data: Path):
    with pytest.raises(ValueError, match="fewer than"):
        measure(data / "videos" / "test_small1.mp4", PipelineConfig(), threads=1, frames=8, skip=5)
