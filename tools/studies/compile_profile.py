"""Where a cold first run's time goes: every Numba compilation of a ``fastdet`` command, per
kernel and per signature, with the phase it happened in (the announced warm-up or later).

Runs the command in this process with ``NUMBA_CACHE_DIR`` pointed at a fresh empty folder
(unless ``--cache DIR`` names one: then only what that cache lacks compiles), records Numba's
``numba:compile`` events (start / end, per thread) and prints one line per compiled
signature: inclusive seconds (the callees it compiled on the way included), exclusive
seconds, thread, phase. Then the totals per phase, and the command's wall and CPU time.

    python tools/studies/compile_profile.py -- video ../shared/data/videos/test_video.mp4 \\
        -o /tmp/o.mp4 --boxes /tmp/o.txt
    python tools/studies/compile_profile.py --json prof.json -- warmup

Run it from the checkout's root (so that ``fastdet`` is this checkout's).
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import sys
import tempfile
import threading
import time


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cache", help="Numba cache folder to use (default: a fresh empty one)")
    ap.add_argument("--json", help="also write the events to this JSON file")
    ap.add_argument("--top", type=int, default=0, help="print only the N longest signatures (0: all)")
    ap.add_argument("--parallel", action="store_true",
                    help="let the warm-up compile in worker processes (their compiles are not seen here)")
    ap.add_argument("command", nargs=argparse.REMAINDER, help="-- then a fastdet command line")
    args = ap.parse_args(argv)
    cmd = [a for a in args.command if a != "--"] if args.command[:1] == ["--"] else args.command
    if not cmd:
        ap.error("give a fastdet command after --")
    cache = args.cache or tempfile.mkdtemp(prefix="fastdet-cold-")
    os.environ["NUMBA_CACHE_DIR"] = cache
    if not args.parallel:
        os.environ["FASTDET_COMPILE_WORKERS"] = "1"
    if "numba" in sys.modules:
        ap.error("numba was imported before the cache folder was set")
    sys.path.insert(0, os.getcwd())

    from numba.core import event as ev

    t_wall0, t_cpu0 = time.perf_counter(), time.process_time()
    records: list[dict] = []
    stacks: dict[int, list] = {}
    lock = threading.Lock()
    marks: dict[str, float] = {}

    class Recorder(ev.Listener):
        def on_start(self, event):
            with lock:
                stacks.setdefault(threading.get_ident(), []).append((time.perf_counter(), event, [0.0, 0.0],
                                                                     time.thread_time()))

        def on_end(self, event):
            t, c = time.perf_counter(), time.thread_time()
            tid = threading.get_ident()
            with lock:
                t0, e, child, c0 = stacks[tid].pop()
                incl, cpu = t - t0, c - c0
                if stacks[tid]:
                    stacks[tid][-1][2][0] += incl
                    stacks[tid][-1][2][1] += cpu
                d = e.data
                disp = d["dispatcher"]
                name = f"{disp.py_func.__module__.rsplit('.', 1)[-1]}.{disp.py_func.__name__}"
                records.append(dict(kernel=name, sig=", ".join(str(a) for a in d["args"]), start=t0 - t_wall0,
                                    incl=incl, excl=incl - child[0], cpu=cpu, cpu_excl=cpu - child[1],
                                    depth=len(stacks[tid]),
                                    thread=threading.current_thread().name))

    # the phase boundary: the end of the announced warm-up
    import fastdet.video.pipeline as pipeline

    orig = pipeline.VideoDetector.warmup

    def warmup(self, *a, **k):
        try:
            return orig(self, *a, **k)
        finally:
            marks.setdefault("warmup_end", time.perf_counter() - t_wall0)

    pipeline.VideoDetector.warmup = warmup
    from fastdet.cli.main import main as fastdet_main

    with ev.install_listener("numba:compile", Recorder()):
        status = fastdet_main(cmd)
    wall, cpu = time.perf_counter() - t_wall0, time.process_time() - t_cpu0
    ru = resource.getrusage(resource.RUSAGE_SELF)
    end = marks.get("warmup_end", float("inf"))
    for r in records:
        r["phase"] = "warm-up" if r["start"] < end else "later"
    rows = sorted(records, key=lambda r: -r["incl"]) if args.top else records
    if args.top:
        rows = rows[:args.top]
    print(f"{'start s':>8} {'incl s':>7} {'excl s':>7} {'CPU s':>7}  {'phase':8} {'thread':14} kernel(signature)")
    for r in rows:
        print(f"{r['start']:8.2f} {r['incl']:7.2f} {r['excl']:7.2f} {r['cpu']:7.2f}  {r['phase']:8} "
              f"{r['thread'][:14]:14} {'  ' * r['depth']}{r['kernel']}({r['sig']})")
    per_kernel: dict[str, list] = {}
    for r in records:
        k = per_kernel.setdefault(r["kernel"], [0, 0.0, 0.0])
        k[0] += 1
        k[1] += r["excl"]
        k[2] += r["cpu_excl"]
    print("\nper kernel (exclusive wall seconds, exclusive CPU seconds, signatures):")
    for name, (n, s, c) in sorted(per_kernel.items(), key=lambda kv: -kv[1][2]):
        print(f"  {s:7.2f} s  {c:7.2f} s  {n:2d}  {name}")
    for phase in ("warm-up", "later"):
        top = [r for r in records if r["phase"] == phase and r["depth"] == 0]
        print(f"{phase}: {len([r for r in records if r['phase'] == phase])} signatures compiled in this process, "
              f"{sum(r['incl'] for r in top):.2f} s wall, {sum(r['cpu'] for r in top):.2f} s CPU")
    print(f"command: exit {status}, wall {wall:.2f} s, CPU {cpu:.2f} s (children "
          f"{ru.ru_utime + ru.ru_stime - cpu:.2f} s not counted), cache {cache}")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(dict(records=records, wall=wall, cpu=cpu, warmup_end=end if end != float("inf") else None,
                           command=cmd), fh, indent=1)
    return status


if __name__ == "__main__":
    sys.exit(main())
