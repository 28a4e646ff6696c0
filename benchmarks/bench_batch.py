"""Throughput of ``python -m fastdet batch`` against a shell loop of ``python -m fastdet video``.

Run (a few minutes; not part of the test run)::

    python -m pytest benchmarks/bench_batch.py --benchmark-only -s

The job: :data:`N_CLIPS` clips of :data:`N_FRAMES` frames at 1280x720, cut in a temporary
folder from the annotated clips (``test_small1.mp4`` followed by ``test_video.mp4``, each clip
starting 1 frame after the previous one), boxes only. Three cases, each timed once as a
whole process (the benchmark time) with its frames per second in ``extra_info``:

- ``loop``: ``for f in DIR/*.mp4; do python -m fastdet video "$f" --boxes OUT/NAME.txt
  --no-progress; done`` -- what a user writes without ``batch``: every clip pays the
  interpreter, the imports and loading the cached kernels, and each run uses the cores as
  ``video`` does (2 Numba threads, reader and writer threads).
- ``batch-2``: ``python -m fastdet batch DIR --out OUT --no-progress`` -- the default local
  cluster (one worker process per core: 2 here, one Numba thread each).
- ``batch-1``: the same with ``--workers 1``: the scaling from 1 to 2 workers, and the
  single-thread frame rate of one worker (``frames/s (task)`` of its summary: frames over
  the summed task times).

The table printed at the end gives the job's frames per second (all frames over the wall
time of the whole command, start-up included), the speed-up over the loop, the CPU time of
the command and all its processes (``getrusage`` of the children: what the job costs
whatever else runs on the machine), the 1-minute load average before it, and the 2-worker
job against the sum of the per-worker single-thread rates (2 x the task rate of
``batch-1``). A first short ``video`` run fills the Numba cache, so no case compiles.
"""
from __future__ import annotations

import os
import re
import resource
import shlex
import subprocess
import sys
import time
from pathlib import Path

import cv2
import pytest

pytest.importorskip("distributed")

N_CLIPS = 16
N_FRAMES = 100
STEP = 1  # clip k starts STEP * k frames into the source sequence
SOURCES = ("test_small1.mp4", "test_video.mp4")
_DONE = re.compile(r"^done\s+(\d+)\s+(\d+)\s+([\d.]+)\s+([\d.]+)", re.MULTILINE)
_RESULTS: dict[str, dict] = {}


def _frames(data: Path, n: int):
    """The first ``n`` frames of the source clips played one after the other."""
    k = 0
    for name in SOURCES:
        cap = cv2.VideoCapture(str(data / "videos" / name))
        while k < n:
            ok, frame = cap.read()
            if not ok:
                break
            yield frame
            k += 1
        cap.release()


def make_clips(data: Path, dst: Path, n_clips: int = N_CLIPS, n_frames: int = N_FRAMES) -> list[Path]:
    """``n_clips`` mp4v clips of ``n_frames`` frames in ``dst``."""
    frames = list(_frames(data, STEP * (n_clips - 1) + n_frames))
    assert len(frames) >= STEP * (n_clips - 1) + n_frames, "the source clips are too short"
    h, w = frames[0].shape[:2]
    paths = []
    for k in range(n_clips):
        p = dst / f"clip{k:02d}.mp4"
        out = cv2.VideoWriter(str(p), cv2.VideoWriter_fourcc(*"mp4v"), 25, (w, h))
        assert out.isOpened()
        for f in frames[STEP * k: STEP * k + n_frames]:
            out.write(f)
        out.release()
        paths.append(p)
    return paths


