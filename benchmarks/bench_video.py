"""End-to-end throughput of ``python -m fastdet video`` on the two test clips.

Run::

    python -m pytest benchmarks/bench_video.py --benchmark-only
    python -m tools.studies.bench_report --only video    # the same figures as a markdown table

Each case runs the CLI in a fresh process with ``NUMBA_NUM_THREADS`` = 1 or 2, on
``videos/test_video.mp4`` (38 frames) or ``videos/test_small1.mp4`` (88 frames), both
1280x720, writing either only the boxes (``--boxes B.txt``) or the annotated video
(``-o OUT.mp4``), with ``--no-progress --profile``; the boxes-only case also with
``--no-oncoming`` (the main model alone), to show what the oncoming-traffic model costs, and
with ``--full-search`` (every window of every band on every frame instead of the
tracking-guided search). Beside them, the I/O limit of the same clip: a fresh process that
only decodes it with OpenCV (``decode``), and one that decodes and writes it again with
OpenCV's ``mp4v`` writer (``decode + encode``, fastdet's output codec), fps over the same
loop (:func:`run_io`). The figure that matters is the fps
of the CLI's summary line (``fastdet video: N frames in S s, F fps``: frames over the wall
time of the frame loop, after the kernels are loaded), in ``extra_info["fps"]`` with the
per-stage ms of ``--profile`` in ``extra_info["stages_ms"]``; the benchmark time itself is
the whole process (interpreter start, imports, loading the cached kernels included).
Decoding and drawing + encoding run in their own threads beside detection, so on 2 cores
the wall time per frame is less than the sum of the stages. A first short run fills the
Numba cache, so no case pays for compilation.
"""
from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
CLIPS = ("test_video.mp4", "test_small1.mp4")
MODES = ("boxes", "boxes-full", "boxes-main", "video")
MODE_LABELS = {"boxes": "--boxes only", "boxes-full": "--boxes only, --full-search",
               "boxes-main": "--boxes only, main model alone (--no-oncoming)",
               "video": "annotated video (-o)"}
IO_MODES = ("decode", "encode")
IO_LABELS = {"decode": "decode only (OpenCV)", "encode": "decode + mp4v encode (OpenCV)"}
_SUMMARY = re.compile(r"^fastdet video: (\d+) frames in ([\d.]+) s, ([\d.]+) fps", re.M)
_STAGE = re.compile(r"^(\S[^\n]*?)\s{2,}([\d.]+)\s{2}(reader|main|writer|\d+ band threads)\b", re.M)


# --------------------------------------------------------------------------------------
# helpers (also used by tools/studies/bench_report.py)
# --------------------------------------------------------------------------------------
def video_args(clip: Path, mode: str, out_dir: Path, frames: int | None = None) -> list[str]:
    """Arguments after ``python -m fastdet``."""
    args = ["video", str(clip)]
    args += ["-o", str(out_dir / "out.mp4")] if mode == "video" else ["--boxes", str(out_dir / "boxes.txt")]
    args += ["--no-progress", "--profile"] + (["--no-oncoming"] if mode == "boxes-main" else [])
    args += ["--full-search"] if mode == "boxes-full" else []
    if frames is not None:
        args += ["--frames", str(frames)]
    return args


def command_line(clip: str, mode: str, n_threads: int | str = "T") -> str:
    """The shell command of one case, for a report (clip relative to the data folder)."""
    out = "/tmp/out.mp4" if mode == "video" else "/tmp/boxes.txt"
    flag = "-o" if mode == "video" else "--boxes"
    return (f"NUMBA_NUM_THREADS={n_threads} python -m fastdet video $FASTDET_DATA/videos/{clip} "
            f"{flag} {out} --no-progress --profile" + (" --no-oncoming" if mode == "boxes-main" else "")
            + (" --full-search" if mode == "boxes-full" else ""))


_IO_SCRIPT = """
import sys, time, cv2
cap = cv2.VideoCapture(sys.argv[1])
out, writer, n = sys.argv[2], None, 0
t0 = time.perf_counter()
while True:
    ok, frame = cap.read()
    if not ok:
        break
    if out != "-":
        if writer is None:
            fps = cap.get(cv2.CAP_PROP_FPS) or 25.0
            writer = cv2.VideoWriter(out, cv2.VideoWriter_fourcc(*"mp4v"), fps, (frame.shape[1], frame.shape[0]))
        writer.write(frame)
    n += 1
if writer is not None:
    writer.release()
dt = time.perf_counter() - t0
print(n, dt, n / dt)
"""


def run_io(clip: Path, mode: str, out_dir: Path) -> dict:
    """The I/O limit of ``clip`` in a fresh process: ``mode`` ``'decode'`` (OpenCV decodes
    every frame) or ``'encode'`` (and writes it with the ``mp4v`` writer, as ``video -o``):
    ``{'frames', 'seconds', 'fps'}``."""
    out = str(out_dir / "io.mp4") if mode == "encode" else "-"
    proc = subprocess.run([sys.executable, "-c", _IO_SCRIPT, str(clip), out], capture_output=True, text=True,
                          check=True)
    n, dt, fps = proc.stdout.split()
    return {"frames": int(n), "seconds": float(dt), "fps": float(fps)}


