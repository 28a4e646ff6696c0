"""Print the HOG benchmark as a markdown table (the figures in docs/benchmarks.md).

    python -m tools.studies.bench_hog_report [--repeat 30] [--no-start-up]     (from the project root)

Times the 1280x256 LUV search band of test_images/test1.jpg, 3 channels, 9 orientations,
8x8 cells, 2x2 blocks (see benchmarks/bench_hog.py for the exact setup): fastdet's
``hog_channels``, OpenCV's ``HOGDescriptor`` (one call per channel) and
``skimage.feature.hog`` (one call per channel), at 1 and 2 threads (Numba and OpenCV
threads; skimage is single-threaded), then the start-up of a fresh process with an empty
and with a filled Numba cache. Each figure is the median of ``--repeat`` timed runs
(skimage: 3), after a warm-up call.
"""
from __future__ import annotations

import argparse
import os
import platform

import cv2
import numba

from benchmarks.bench_hog import (
    load_roi,
    opencv_setup,
    run_fastdet,
    run_opencv,
    run_skimage,
    start_up_times,
    threads,
    time_ms,
)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=30, help="timed runs per figure")
    ap.add_argument("--no-start-up", action="store_true", help="skip the cold/warm start runs")
    args = ap.parse_args(argv)

    roi = load_roi()
    desc, planes = opencv_setup(roi)
    thread_counts = [n for n in (1, 2) if n <= numba.config.NUMBA_NUM_THREADS]
    try:
        import skimage  # noqa: F401
        have_skimage = True
    except ImportError:
        have_skimage = False

    rows = {}
    for n in thread_counts:
        with threads(n):
            rows[("fastdet.hog_channels", n)] = time_ms(run_fastdet, roi, repeat=args.repeat)
            rows[("cv2.HOGDescriptor x3", n)] = time_ms(run_opencv, desc, planes, repeat=args.repeat)
    if have_skimage:
        rows[("skimage.feature.hog x3", 1)] = time_ms(run_skimage, roi, repeat=3)
    sk = rows.get(("skimage.feature.hog x3", 1))

    print(f"HOG of the {roi.shape[1]}x{roi.shape[0]} LUV band of test1.jpg, 3 channels, "
          "9 orientations, 8x8 cells, 2x2 blocks; ms per call, median and minimum; "
          "speed-ups from the medians\n")
    print("| implementation | threads | ms / call (median) | ms (min) | speed-up vs skimage "
          "| speed-up vs OpenCV |")
    print("|---|---:|---:|---:|---:|---:|")
    for (name, n), (med, best) in rows.items():
        cv = rows.get(("cv2.HOGDescriptor x3", n))
        vs_sk = f"{sk[0] / med:.0f}x" if sk else "n/a"
        vs_cv = f"{cv[0] / med:.1f}x" if cv and not name.startswith("skimage") else ""
        print(f"| {name} | {n} | {med:.2f} | {best:.2f} | {vs_sk} | {vs_cv} |")

    if not args.no_start_up:
        start = start_up_times(roi, max(thread_counts))
        print("\nStart-up of a fresh process: import fastdet._hog; Numba's one-time set-up "
              "(first call of any cached kernel); first and second hog_channels on the band\n")
        print("| Numba cache | import s | Numba set-up s | first call s | second call ms |")
        print("|---|---:|---:|---:|---:|")
        for kind, label in (("cold", "empty (compiles)"), ("warm", "filled (loads)")):
            print(f"| {label} | {start[f'{kind}_import_s']:.2f} | {start[f'{kind}_numba_init_s']:.2f} "
                  f"| {start[f'{kind}_first_call_s']:.2f} | {start[f'{kind}_second_call_s'] * 1e3:.1f} |")

    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"\n{platform.processor() or platform.machine()}, {os.cpu_count()} CPUs, "
          f"numba {numba.__version__}, OpenCV {cv2.__version__}, load average {load:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
