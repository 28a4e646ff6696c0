"""Print the detector, video and start-up benchmarks as markdown tables (docs/benchmarks.md).

    python -m tools.studies.bench_report [--quick] [--oncoming W.npz]
        [--only detector|opencv|wait-policy|video|start-up ...]

All figures are measured in this one run (setups as in ``benchmarks/bench_detector.py`` and
``benchmarks/bench_video.py``):

(a) detector: ms per 1280x720 frame of the classic per-window pipeline
    (``tests.reference.ClassicDetector``, test1.jpg) and of fastdet's ``Detector.detect``
    (cycling through test_images/*.jpg) at 1 and 2 Numba threads, with the main model only
    (the same model and bands as the classic one) and as ``Detector()`` builds it by default
    (the same: the oncoming-traffic model runs in VideoDetector), and with ``--oncoming W.npz`` also with that
    oncoming-traffic model beside the main one; speed-up = classic best / fastdet best.
    The fastdet configurations are timed in interleaved rounds, so a burst of load from
    another program hits all of them alike.
(a'') opencv: ``Detector(oncoming=None).detect`` (and at an 8-px window stride) side by side with
    OpenCV's ``HOGDescriptor.detectMultiScale`` at 8 and 16 px on the same 7 bands
    (``benchmarks/bench_opencv.py``), interleaved, 1 and 2 threads.
(a') wait policy: ``python -m fastdet bench`` at 2 threads in fresh processes with
    ``OMP_WAIT_POLICY=PASSIVE`` (fastdet's default for ``video`` and ``bench``) and ``ACTIVE``
    (spinning idle OpenMP workers: faster on an idle machine, far slower on a busy one).
(b) video: fps of ``python -m fastdet video`` (its summary line) per clip, 1 and 2 threads,
    boxes only and writing the annotated video; each case is a fresh process.
(c) start-up: a fresh process importing fastdet, building ``Detector()`` and calling
    ``detect`` twice, with an empty ``NUMBA_CACHE_DIR`` (cold: compiles) and with the
    folder that run filled (warm: loads from disk).

"best" is the fastest of the repeats (the least disturbed by other programs), "median" the
typical one; a wide gap between them means the machine was busy. ``--quick``: fewer repeats.
"""
from __future__ import annotations

import argparse
import os
import platform
import shlex
import statistics
import sys

os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")  # as `python -m fastdet video`; before Numba starts OpenMP

import cv2  # noqa: E402
import numba  # noqa: E402

from benchmarks.bench_detector import (  # noqa: E402
    CLASSIC_FRAME,
    load_frames,
    make_fastdet,
    models_label,
    same_windows,
    start_up_times,
    time_classic,
    time_detectors,
    wait_policy_times,
)
from benchmarks.bench_opencv import CASES, summary, time_side_by_side  # noqa: E402
from benchmarks.bench_video import CLIPS, IO_LABELS, IO_MODES, MODE_LABELS, MODES, command_line, video_runs  # noqa: E402
from fastdet.data import data_dir  # noqa: E402

SECTIONS = ("detector", "opencv", "wait-policy", "video", "start-up")
NOISY = 1.25  # median / best above this: flagged as noisy


def this_command(args: argparse.Namespace, section: str) -> str:
    cmd = ["python", "-m", "tools.studies.bench_report", "--only", section]
    if args.quick:
        cmd.append("--quick")
    if args.oncoming and section == "detector":
        cmd += ["--oncoming", str(args.oncoming)]
    return shlex.join(cmd)


def _flag(best: float, med: float) -> str:
    return " (noisy)" if med > NOISY * best else ""


