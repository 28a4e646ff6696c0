"""fastdet's ``video --boxes`` pipeline against the teacher CNN (YOLOX-nano through onnxruntime,
the model of ``fastdet label``) on the same clip, side by side in one run, at 1 and 2 threads
(issue 31's speed goal: fastdet at least 3x the teacher's frame rate at 640 px).

Each measurement is a fresh process (``NUMBA_NUM_THREADS`` = the thread count; the teacher's
onnxruntime threads the same) that decodes the whole clip and runs its detector on every frame:
fastdet through :func:`fastdet.video.run.iter_video_detections` (what ``video --boxes`` runs,
kernels compiled and the models loaded before the clock starts), the teacher through
:class:`fastdet.teacher.TeacherDetector` (``--size``, default 640). Systems and thread counts take
turns, ``--repeats`` times; the table has the best fps of each and the ratio, and beside them
the decode-only rate of the same file (:class:`fastdet.io.reader.FrameReader` alone: the I/O
limit). The default clip is short (88 frames), so the start-up work of a run (the horizon read
from its first frames, the own-vehicle look) weighs on it; ``--minutes M`` times M minutes of
1280x720 footage instead (``benchmarks.bench_adapt.make_footage``: the Udacity clips forwards and
backwards, written once into a temporary folder, or kept in ``--keep``), the steady frame loop.

``--model M.npz`` runs fastdet with another main model (an adapted camera's: its boxes made the
way the model file records, the heat map's or its windows').

    python -m tools.studies.vs_teacher [--video V | --minutes M [--keep F.mp4]] [--size 640] [--repeats 3]
                                       [--model M.npz]
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
from pathlib import Path

from benchmarks.bench_adapt import make_footage
from fastdet.data import data_dir

_FASTDET = """
import sys, time
from fastdet._numba import ensure_compiled
from fastdet.config import PipelineConfig
from fastdet.video.detector import detector_kernels, make_detector
from fastdet.video.run import iter_video_detections
config = PipelineConfig(model=sys.argv[2] or None)
ensure_compiled(detector_kernels(make_detector(config)))
t0 = time.perf_counter(); n = 0
for _ in iter_video_detections(sys.argv[1], config, progress=False):
    n += 1
print(n / (time.perf_counter() - t0))
"""

_TEACHER = """
import sys, time
from fastdet.io.reader import FrameReader
from fastdet.teacher import TeacherDetector
det = TeacherDetector(sys.argv[2], size=int(sys.argv[3]), threads=int(sys.argv[4]))
t0 = time.perf_counter(); n = 0
with FrameReader(sys.argv[1], notify=lambda _: None) as reader:
    for i, (number, frame, _) in enumerate(reader):
        if i == 0:
            det.detect(frame); t0 = time.perf_counter()  # onnxruntime plans its first run
        det.detect(frame); n += 1
print(n / (time.perf_counter() - t0))
"""

_DECODE = """
import sys, time
from fastdet.io.reader import FrameReader
t0 = time.perf_counter(); n = 0
with FrameReader(sys.argv[1], notify=lambda _: None) as reader:
    for _ in reader:
        n += 1
print(n / (time.perf_counter() - t0))
"""


def _fps(code: str, args: list[str], threads: int) -> float:
    env = dict(os.environ, NUMBA_NUM_THREADS=str(threads), OMP_NUM_THREADS=str(threads))
    out = subprocess.run([sys.executable, "-c", code, *args], env=env, capture_output=True, text=True, check=True)
    return float(out.stdout.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--video", default=None, help="the clip (default: videos/test_small1.mp4)")
    ap.add_argument("--minutes", type=float, default=None,
                    help="time this many minutes of 1280x720 footage instead of --video")
    ap.add_argument("--keep", type=Path, default=None, help="with --minutes: the footage file (reused if there)")
    ap.add_argument("--teacher", default=str(data_dir() / "teachers" / "yolox_nano.onnx"))
    ap.add_argument("--size", type=int, default=640)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--model", default="",
                    help="fastdet's main model (default: the bundled one); a model `fastdet adapt` made makes its "
                         "boxes the way it records (heat map or windows)")
    args = ap.parse_args(argv)
    if args.minutes is not None and args.video is not None:
        ap.error("give --video or --minutes, not both")
    with tempfile.TemporaryDirectory() as tmp:
        video = args.video or str(data_dir() / "videos" / "test_small1.mp4")
        if args.minutes is not None:
            footage = args.keep or Path(tmp) / "footage.mp4"
            if not footage.exists():
                make_footage(footage, args.minutes)
            video = str(footage)
        best = _race(video, args.teacher, args.size, args.repeats, args.model)
    print(f"`{video}`, best of {args.repeats}:\n")
    print(f"| threads | fastdet `video --boxes` fps (ms / frame) | teacher {args.size} px fps (ms / frame) | ratio "
          f"| decode only fps (ms / frame) |")
    print("|---:|---:|---:|---:|---:|")
    for t in (1, 2):
        f, c, d = best["fastdet", t], best["teacher", t], best["decode", t]
        print(f"| {t} | {f:.1f} ({1000 / f:.1f}) | {c:.1f} ({1000 / c:.1f}) | {f / c:.2f}x "
              f"| {d:.1f} ({1000 / d:.1f}) |")
    return 0


def _race(video: str, teacher: str, size: int, repeats: int, model: str = "") -> dict[tuple[str, int], float]:
    """Best fps of each system at 1 and 2 threads, systems and thread counts taking turns
    (``model``: fastdet's main model file, ``""`` the bundled one)."""
    best: dict[tuple[str, int], float] = {}
    for _ in range(repeats):
        for threads in (1, 2):
            for name, code, extra in (("fastdet", _FASTDET, [model]),
                                      ("teacher", _TEACHER, [teacher, str(size), str(threads)]),
                                      ("decode", _DECODE, [])):
                fps = _fps(code, [video, *extra], threads)
                best[name, threads] = max(best.get((name, threads), 0.0), fps)
    return best


if __name__ == "__main__":
    sys.exit(main())
