"""The teacher's own F1 on the human keyframes of the annotated clips: the reference issue 32
measures an adapted model against (``adapt`` at its defaults trains on the teacher at 640 px, its
boxes of score >= 0.3 the targets).

For each clip of ``annotations/`` (keyframes only, where ``CLIP.frames`` lists them) and each
``--sizes`` input size, :class:`fastdet.teacher.TeacherDetector` (``teachers/yolox_nano.onnx`` by
default) boxes the scored frames; the boxes are read back as ``adapt`` reads its labels
(:func:`fastdet.labels.teacher.read_teacher_clip`: vehicles at ``min_score`` and above are
targets, the rest and two-wheelers ignore regions, the size rule) at each ``--min-scores`` value
and scored against the human boxes as ``fastdet eval`` scores a run (:func:`fastdet.eval.evaluate`,
IoU 0.5). Prints one markdown row a clip, size and score.

    python -m tools.studies.teacher_f1 [--clips highway_640,boston_street,motorcycle_highway]
                                       [--sizes 640,960] [--min-scores 0.3,0.4,0.5] [--teacher M.onnx]
"""
from __future__ import annotations

import argparse
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from fastdet.data import data_dir
from fastdet.detections import Detections
from fastdet.eval import EvalResult, evaluate
from fastdet.eval.clips import AnnotatedClip, annotated_clips
from fastdet.eval.pictures import frames_ground_truth
from fastdet.io.reader import FrameReader
from fastdet.labels.teacher import read_teacher_clip
from fastdet.teacher import TeacherDetector
from fastdet.teacher.label import write_teacher_files


def teacher_results(name: str, video: str | Path, gt: Detections, frames: np.ndarray | None,
                    detector: TeacherDetector, min_scores: Sequence[float], work: Path) -> dict[float, EvalResult]:
    """The teacher's boxes on ``frames`` of ``video`` (1-based numbers; ``None``: every frame),
    read back as ``adapt`` reads its labels at each of ``min_scores`` and scored against ``gt``
    on those frames (``work``: a folder for the label files, ``name`` their clip name)."""
    wanted = None if frames is None else {int(k) for k in frames}
    labelled = []
    with FrameReader(str(video), notify=lambda _: None) as reader:
        for number, frame, _ in reader:
            if wanted is None or number in wanted:
                labelled.append((number, detector.detect(frame)))
    work.mkdir(parents=True, exist_ok=True)
    boxes_path, _ = write_teacher_files(work, name, labelled)
    out = {}
    for m in min_scores:
        labels = frames_ground_truth(read_teacher_clip(boxes_path, min_score=m, video=video))
        t = labels[labels.targets]  # the targets as predictions (a scored table: each box 1)
        preds = Detections(t.boxes.astype(np.int32), np.ones(len(t), np.float32), frames=t.frames)
        out[m] = evaluate(gt, preds, keyframes=frames, tracking=False)
    return out


def teacher_rows(clip: AnnotatedClip, detector: TeacherDetector, min_scores: Sequence[float],
                 work: Path) -> dict[float, EvalResult]:
    """:func:`teacher_results` on ``clip``'s scored frames (its keyframes, else every frame)
    against its human boxes."""
    return teacher_results(clip.name, clip.video, clip.gt(), clip.keyframes(), detector, min_scores, work)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--clips", default=None, help="comma-separated clip names (default: every annotated clip)")
    ap.add_argument("--sizes", default="640,960", help="teacher input sizes, comma-separated")
    ap.add_argument("--min-scores", default="0.3,0.4,0.5", help="target score thresholds, comma-separated")
    ap.add_argument("--teacher", default=str(data_dir() / "teachers" / "yolox_nano.onnx"))
    args = ap.parse_args(argv)
    clips = annotated_clips()
    if args.clips:
        names = args.clips.split(",")
        missing = sorted(set(names) - {c.name for c in clips})
        if missing:
            ap.error(f"no annotated clip {', '.join(missing)}")
        clips = [c for c in clips if c.name in names]
    sizes = [int(s) for s in args.sizes.split(",")]
    scores = [float(s) for s in args.min_scores.split(",")]
    print("| clip | teacher size | min score | P | R | **F1** | hits / false / missed |")
    print("|---|---:|---:|---:|---:|---:|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for size in sizes:
            detector = TeacherDetector(args.teacher, size=size)
            for clip in clips:
                for m, r in teacher_rows(clip, detector, scores, Path(tmp) / f"{size}").items():
                    print(f"| {clip.name} | {size} | {m:g} | {r.precision:.2f} | {r.recall:.2f} | **{r.f1:.3f}** "
                          f"| {r.tp} / {r.fp} / {r.fn} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