# --------------------------------------------------------------------------------------
# (a) detector
# --------------------------------------------------------------------------------------
def detector_section(args: argparse.Namespace, thread_counts: list[int]) -> None:
    frames = load_frames()
    calls, rounds = (30, 3) if args.quick else (120, 6)
    classic_rounds = 1 if args.quick else 2

    kinds = ("main", "default", "oncoming") if args.oncoming else ("main", "default")
    dets = {kind: make_fastdet(kind, args.oncoming) for kind in kinds}
    configs = [(kind, n) for kind in dets for n in thread_counts]
    times, stages = time_detectors(dets, frames, thread_counts, calls, rounds)
    frame = frames[CLASSIC_FRAME]
    ctimes, cres = time_classic(frame, classic_rounds)
    agree = same_windows(cres, dets["main"].detect(frame))
    c_best, c_med = 1e3 * min(ctimes), 1e3 * statistics.median(ctimes)

    print(f"### Detector: ms per 1280x720 frame\n\n`{this_command(args, 'detector')}`  \n"
          "(pytest-benchmark: `python -m pytest benchmarks/bench_detector.py --benchmark-only "
          "-k 'classic or fastdet'`)\n")
    print("| pipeline | models | threads | best ms | median ms | resize/colour ms | HOG ms | scoring ms "
          "| speed-up vs classic |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|")
    print(f"| classic (skimage HOG per band, per-window features + sklearn), {CLASSIC_FRAME} | main | 1 "
          f"| {c_best:,.0f} | {c_med:,.0f} | | | | 1x |")
    best2 = {}
    for kind, n in configs:
        ts = times[(kind, n)]
        best, med = 1e3 * min(ts), 1e3 * statistics.median(ts)
        st = {k: 1e3 * statistics.median(v) for k, v in stages[(kind, n)].items()}
        if n == max(thread_counts):
            best2[kind] = best
        name = {"main": "fastdet `Detector(oncoming=None)`", "default": "fastdet `Detector()` (default)",
                "oncoming": f"fastdet `Detector(oncoming={os.path.basename(str(args.oncoming))!r})`"}[kind]
        print(f"| {name} | {models_label(dets[kind])} | {n} | {best:.2f} | {med:.2f}{_flag(best, med)} "
              f"| {st.get('resize_colour', 0):.2f} | {st.get('hog', 0):.2f} | {st.get('score', 0):.2f} "
              f"| {c_best / best:,.0f}x |")
    n_frames = len(frames)
    print(f"\nfastdet: {calls} calls per row over {rounds} interleaved rounds, cycling through the "
          f"{n_frames} test images; stage columns are medians, and at 2 threads they add up the work of both "
          f"band threads (so they exceed the wall time). Classic: {classic_rounds} run(s) on "
          f"{CLASSIC_FRAME}. Same positive windows from classic and fastdet (main): "
          f"{'yes' if agree else 'NO'}.")
    if dets["default"].oncoming_model is None:
        print("`Detector()` is `Detector(oncoming=None)`: the oncoming-traffic model runs in `VideoDetector` "
              "(what `video` runs), where motion narrows its search; its cost is in the video table.")
    if args.oncoming:
        n_wide = len(dets["oncoming"].geometries(frames[CLASSIC_FRAME].shape[:2], part=1))
        print(f"Oncoming model {args.oncoming}: {n_wide} more bands (`fastdet.config.ONCOMING_SEARCH`).")
    nt = max(thread_counts)
    b = best2["default"]
    print(f"Goal (>= 100x classic, < 10 ms per frame at 2 threads): default detector {b:.2f} ms at "
          f"{nt} thread(s), {c_best / b:,.0f}x: {'met' if b < 10 and c_best / b >= 100 else 'NOT met'}.\n")


