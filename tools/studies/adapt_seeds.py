"""``fastdet adapt`` on the annotated clips at several seeds, scored on their human keyframes:
issue 32's human figures with their spread (docs/training.md, "How much of a human figure is the
seed"). One seed is one draw: on boston_street the seeds 0-3 gave 0.57-0.81.

For each clip of ``--clips`` and each seed of ``--seeds``: ``python -m fastdet adapt
videos/CLIP.mp4 --teacher teachers/yolox_nano.onnx -o WORK/CLIP.sSEED.npz --seed SEED`` with
``--adapt-args`` appended (skipped when the file exists: a rerun only scores), then the video
pipeline over the clip with that model as ``video --model`` runs it, scored on the clip's keyframes
against its human boxes (IoU 0.5, :func:`fastdet.eval.evaluate`). Prints one markdown row a clip:
each seed's F1 (hits / false alarms / misses), their mean, lowest and highest.

    python -m tools.studies.adapt_seeds --work W [--clips highway_640,boston_street,motorcycle_highway]
                                        [--seeds 0,1,2,3] [--adapt-args '--teacher-size 960']
"""
from __future__ import annotations

import argparse
import shlex
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from fastdet.data import data_dir
from fastdet.detections import Detections
from fastdet.eval import EvalResult, evaluate
from fastdet.eval.clips import AnnotatedClip, annotated_clips
from fastdet.video.run import detect_video
from tools.studies.adapt_unlabelled import run_adapt

#: the human-labelled clips of issue 32
CLIPS = ("highway_640", "boston_street", "motorcycle_highway")


@dataclass(frozen=True)
class SeedScore:
    """One adapted model's human keyframe figures: ``seed``, ``f1``, hits ``tp``, false alarms
    ``fp``, misses ``fn``."""

    seed: int
    f1: float
    tp: int
    fp: int
    fn: int

    @classmethod
    def of(cls, seed: int, r: EvalResult) -> SeedScore:
        return cls(seed, float(r.f1), int(r.tp), int(r.fp), int(r.fn))


def adapt_clip(clip: AnnotatedClip, seed: int, out: Path, data: Path, extra: Sequence[str] = ()) -> str | None:
    """:func:`~tools.studies.adapt_unlabelled.run_adapt` on ``clip``'s video at ``seed``: ``None``
    when the model is there, else adapt's last line of error."""
    return run_adapt(clip.video, out, data, ["--seed", str(seed), *extra])


def human_score(clip: AnnotatedClip, model: Path) -> EvalResult:
    """``model`` through the video pipeline over ``clip`` (as ``video --model``), scored on its
    keyframes against its human boxes."""
    tables = list(detect_video(str(clip.video), model=str(model), progress=False))
    return evaluate(clip.gt(), Detections.concat(tables), keyframes=clip.keyframes(), tracking=False)


def row(name: str, scores: Sequence[SeedScore]) -> str:
    """The markdown row of one clip: each seed's F1 (hits / false alarms / misses), then the
    mean, lowest and highest F1 (``n/a`` without a score)."""
    cells = [f"{s.f1:.3f} ({s.tp} / {s.fp} / {s.fn})" for s in scores]
    if scores:
        f1 = [s.f1 for s in scores]
        tail = [f"**{sum(f1) / len(f1):.3f}**", f"{min(f1):.3f}", f"{max(f1):.3f}"]
    else:
        tail = ["n/a"] * 3
    return "| " + " | ".join([name, *cells, *tail]) + " |"


def study(clips: Sequence[AnnotatedClip], seeds: Sequence[int], work: Path, data: Path, extra: Sequence[str] = (),
          run: Callable[..., str | None] = adapt_clip,
          score: Callable[[AnnotatedClip, Path], EvalResult] = human_score) -> list[str]:
    """The table's lines (header first), each clip's row printed as it is done; a seed whose
    adapt refused is named on stderr and left out of its clip's row."""
    head = ["clip", *[f"seed {s}" for s in seeds], "mean", "lowest", "highest"]
    lines = ["| " + " | ".join(head) + " |", "|---" * len(head) + "|"]
    for line in lines:
        print(line, flush=True)
    for clip in clips:
        got = []
        for seed in seeds:
            out = work / f"{clip.name}.s{seed}.npz"
            err = run(clip, seed, out, data, extra)
            if err is not None:
                print(f"{clip.name} seed {seed}: adapt: {err}", file=sys.stderr)
                continue
            got.append(SeedScore.of(seed, score(clip, out)))
        lines.append(row(clip.name, got))
        print(lines[-1], flush=True)
    return lines


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--work", required=True, type=Path, help="folder of the adapted models (made if missing)")
    ap.add_argument("--clips", default=",".join(CLIPS), help="comma-separated annotated clip names")
    ap.add_argument("--seeds", default="0,1,2,3", help="comma-separated adapt seeds")
    ap.add_argument("--adapt-args", default="", help="options appended to each adapt run")
    a = ap.parse_args(argv)
    data = data_dir()
    known = {c.name: c for c in annotated_clips(data)}
    names = a.clips.split(",")
    missing = sorted(set(names) - set(known))
    if missing:
        ap.error(f"no annotated clip {', '.join(missing)}")
    try:
        seeds = [int(s) for s in a.seeds.split(",")]
    except ValueError:
        ap.error(f"--seeds: whole numbers separated by commas, got {a.seeds!r}")
    a.work.mkdir(parents=True, exist_ok=True)
    study([known[n] for n in names], seeds, a.work, data, shlex.split(a.adapt_args))
    return 0


if __name__ == "__main__":
    sys.exit(main())
