"""A model through ``video``'s pipeline over whole unlabelled clips of ``$FASTDET_DATA/videos``,
scored against the shared teacher ensemble's boxes of every 5th frame (``teacher/CLIP.teacher.txt``:
its targets by the data README's rule, the rest ignore regions; IoU 0.5, no tracking). Training
labels, not ground truth: the issue's second, cheaper signal, for cameras no human labelled (run by
hand; docs/geometry.md, "Frames taller than wide"). Prints one markdown row a clip: F1 (hits /
false alarms / misses).

    python -m tools.studies.ensemble_agreement --clips haroon_road,j219_road [--model M.npz]
"""
from __future__ import annotations

import argparse

from fastdet.data import data_dir
from fastdet.detections import Detections
from fastdet.eval import evaluate
from fastdet.video.run import detect_video
from tools.studies.adapt_unlabelled import clip_video, kept_aside_truth


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--clips", required=True, help="comma-separated clip names of videos/ with teacher/ labels")
    ap.add_argument("--model", default=None, help="main model file (default: the bundled one)")
    a = ap.parse_args(argv)
    data = data_dir()
    for clip in a.clips.split(","):
        gt, keyframes = kept_aside_truth(clip, data, 1)
        tables = list(detect_video(clip_video(clip, data), model=a.model, progress=False))
        r = evaluate(gt, Detections.concat(tables), keyframes=keyframes, tracking=False)
        print(f"| {clip} | {r.f1:.2f} ({r.tp} / {r.fp} / {r.fn}) |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
