"""``fastdet adapt`` on the unlabelled clips of ``$FASTDET_DATA/videos``, scored against the shared
teacher ensemble (``teacher/CLIP.teacher.txt``) on the stretch adapt kept aside (run by hand;
docs/training.md, "The camera's own box regressor").

For each clip: ``python -m fastdet adapt videos/CLIP.mp4 --teacher teachers/yolox_nano.onnx -o
WORK/CLIP.npz`` at the defaults (skipped when WORK/CLIP.npz exists: a rerun only scores), then the
video pipeline over the kept-aside stretch (from ``metadata["adapt"]["footage"][0]
["kept_aside_from"]`` to the end, as ``detect_video``) with three main models:

- the bundled one;
- the adapted one with the bundled box regressor (its carried regressor left out: written as
  ``WORK/CLIP.noreg.npz``);
- the adapted one as written (its own regressor, when adapt fitted one).

Each is scored with :func:`fastdet.eval.evaluate` (IoU 0.5, no tracking) on the stretch's frames
the ensemble labelled: its targets (the data README's rule, ``read_teacher_clip``) count,
the rest are ignore regions. This is the issue's second, cheaper signal: the ensemble's boxes are
not ground truth, and adapt trained on other labels (its own teacher's, on frames before the
stretch). The stretch is searched at the horizon a ``video`` run of the whole clip has
(:func:`fastdet.video.run.file_horizon`, or the camera's horizon an adapted model records; before
the fourteenth session, at the one the stretch's own first frames gave). Prints a markdown table,
one row a clip (F1, hits / false alarms / misses, and what adapt chose).

With ``--teacher-column`` a last column scores the teacher itself (``teachers/yolox_nano.onnx`` at
640 px, its boxes of score >= 0.3 as adapt reads its labels) on the same frames against the same
ensemble boxes: the reference of issue 32's goal on these clips (the teacher's own F1 minus 0.03).

    python -m tools.studies.adapt_unlabelled --work W [--clips anmol_highway,tmo_seattle1,...]
        [--adapt-args '--teacher-size 960'] [--teacher-column]
"""
from __future__ import annotations

import argparse
import dataclasses
import subprocess
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from fastdet.data import data_dir
from fastdet.detections import Detections
from fastdet.eval import EvalResult, evaluate
from fastdet.eval.pictures import frames_ground_truth
from fastdet.labels.mot import find_video
from fastdet.labels.teacher import MIN_SCORE, read_teacher_clip
from fastdet.model import load_model
from fastdet.teacher import TeacherDetector
from fastdet.video.detector import recorded_horizon
from fastdet.video.run import detect_video, file_horizon
from tools.studies.markdown import table
from tools.studies.teacher_f1 import teacher_results

#: every clip of ``teacher/`` (the 17 unlabelled cameras); docs/training.md's tables name the ones
#: they measured (a clip whose kept-aside stretch the ensemble labels no vehicle on scores nothing)
CLIPS = ("akin_highway", "anmol_highway", "chanremin_v49", "tmo_seattle1", "driveai_road", "suchet_car",
         "hadiya_input", "hadiya_input8", "neeraj_test", "haroon_road", "j219_road", "ebuarip_640",
         "orange_road", "tmo_rainy", "tmo_night", "teamlv_rainy", "samyx_nuit")


def clip_video(clip: str, data: Path) -> Path:
    """The clip's video, ``data/videos/CLIP.*`` of any video suffix (``ebuarip_640.avi``), as the
    teacher reader finds it beside the clip's labels (:func:`fastdet.labels.mot.find_video`)."""
    return find_video(data / "teacher" / f"{clip}.teacher.txt", clip)


def run_adapt(video: Path, out: Path, data: Path, extra: Sequence[str] = ()) -> str | None:
    """Run ``python -m fastdet adapt VIDEO --teacher DATA/teachers/yolox_nano.onnx -o OUT`` with
    ``extra`` options appended, unless ``out`` exists; ``None`` when the model is there, else
    adapt's last line of error."""
    if out.exists():
        return None
    cmd = [sys.executable, "-m", "fastdet", "adapt", str(video),
           "--teacher", str(data / "teachers" / "yolox_nano.onnx"), "-o", str(out), "--no-progress", *extra]
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode:
        return (r.stderr.strip().splitlines() or ["(no message)"])[-1]
    return None


def adapt(clip: str, out: Path, data: Path, extra: list[str] | None = None) -> bool:
    """:func:`run_adapt` on the clip's video (``extra`` e.g. ``--teacher-size 960``); False when
    adapt refused (its one line is printed)."""
    err = run_adapt(clip_video(clip, data), out, data, extra or [])
    if err is not None:
        print(f"{clip}: adapt: {err}", file=sys.stderr)
        return False
    return True