# --------------------------------------------------------------------------------------
# (a'') side by side with OpenCV's HOG detector
# --------------------------------------------------------------------------------------
def opencv_section(args: argparse.Namespace, thread_counts: list[int]) -> None:
    frames = load_frames()
    calls, rounds = (30, 3) if args.quick else (120, 8)
    times, windows = time_side_by_side(frames, thread_counts, calls, rounds)
    res = summary(times)
    print(f"### Detector vs OpenCV's HOG detector: ms per 1280x720 frame, the same 7 bands\n\n"
          f"`{this_command(args, 'opencv')}`  \n"
          "(pytest-benchmark: `python -m pytest benchmarks/bench_opencv.py --benchmark-only`)\n")
    print("| detector | window stride | windows / frame | threads | best ms | median ms | CPU ms (median) "
          "| OpenCV stride 8 / this (best) | OpenCV stride 8 / this (median) |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for label, kind, stride in CASES:
        for n in thread_counts:
            best, med, cpu = res[(label, n)]
            ref_best, ref_med, _ = res[("OpenCV stride 8", n)]
            name = {"fastdet": "fastdet `Detector(oncoming=None)` (default search)",
                    "fastdet stride 8": "fastdet, `SearchConfig(cells_per_step=1)`"
                    }.get(label, "OpenCV `detectMultiScale`")
            print(f"| {name} | {stride} px | {windows[label]:,} | {n} | {best:.2f} | {med:.2f}{_flag(best, med)} "
                  f"| {cpu:.2f} | {ref_best / best:.2f}x | {ref_med / med:.2f}x |")
    print(f"\n{calls} calls per row over {rounds} interleaved rounds, cycling through the {len(frames)} test "
          "images. CPU ms: process CPU time per call (both threads at 2 threads). fastdet: 3-channel HOG "
          "with 16 orientations + spatial bins + colour histograms, 12,576 weights a window; OpenCV: "
          "HOG of the strongest channel, 9 orientations, 1,764 weights a window; both include cutting and "
          "resizing the bands.")
    nt = max(thread_counts)
    ratio = res[("OpenCV stride 8", nt)][0] / res[("fastdet", nt)][0]
    print(f"Goal (`Detector.detect` >= 2x faster than OpenCV at stride 8, {nt} threads): {ratio:.2f}x: "
          f"{'met' if ratio >= 2 else 'NOT met'}.\n")


# --------------------------------------------------------------------------------------
# (a') OpenMP wait policy
# --------------------------------------------------------------------------------------
def wait_policy_section(args: argparse.Namespace, thread_counts: list[int]) -> None:
    nt = max(thread_counts)
    repeat = 1 if args.quick else 3
    bench_args = ["--threads", str(nt), "--frames", "30", "--repeat", "5"]
    res = wait_policy_times(bench_args, repeat)
    print(f"### OpenMP wait policy, {nt} threads, ms per frame (detect + heat map)\n\n"
          f"`{this_command(args, 'wait-policy')}`  \n"
          f"each row: `OMP_WAIT_POLICY=P python -m fastdet bench {shlex.join(bench_args)}`, "
          f"{repeat} fresh process(es), interleaved\n")
    print("| OMP_WAIT_POLICY | best ms | median ms |")
    print("|---|---:|---:|")
    for policy, runs in res.items():
        best, med = min(b for b, _ in runs), statistics.median(m for _, m in runs)
        print(f"| {policy}{' (fastdet default)' if policy == 'PASSIVE' else ''} | {best:.2f} "
              f"| {med:.2f}{_flag(best, med)} |")
    print("\nACTIVE keeps idle OpenMP workers spinning: no wake-up latency at the many small parallel "
          "regions of a frame when both cores are free, but a spinning worker takes the core its "
          "partner (or the video reader / writer thread, or another program) needs.\n")


# --------------------------------------------------------------------------------------
# (b) video
# --------------------------------------------------------------------------------------
def video_section(args: argparse.Namespace, thread_counts: list[int]) -> None:
    data = data_dir()
    repeat = 1 if args.quick else 3
    results = video_runs(data, thread_counts, repeat)
    clips = [c for c in CLIPS if any(k[0] == c for k in results)]

    print(f"### Video: `python -m fastdet video` frames per second\n\n`{this_command(args, 'video')}`  \n"
          f"each cell: `{command_line('CLIP', 'boxes')}` (or `-o /tmp/out.mp4` instead of `--boxes`, "
          "or with `--no-oncoming` or `--full-search`); "
          "fps from its summary line, best of "
          f"{repeat} (median in brackets)\n")
    head = " | ".join(f"fps, {n} thread{'s' if n > 1 else ''}" for n in thread_counts)
    nt = max(thread_counts)
    print(f"| clip | frames | output | {head} | I/O limit fps | {nt}T / I/O limit (best) "
          f"| HOG ms ({nt}T) | scoring ms ({nt}T) | encode ms ({nt}T) |")
    print("|---|---:|---|" + "---:|" * len(thread_counts) + "---:|---:|---:|---:|---:|")
    for clip in clips:
        io = {m: [r["fps"] for r in results[(clip, m, 0)]] for m in IO_MODES}
        for mode in IO_MODES:
            best, med = max(io[mode]), statistics.median(io[mode])
            print(f"| {clip} | {results[(clip, mode, 0)][0]['frames']} | {IO_LABELS[mode]} "
                  + "| " * len(thread_counts) + f"| {best:.1f} ({med:.1f}) | 1x | | | |")
        for mode in MODES:
            cells = []
            for n in thread_counts:
                fps = [r["fps"] for r in results[(clip, mode, n)]]
                best, med = max(fps), statistics.median(fps)
                cells.append(f"{best:.1f} ({med:.1f}){_flag(1 / best, 1 / med)}")
            top = max(results[(clip, mode, nt)], key=lambda r: r["fps"])
            st = top["stages_ms"]
            enc = f"{st['encode']:.2f}" if "encode" in st else ""
            limit = max(io["encode" if mode == "video" else "decode"])
            print(f"| {clip} | {top['frames']} | {MODE_LABELS[mode]} | {' | '.join(cells)} "
                  f"| {limit:.1f} | {top['fps'] / limit:.2f}x "
                  f"| {st.get('HOG', 0):.2f} | {st.get('scoring', 0):.2f} | {enc} |")
    print("\nDecoding (reader thread) and drawing + encoding (writer thread) overlap with detection; "
          "stage columns are from `--profile` of the best run. I/O limit: a fresh process that only "
          "decodes the clip with OpenCV (for the `--boxes` rows), or decodes and writes it again with "
          "the `mp4v` writer (for `-o`), best of the runs (median in brackets), interleaved with the "
          "others.\n")


# --------------------------------------------------------------------------------------
# (c) start-up
# --------------------------------------------------------------------------------------
def start_up_section(args: argparse.Namespace, thread_counts: list[int]) -> None:
    repeat = 1 if args.quick else 2
    nt = max(thread_counts)
    runs = [start_up_times(n_threads=nt) for _ in range(repeat)]
    best = {k: min(r[k] for r in runs) for k in runs[0] if isinstance(runs[0][k], float)}
    print(f"### Start-up: fresh process, `Detector().detect` on {CLASSIC_FRAME}\n\n"
          f"`{this_command(args, 'start-up')}`  \n"
          "(pytest-benchmark: `python -m pytest benchmarks/bench_detector.py --benchmark-only -k start_up -s`; "
          f"by hand: `D=$(mktemp -d); for i in 1 2; do NUMBA_CACHE_DIR=$D NUMBA_NUM_THREADS={nt} python -m fastdet "
          "bench --frames 1 --repeat 1 | grep warm-up; done`)\n")
    print("| Numba cache | whole process s | import s | Detector() s | first detect s | second detect ms |")
    print("|---|---:|---:|---:|---:|---:|")
    for kind, label in (("cold", "empty (compiles)"), ("warm", "filled (loads)")):
        print(f"| {label} | {best[f'{kind}_process_s']:.2f} | {best[f'{kind}_import_s']:.2f} "
              f"| {best[f'{kind}_construct_s']:.3f} | {best[f'{kind}_first_detect_s']:.2f} "
              f"| {1e3 * best[f'{kind}_second_detect_s']:.1f} |")
    print(f"\n{nt} Numba thread(s), models: {runs[0]['cold_models']}; best of {repeat} cold/warm pair(s).\n")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer repeats (a rough picture in about a minute)")
    ap.add_argument("--only", nargs="+", choices=SECTIONS, default=list(SECTIONS), metavar="SECTION",
                    help=f"tables to print: {', '.join(SECTIONS)} (default: all)")
    ap.add_argument("--oncoming", metavar="ONCOMING.npz",
                    help="detector table: also time Detector(oncoming=ONCOMING.npz), an oncoming-traffic "
                         "model beside the main one")
    args = ap.parse_args(argv)
    if args.oncoming and not os.path.exists(args.oncoming):
        ap.error(f"--oncoming {args.oncoming}: file not found")

    thread_counts = [n for n in (1, 2) if n <= numba.config.NUMBA_NUM_THREADS]
    load0 = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    for section in SECTIONS:
        if section in args.only:
            {"detector": detector_section, "opencv": opencv_section, "wait-policy": wait_policy_section,
             "video": video_section,
             "start-up": start_up_section}[section](
                args, thread_counts)
            sys.stdout.flush()
    load1 = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    try:
        layer = numba.threading_layer()
    except ValueError:
        layer = "no"  # nothing parallel ran in this process
    print(f"{platform.processor() or platform.machine()}, {os.cpu_count()} CPUs, Python "
          f"{platform.python_version()}, numba {numba.__version__} ({layer} threading layer, "
          f"OMP_WAIT_POLICY={os.environ.get('OMP_WAIT_POLICY')}), OpenCV {cv2.__version__}; "
          f"1-min load average {load0:.2f} before, {load1:.2f} after")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