@pytest.fixture(scope="module")
def clips(data: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("batch_clips")
    paths = make_clips(data, d)
    # fill the Numba cache (not timed)
    subprocess.run([sys.executable, "-m", "fastdet", "video", str(paths[0]), "--boxes", str(d.parent / "warm.txt"),
                    "--no-progress", "--frames", "3"], check=True, capture_output=True, timeout=900)
    yield d
    _print_table()


def _cpu_s() -> float:
    """User + system CPU seconds of every finished child process (and theirs) so far."""
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def _timed(cmd: list[str] | str, shell: bool = False) -> tuple[float, float, float, subprocess.CompletedProcess]:
    """Run ``cmd``: ``(wall s, CPU s of it and its children, 1-min load average before, result)``."""
    load = os.getloadavg()[0]
    c0, t0 = _cpu_s(), time.perf_counter()
    r = subprocess.run(cmd, shell=shell, capture_output=True, text=True, timeout=3600,
                       executable="/bin/bash" if shell else None)
    wall, cpu = time.perf_counter() - t0, _cpu_s() - c0
    assert r.returncode == 0, r.stderr[-2000:]
    return wall, cpu, load, r


def test_loop_of_video(benchmark, clips: Path, tmp_path: Path) -> None:
    out = tmp_path / "loop"
    out.mkdir()
    py = shlex.quote(sys.executable)
    cmd = (f'for f in {shlex.quote(str(clips))}/*.mp4; do {py} -m fastdet video "$f" '
           f'--boxes {shlex.quote(str(out))}/"$(basename "$f" .mp4)".txt --no-progress || exit 1; done')
    wall, cpu, load, _ = benchmark.pedantic(_timed, args=(cmd, True), rounds=1, iterations=1)
    assert len(list(out.glob("*.txt"))) == N_CLIPS
    _record(benchmark, "loop", wall, cpu, load)


@pytest.mark.parametrize("workers", [2, 1])
def test_batch_local_cluster(benchmark, clips: Path, tmp_path: Path, workers: int) -> None:
    out = tmp_path / f"batch{workers}"
    cmd = [sys.executable, "-m", "fastdet", "batch", str(clips), "--out", str(out), "--no-progress"]
    if workers != 2:
        cmd += ["--workers", str(workers)]
    wall, cpu, load, r = benchmark.pedantic(_timed, args=(cmd,), rounds=1, iterations=1)
    m = _DONE.search(r.stdout)
    assert m and int(m[1]) == N_CLIPS and int(m[2]) == N_CLIPS * N_FRAMES, r.stdout
    _record(benchmark, f"batch-{workers}", wall, cpu, load, task_fps=float(m[4]))


def _record(benchmark, key: str, wall: float, cpu: float, load: float, **more: float) -> None:
    fps = N_CLIPS * N_FRAMES / wall
    res = {"wall": wall, "fps": fps, "cpu": cpu, "cpu_ms": 1e3 * cpu / (N_CLIPS * N_FRAMES), "load": load, **more}
    benchmark.extra_info.update({k: round(v, 2) for k, v in res.items()})
    _RESULTS[key] = res


def _print_table() -> None:
    if not _RESULTS:
        return
    loop = _RESULTS.get("loop")
    one = _RESULTS.get("batch-1")
    lines = [f"\n{N_CLIPS} clips x {N_FRAMES} frames (1280x720), boxes only, {os.cpu_count()} CPUs",
             ("| command | wall s | frames/s (job) | speed-up vs loop | CPU s (all processes) | CPU ms / frame "
              "| frames/s per task | load before |"),
             "|---|---:|---:|---:|---:|---:|---:|---:|"]
    labels = {"loop": "shell loop of `fastdet video`", "batch-2": "`fastdet batch` (local cluster, 2 workers)",
              "batch-1": "`fastdet batch --workers 1`"}
    for key in ("loop", "batch-2", "batch-1"):
        r = _RESULTS.get(key)
        if r is None:
            continue
        up = f"{r['fps'] / loop['fps']:.2f}x" if loop else ""
        task = f"{r['task_fps']:.1f}" if "task_fps" in r else ""
        lines.append(f"| {labels[key]} | {r['wall']:.1f} | {r['fps']:.1f} | {up} | {r['cpu']:.1f} | "
                     f"{r['cpu_ms']:.1f} | {task} | {r['load']:.2f} |")
    two = _RESULTS.get("batch-2")
    if one and two:
        lines.append(f"\n1 -> 2 workers: {two['fps'] / one['fps']:.2f}x; the 2-worker job runs at "
                     f"{two['fps'] / (2 * one['task_fps']):.0%} of 2 x the single-thread task rate "
                     f"({2 * one['task_fps']:.1f} frames/s), start-up included")
    print("\n".join(lines), flush=True)
