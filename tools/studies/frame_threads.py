"""Where a frame's time goes between the threads of ``video --boxes``: wall milliseconds a frame,
the band phase's share of it, and each thread's CPU milliseconds a frame, at 1 and 2 threads
(issue 31's speed goal is measured at 2; docs/benchmarks.md "Where the second core goes").

The pipeline runs as ``video --boxes`` runs it (:func:`fastdet.video.pipeline.run_frames`: the
decoding thread ahead, a frame's last stages beside the next frame) over the first ``--frames``
frames of the clip, kernels compiled and the models loaded before the clock starts. Each
thread's CPU time is read from Linux's ``/proc/self/task`` before and after and put under the
role its Python name gives it:

- ``main``: the thread that runs the frame loop, the detector's share of the bands among them;
- ``band pool``: the detector's helper threads (``fastdet-band``), the other share of the bands;
- ``decode``: :class:`~fastdet.io.reader.FrameReader`'s thread and FFmpeg's decoding workers
  (threads named ``av:...`` by the system; they do most of the decoding);
- ``beside``: the thread that runs a frame's last stages beside the next frame (``fastdet-tail``);
- ``other``: threads without a Python name: OpenCV's own worker pool (``cv2.setNumThreads(1)``
  leaves it empty) and OpenMP's workers;
- ``ended``: threads that ended between the two readings (their last reading is gone): the
  process's CPU time (``time.process_time``) less that of the threads alive at the end. The
  window ends :data:`~fastdet.io.reader.QUEUE_SIZE` frames before the reader's last one, so the
  decoding threads, which end with the file, are still alive; the role should be about 0.

``band phase`` is the wall time a frame spends in the detector's band scoring
(:meth:`fastdet.detect.Detector._all_band_scores`), the part the band threads share; ``cores
busy`` is the process's CPU time over the wall time.

    python -m tools.studies.frame_threads [--video V] [--model M.npz] [--frames 750] [--threads 1 2] [--repeats 2]
"""
from __future__ import annotations

import argparse
import os
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numba

from fastdet.config import PipelineConfig
from fastdet.data import data_dir
from fastdet.io.reader import QUEUE_SIZE, FrameReader
from fastdet.video import make_detector, run_frames, video_detector_for

ROLES = ("main", "band pool", "decode", "beside", "other", "ended")


def thread_stats() -> tuple[dict[int, float], dict[int, str]]:
    """``(CPU seconds, system name)`` of each live thread of this process, by its native id, in
    one pass over ``/proc/self/task`` (Linux): user + system time from ``TID/stat``, the name
    from ``TID/comm`` (FFmpeg names its workers ``av:...``). ``OSError`` where there is no such
    folder."""
    tick = os.sysconf("SC_CLK_TCK")
    cpu: dict[int, float] = {}
    comms: dict[int, str] = {}
    for name in os.listdir("/proc/self/task"):
        try:
            with open(f"/proc/self/task/{name}/stat") as f:
                stat = f.read()
            with open(f"/proc/self/task/{name}/comm") as f:
                comm = f.read().strip()
        except OSError:  # the thread ended meanwhile
            continue
        fields = stat.rsplit(")", 1)[1].split()  # after the command name, which may hold spaces
        cpu[int(name)] = (int(fields[11]) + int(fields[12])) / tick  # utime, stime
        comms[int(name)] = comm
    return cpu, comms


def thread_cpu() -> dict[int, float]:
    """CPU seconds (user + system) of each live thread, by its native id (:func:`thread_stats`)."""
    return thread_stats()[0]


def role_of(name: str | None, is_main: bool, comm: str | None = None) -> str:
    """The role (:data:`ROLES`) of a thread by its Python name (``None``: none) or, for a thread
    without one, its system name ``comm`` (FFmpeg names its workers ``av:...``)."""
    if is_main:
        return "main"
    if name is None:
        return "decode" if comm is not None and comm.startswith("av:") else "other"
    for prefix, role in (("fastdet-band", "band pool"), ("fastdet-decode", "decode"), ("fastdet-tail", "beside")):
        if name.startswith(prefix):
            return role
    return "other"


def thread_names() -> dict[int, str]:
    """The Python name of each live Python thread, by its native id."""
    return {t.native_id: t.name for t in threading.enumerate() if t.native_id is not None}