def kept_aside_truth(clip: str, data: Path, start: int) -> tuple[Detections, np.ndarray]:
    """The ensemble's boxes of the clip's frames from ``start`` on (targets, and ignore regions with
    ``consider`` False) and those frames."""
    video = clip_video(clip, data)
    pics = [p for p in read_teacher_clip(data / "teacher" / f"{clip}.teacher.txt", video=video,
                                         camera=clip, source="teacher") if p.frame >= start]
    return frames_ground_truth(pics, source="teacher ensemble"), np.array([p.frame for p in pics], np.int64)


def score(clip: str, model: Path, data: Path, teacher: TeacherDetector | None = None) -> str:
    """One table row: the three models on the clip's kept-aside stretch, and with ``teacher`` the
    teacher itself there (its boxes of score >= 0.3, as adapt reads them: the reference of issue
    32's goal, the teacher's own F1 minus 0.03)."""
    m = load_model(model)
    footage = m.metadata["adapt"]["footage"][0]
    start, total = int(footage["kept_aside_from"]), int(footage["frames"])
    gt, keyframes = kept_aside_truth(clip, data, start)
    plain = model.with_name(model.stem + ".noreg.npz")
    dataclasses.replace(m, regressor=None).save(plain)
    video = clip_video(clip, data)
    # where a `video` run of the whole clip searches, not the stretch's own estimate: the flow's,
    # or the camera's horizon the adapted model records
    flow = file_horizon(video)
    recorded = recorded_horizon("auto", m.metadata)  # a bad record: the one line a `video` run gives
    cells = []
    for path in (None, plain, model):
        horizon = flow if path is None or recorded == "auto" else recorded
        tables = list(detect_video(video, model=None if path is None else str(path), start=start - 1,
                                   frames=total - start + 1, horizon=horizon, progress=False))
        cells.append(_cell(evaluate(gt, Detections.concat(tables), keyframes=keyframes, tracking=False)))
    if teacher is not None:
        with tempfile.TemporaryDirectory() as tmp:
            cells.append(_cell(teacher_results(clip, video, gt, keyframes, teacher, [MIN_SCORE], Path(tmp))[MIN_SCORE]))
    return f"| {clip} | {len(keyframes)} | " + " | ".join(cells) + f" | {chosen(m.metadata['adapt'])} |"


def _cell(r: EvalResult) -> str:
    """A table cell: F1 (hits / false alarms / misses)."""
    return f"{r.f1:.2f} ({r.tp} / {r.fp} / {r.fn})" if r.tp + r.fp + r.fn else "no box, no target"


def chosen(summary: dict) -> str:
    """What adapt chose: the formation; its best offset, that F1 +- its standard error -> the offset
    chosen (the strictest within it); then the side-view component's offset or "left out" where one
    was fitted; older models: the formation and offset."""
    b = summary.get("boxes", "heat")
    t = (summary.get("boxes_tried") or {}).get(b, {})
    if "best_offset" not in t:
        return f"{b}, {summary.get('offset', 0):g}"
    side = summary.get("side") or {}
    kept = "" if "offsets_f1" not in side else (
        "; side-view left out" if side.get("offset") is None else f"; side-view {side['offset']:g}")
    return f"{b}; {t['best_offset']:g}, {t['best_f1']:.2f} +- {t['f1_se']:.2f} -> {summary['offset']:g}{kept}"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--work", required=True, type=Path, help="folder of the adapted models (made if missing)")
    ap.add_argument("--clips", default=",".join(CLIPS), help="comma-separated clip names of videos/")
    ap.add_argument("--adapt-args", default="", help="options appended to each adapt run, e.g. '--teacher-size 960'")
    ap.add_argument("--teacher-column", action="store_true",
                    help="also score the teacher itself (teachers/yolox_nano.onnx at 640 px) on each stretch")
    a = ap.parse_args(argv)
    data = data_dir()
    teacher = TeacherDetector(str(data / "teachers" / "yolox_nano.onnx")) if a.teacher_column else None
    a.work.mkdir(parents=True, exist_ok=True)
    rows = []
    for clip in a.clips.split(","):
        out = a.work / f"{clip}.npz"
        if adapt(clip, out, data, a.adapt_args.split()):
            rows.append(score(clip, out, data, teacher))
            print(rows[-1], file=sys.stderr, flush=True)
    own = "teacher 640 px, score >= 0.3 | " if teacher else ""
    print(table("| clip | kept-aside teacher frames | bundled model | adapted, bundled regressor | "
                f"adapted, own regressor | {own}chosen |", rows))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
