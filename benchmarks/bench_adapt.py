"""``fastdet adapt`` on long footage: the seconds of each step (plan, label, train, operating
point) against the issue's budget -- 10 minutes of 1280x720 footage adapted in at most 10
minutes on 2 cores.

Run::

    python -m benchmarks.bench_adapt                    # 10 minutes of footage at 25 fps
    python -m benchmarks.bench_adapt --minutes 2 --keep /tmp/footage.mp4

Footage: the shared 1280x720 clips (``videos/test_video.mp4``, ``videos/test_small1.mp4``)
played forwards and backwards in turn until the footage is ``--minutes`` long (one mp4, written
once into ``--keep`` or a temporary folder; the writing is not timed). This is a **timing**
input only: the frames repeat one drive, so the model it makes says nothing about accuracy.
The command timed is the user's: ``python -m fastdet adapt FOOTAGE --teacher
teachers/yolox_nano.onnx -o M.npz`` at its defaults, in a subprocess; the seconds per step are
read from the model's metadata (``metadata["adapt"]["seconds"]``), the wall time and the peak
memory (``ru_maxrss`` of the child) around it.
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

#: the issue's budget: seconds to adapt on 10 minutes of footage
BUDGET_S = 600.0


def make_footage(out: Path, minutes: float, fps: float = 25.0) -> int:
    """Write ``minutes`` of 1280x720 footage at ``fps`` to ``out`` (mp4v); the frame count."""
    import cv2
    import numpy as np

    from fastdet.data import data_dir

    clips = []
    for name in ("test_video.mp4", "test_small1.mp4"):
        cap = cv2.VideoCapture(str(data_dir() / "videos" / name))
        frames = []
        while True:
            ok, f = cap.read()
            if not ok:
                break
            frames.append(f if f.shape[:2] == (720, 1280) else cv2.resize(f, (1280, 720)))
        cap.release()
        if not frames:
            raise SystemExit(f"bench_adapt: {name}: no frames")
        clips.append(frames)
    order = []
    for frames in clips:
        order += frames + frames[::-1]
    total = int(round(minutes * 60 * fps))
    tmp = out.with_name(out.stem + ".part" + out.suffix)
    writer = cv2.VideoWriter(str(tmp), cv2.VideoWriter_fourcc(*"mp4v"), fps, (1280, 720))
    if not writer.isOpened():
        raise SystemExit(f"bench_adapt: cannot write {tmp}")
    for i in range(total):
        writer.write(np.ascontiguousarray(order[i % len(order)]))
    writer.release()
    os.replace(tmp, out)
    return total


def run(footage: Path, model: Path, extra: list[str]) -> dict:
    """Time ``fastdet adapt`` on ``footage``; its per-step seconds, wall time, peak memory."""
    from fastdet.data import data_dir
    from fastdet.model import load_model

    teacher = data_dir() / "teachers" / "yolox_nano.onnx"
    cmd = [sys.executable, "-m", "fastdet", "adapt", str(footage), "--teacher", str(teacher), "-o", str(model),
           "--no-progress", *extra]
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise SystemExit(f"bench_adapt: adapt failed ({proc.returncode}): {proc.stderr.strip()[-2000:]}")
    meta = load_model(str(model)).metadata.get("adapt", {})
    rss = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024  # KiB -> MiB (Linux)
    return {"command": " ".join(cmd[1:]), "wall_s": round(wall, 1), "peak_mib": round(rss),
            "seconds": meta.get("seconds", {}), "frames": meta.get("frames", {})}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--minutes", type=float, default=10.0, help="footage length (default 10)")
    p.add_argument("--keep", type=Path, default=None, help="write (or reuse) the footage here")
    p.add_argument("--json", action="store_true", help="print the report as JSON")
    p.add_argument("adapt_args", nargs="*", help="more arguments for adapt (after --)")
    args = p.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="bench-adapt-") as tmp:
        footage = args.keep or Path(tmp) / "footage.mp4"
        n = None
        if not footage.exists():
            t = time.perf_counter()
            n = make_footage(footage, args.minutes)
            print(f"wrote {footage}: {n} frames ({time.perf_counter() - t:.0f} s, not timed)", file=sys.stderr)
        report = run(footage, Path(tmp) / "adapted.npz", args.adapt_args)
    report["footage_minutes"] = args.minutes
    report["threads"] = os.environ.get("NUMBA_NUM_THREADS", str(os.cpu_count()))
    report["budget_s_for_10_minutes"] = BUDGET_S
    if args.json:
        print(json.dumps(report, indent=2))
        return 0
    print(f"fastdet adapt on {args.minutes:g} min of 1280x720 footage: {report['wall_s']:.0f} s wall, peak memory "
          f"{report['peak_mib']} MiB (the budget: {BUDGET_S:.0f} s for 10 minutes of footage)")
    for k, v in report["seconds"].items():
        print(f"  {k:>16}: {v:8.1f} s")
    print(f"  frames: {json.dumps(report['frames'])}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