def cpu_by_role(before: dict[int, float], after: dict[int, float], names: dict[int, str],
                process: float | None = None, comms: dict[int, str] | None = None) -> dict[str, float]:
    """CPU seconds each role spent between two :func:`thread_cpu` readings, the threads named by
    ``names`` (:func:`thread_names` at the second reading). A thread that started in between
    counts from zero; one that ended has no last reading: ``process``, the process's CPU seconds
    between the readings, gives the ``ended`` role what the live threads do not account for
    (0 without it). ``comms``: the system names of :func:`thread_stats` at the second reading."""
    main = threading.main_thread().native_id
    comms = comms or {}
    out = dict.fromkeys(ROLES, 0.0)
    for tid, cpu in after.items():
        out[role_of(names.get(tid), tid == main, comms.get(tid))] += max(cpu - before.get(tid, 0.0), 0.0)
    if process is not None:
        out["ended"] = max(process - sum(out.values()), 0.0)
    return out


@dataclass(frozen=True)
class FrameThreads:
    """One run's figures, milliseconds a frame."""

    threads: int
    frames: int
    wall_ms: float
    band_phase_ms: float
    cpu_ms: dict[str, float]  # by role

    @property
    def cores_busy(self) -> float:
        return sum(self.cpu_ms.values()) / self.wall_ms if self.wall_ms else 0.0


def _timed(fn: Callable[..., Any], total: list[float]) -> Callable[..., Any]:
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        t = time.perf_counter()
        try:
            return fn(*args, **kwargs)
        finally:
            total[0] += time.perf_counter() - t
    return wrapper


def measure(video: str | os.PathLike, config: PipelineConfig, threads: int, frames: int,
            skip: int = 10) -> FrameThreads:
    """The pipeline over the first ``frames`` frames of ``video`` with ``threads`` Numba threads,
    measured from the ``skip``-th frame to the ``skip + QUEUE_SIZE``-th from the end (the reader
    decodes that far ahead, and its threads end with the file)."""
    before_threads = numba.get_num_threads()
    numba.set_num_threads(threads)
    try:
        detector = make_detector(config)
        band_s = [0.0]
        # this detector's band scoring, timed (an instance attribute: the class is left alone)
        detector._all_band_scores = _timed(detector._all_band_scores, band_s)  # type: ignore[method-assign]
        reader = FrameReader(video, 0, frames)
        vd = video_detector_for(reader, detector, config)
        # read between the skip-th frame and the (skip + QUEUE_SIZE)-th from the end, every thread
        # alive: the reader decodes QUEUE_SIZE frames ahead, and its threads end with the file
        # (their CPU time with them)
        last = reader.expected if reader.expected is not None else frames
        end = skip + QUEUE_SIZE
        marks: list[tuple[float, float, float, dict[int, float], dict[int, str], dict[int, str]]] = []
        try:
            if last < skip + end + 1:
                raise ValueError(f"{video}: {last} frames, fewer than the {skip + end + 1} the measurement needs")
            vd.warmup()
            for i, _ in enumerate(run_frames(vd, reader)):
                if i == skip or i == last - end:
                    marks.append((time.perf_counter(), band_s[0], time.process_time(), *thread_stats(),
                                  thread_names()))
        finally:
            reader.close()
            vd.close()
    finally:
        numba.set_num_threads(before_threads)
    if len(marks) < 2:
        raise ValueError(f"{video}: decoding ended before frame {last - end}")
    (t0, b0, p0, cpu0, _, _), (t1, b1, p1, cpu1, comms, names) = marks
    n = last - end - skip
    wall = t1 - t0
    roles = cpu_by_role(cpu0, cpu1, names, process=p1 - p0, comms=comms)
    return FrameThreads(threads, n, wall / n * 1e3, (b1 - b0) / n * 1e3, {k: v / n * 1e3 for k, v in roles.items()})


def table(rows: Sequence[FrameThreads]) -> str:
    """A markdown table of runs."""
    head = ("| threads | wall ms / frame | band phase ms / frame | " + " | ".join(f"CPU {r}" for r in ROLES)
            + " | cores busy |")
    lines = [head, "|" + "---:|" * (len(ROLES) + 4)]
    for r in rows:
        lines.append(f"| {r.threads} | {r.wall_ms:.2f} | {r.band_phase_ms:.2f} | "
                     + " | ".join(f"{r.cpu_ms[k]:.2f}" for k in ROLES) + f" | {r.cores_busy:.2f} |")
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--video", type=Path, default=None, help="the clip (default: videos/test_small1.mp4)")
    ap.add_argument("--model", default=None, help="the main model (default: the bundled one)")
    ap.add_argument("--frames", type=int, default=750)
    ap.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--repeats", type=int, default=2)
    a = ap.parse_args(argv)
    video = a.video if a.video is not None else data_dir() / "videos" / "test_small1.mp4"
    config = PipelineConfig(model=a.model) if a.model else PipelineConfig()
    rows = [measure(video, config, t, a.frames) for _ in range(a.repeats) for t in a.threads]
    print(f"`{video}`, {rows[0].frames} frames, {os.cpu_count()} CPUs:\n")
    print(table(rows))


if __name__ == "__main__":
    main()
