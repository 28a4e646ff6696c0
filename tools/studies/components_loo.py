"""Leave-one-clip-out measurement of the side-view component: every annotated clip scored with a
side model that never saw it, beside the pipeline without the component.

For each annotated clip ``X`` of the data folder, ``WORK/side_without_X.npz`` is trained on all
the other clips (``tools/scripts/side_model.py --exclude X``; kept when it exists, so a rerun
only scores) and the video pipeline runs on ``X`` twice, with that model as its side component
and without a side component; both are scored as ``fastdet eval --all`` scores (keyframes only
on the keyframe clips, IoU 0.5, :mod:`fastdet.eval.clips`). Prints the two markdown tables.

Usage (from the repository root)::

    python -m tools.studies.components_loo [--work /tmp/fastdet-side-loo] [--clips A,B] [--no-train]
    python -m tools.studies.components_loo --cost [--repeat 2]

``--cost``: CPU per frame (``time.process_time``, one thread, guided search on) of
``VideoDetector.update`` over every frame of ``videos/test_small1.mp4``, with and without the
bundled side component, best of ``--repeat`` runs.

About 1 minute of CPU per clip to train and as much to run both pipelines.
"""
from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path

import cv2

from fastdet.config import PipelineConfig
from fastdet.data import data_dir
from fastdet.eval.clips import annotated_clips, markdown_table
from fastdet.io.reader import read_frames
from fastdet.video import VideoDetector, make_detector
from tools.scripts.side_model import build
from tools.studies.loo import run_clip


def cost(repeat: int) -> None:
    import numba

    numba.set_num_threads(1)
    cv2.setNumThreads(1)
    frames = read_frames(data_dir() / "videos" / "test_small1.mp4")
    best: dict[str, float] = {}
    for _ in range(repeat):
        for name, cfg in (("today", PipelineConfig()), ("with the side component", PipelineConfig(side=True))):
            vd = VideoDetector(make_detector(cfg), cfg)
            vd.warmup()
            vd.prime_horizon(frames)
            t = time.process_time()
            for f in frames:
                vd.update(f)
            ms = (time.process_time() - t) / len(frames) * 1000
            best[name] = min(best.get(name, ms), ms)
    for name, ms in best.items():
        print(f"{name}: {ms:.1f} ms CPU per frame ({ms / best['today']:.2f}x)")


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--work", type=Path, default=Path("/tmp/fastdet-side-loo"))
    p.add_argument("--clips", help="comma-separated clips (default: every annotated clip)")
    p.add_argument("--no-train", action="store_true", help="only score: every held-out model must exist")
    p.add_argument("--cost", action="store_true", help="only measure the CPU per frame with and without it")
    p.add_argument("--repeat", type=int, default=2)
    args = p.parse_args(argv)
    if args.cost:
        cost(args.repeat)
        return 0
    data = data_dir()
    clips = annotated_clips(data)
    names = [c.name for c in clips]
    if args.clips:
        want = args.clips.split(",")
        clips = [c for c in clips if c.name in want]
    args.work.mkdir(parents=True, exist_ok=True)
    base, side = [], []
    for clip in clips:
        model = args.work / f"side_without_{clip.name}.npz"
        if not model.exists():
            if args.no_train:
                print(f"components_loo: {model} missing (run without --no-train)", file=sys.stderr)
                return 2
            build(model, [n for n in names if n != clip.name], data)
        base.append(run_clip(clip, replace(PipelineConfig(), side=False)))
        side.append(run_clip(clip, replace(PipelineConfig(), side=str(model))))
        print(f"{clip.name}: F1 {base[-1].result.f1:.3f} -> {side[-1].result.f1:.3f}", flush=True)
    print("\nwithout the side component\n")
    print(markdown_table(base))
    print("\nwith the side component, leave one clip out (each clip scored by the model trained without it)\n")
    print(markdown_table(side))
    return 0


if __name__ == "__main__":
    sys.exit(main())