def parse_output(stdout: str) -> dict:
    """``{'frames', 'seconds', 'fps', 'stages_ms': {label: ms per frame}}`` from the CLI's output."""
    m = _SUMMARY.search(stdout)
    if m is None:
        raise RuntimeError(f"no summary line in the output of fastdet video:\n{stdout}")
    stages = {label.strip(): float(ms) for label, ms, _ in _STAGE.findall(stdout)}
    return {"frames": int(m.group(1)), "seconds": float(m.group(2)), "fps": float(m.group(3)),
            "stages_ms": stages}


def run_video(clip: Path, mode: str, n_threads: int, out_dir: Path, frames: int | None = None) -> dict:
    """Run the CLI once in a fresh process; :func:`parse_output` plus ``process_s`` (the
    whole process) and ``threads``."""
    env = dict(os.environ, NUMBA_NUM_THREADS=str(n_threads))
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(REPO), env.get("PYTHONPATH")]))
    argv = [sys.executable, "-m", "fastdet", *video_args(clip, mode, out_dir, frames)]
    t0 = time.perf_counter()
    proc = subprocess.run(argv, env=env, capture_output=True, text=True, cwd=REPO)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise RuntimeError(f"{shlex.join(argv)} failed ({proc.returncode}):\n{proc.stderr}")
    result = parse_output(proc.stdout)
    result.update(process_s=wall, threads=n_threads)
    return result


def warm_cache(clip: Path, out_dir: Path) -> None:
    """A 2-frame run of each mode so the Numba cache is filled before anything is timed."""
    for mode in MODES:
        run_video(clip, mode, 2, out_dir, frames=2)


def video_runs(data: Path, thread_counts: list[int], repeat: int) -> dict[tuple[str, str, int], list[dict]]:
    """Every case (clip of :data:`CLIPS` found in ``data/videos``, mode, thread count) run
    ``repeat`` times, interleaved, after :func:`warm_cache`: ``{(clip, mode, n): [run_video
    result, ...]}``; the I/O limits as ``(clip, 'decode' | 'encode', 0)`` (:func:`run_io`),
    interleaved with them."""
    clips = [c for c in CLIPS if (data / "videos" / c).exists()]
    results: dict[tuple[str, str, int], list[dict]] = {}
    with tempfile.TemporaryDirectory(prefix="fastdet-bench-") as tmp:
        warm_cache(data / "videos" / clips[0], Path(tmp))
        for _ in range(repeat):
            for clip in clips:
                for mode in IO_MODES:
                    results.setdefault((clip, mode, 0), []).append(run_io(data / "videos" / clip, mode, Path(tmp)))
                for mode in MODES:
                    for n in thread_counts:
                        results.setdefault((clip, mode, n), []).append(
                            run_video(data / "videos" / clip, mode, n, Path(tmp)))
    return results


# --------------------------------------------------------------------------------------
# benchmarks
# --------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def warmed(data, tmp_path_factory):
    warm_cache(data / "videos" / CLIPS[0], tmp_path_factory.mktemp("warm"))
    return data


@pytest.mark.parametrize("mode", IO_MODES)
@pytest.mark.parametrize("clip", CLIPS)
def test_io_limit(benchmark, data, tmp_path, clip, mode):
    path = data / "videos" / clip
    if not path.exists():
        pytest.skip(f"{path} not found")
    benchmark.group = f"python -m fastdet video {clip} (whole process)"
    result = benchmark.pedantic(run_io, args=(path, mode, tmp_path), rounds=3, iterations=1)
    benchmark.extra_info.update(clip=clip, mode=IO_LABELS[mode], fps=result["fps"], frames=result["frames"])


@pytest.mark.parametrize("mode", MODES)
@pytest.mark.parametrize("n_threads", [1, 2])
@pytest.mark.parametrize("clip", CLIPS)
def test_video_cli(benchmark, warmed, tmp_path, clip, n_threads, mode):
    path = warmed / "videos" / clip
    if not path.exists():
        pytest.skip(f"{path} not found")
    benchmark.group = f"python -m fastdet video {clip} (whole process)"
    result = benchmark.pedantic(run_video, args=(path, mode, n_threads, tmp_path), rounds=1, iterations=1)
    benchmark.extra_info.update(clip=clip, mode=MODE_LABELS[mode], threads=n_threads, fps=result["fps"],
                                frames=result["frames"], loop_s=result["seconds"],
                                process_s=round(result["process_s"], 3), stages_ms=result["stages_ms"],
                                command=command_line(clip, mode, n_threads))
    print(f"\n{clip} {MODE_LABELS[mode]} {n_threads} thread(s): {result['fps']:.1f} fps "
          f"({result['frames']} frames, process {result['process_s']:.2f} s)")
    assert result["frames"] >= 30
    if mode == "video":
        assert (tmp_path / "out.mp4").stat().st_size > 0
