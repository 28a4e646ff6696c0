"""Leave-one-camera-out measurement of the main model trained on the data set's crops plus the crops
of the annotated frames (``tools/scripts/keyframe_model.py``): every annotated clip scored by a
model that never saw its camera, beside the bundled model, in two ways:

- (a) the pipeline: ``fastdet video``'s defaults with the held-out model as the main model,
  scored as ``fastdet eval --all`` (keyframes only on the keyframe clips, IoU 0.5): what a user
  gets today, search placement included;
- (b) placement-free, per window: on the annotated frames every row and window size searched
  (:func:`fastdet.train.windows.dense_search`: window widths from 1/32 of the frame width to
  the frame height, 4 sizes per octave, one HOG cell apart), each target's best window at IoU
  >= 0.5 against the windows that touch no annotated box: recall at 0.1 / 1 / 10 such false
  windows per frame, and recall with the false windows per frame at probability 0.5
  (:func:`fastdet.train.windows.score_frames`). This is the model alone, wherever the search
  may later put its bands.

Per clip it also prints, of the pipeline's boxes that match no target (IoU < 0.5) and touch no
ignore region, how many touch a target (misplaced: too big, over two vehicles) and how many
touch nothing annotated (:func:`tools.studies.loo.misplaced`).

Folds (:func:`tools.studies.loo.folds`): each camera is held out in turn; the two Udacity clips
(one drive) together. ``WORK/main[_TAG]_without_FOLD.npz`` is trained on the other clips
(kept when it exists, so a rerun only scores); one training at a time, single process.

``--refine-loo DIR``: each clip's box regressor is ``DIR/refine_without_CLIP.npz`` (fitted on the
other cameras, ``python -m tools.studies.refine_loo --out-dir DIR``), for the bundled model and the
held-out one alike, so that nothing that saw the clip scores it; without it the bundled
regressor (which saw every clip) refines the boxes.

Two rules that turn a held-out model into the one scored, both learnt only from its own training
clips (:mod:`fastdet.train.blend`), written beside it (``..._mixM``, ``..._cal``):

- ``--mix M``: the bundled model and the held-out one blended, ``(1 - M) x bundled + M x
  held-out`` (folded weights averaged: one linear model, the same search cost);
- ``--calibrate``: the model's decision values moved by a constant so that, on the dense search's
  false windows of its training clips' annotated frames (every second HOG cell), it lets through
  as many as the bundled model does at the search's threshold (decision value 0): every
  threshold of the pipeline on a main-model window moves with it; ``--calibrate-on near``
  (``..._calnear``): matched on the near windows instead (touching a target at IoU < 0.3 with
  every target, no ignore region: the windows the heat map grows into misplaced boxes), which
  the recipe does not mine as negatives;
- ``--offset D`` (``..._offD``): the decision values lowered by a fixed ``D`` after either (a
  sweep, not a rule: a value chosen by looking at the held-out clips scores them in-sample).

``--held-out-rate`` (a diagnostic, never a rule): also the offset at which the scored model lets
through as many of the *held-out* clips' dense false windows (near windows with
``--calibrate-on near``) as the bundled model does at 0,
and how many each lets through (JSON ``held_out_rate``), to compare with what ``--calibrate``
learnt on the training clips.

``--no-windows`` skips the placement-free scores (b) (they do not depend on the pipeline).

Usage (from the repository root)::

    python -m tools.studies.model_loo [--work /tmp/fastdet-model-loo] [--clips A,B] [--tag T]
        [--jitter N] [--background N] [--hard-per-frame N] [--hard-rounds N [--reuse-round1]] [--C C]
        [--no-train] [--no-baseline] [--refine-loo DIR] [--mix M] [--calibrate [--calibrate-on near]]
        [--offset D] [--held-out-rate] [--no-windows]
        [--json OUT.json]

About 4 minutes of CPU per fold to train, 1-2 to score.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
from dataclasses import replace
from pathlib import Path
from typing import Any

from fastdet.config import PipelineConfig
from fastdet.data import data_dir
from fastdet.detections import Detections
from fastdet.eval.clips import annotated_clips, markdown_table
from fastdet.io.atomic import write_bytes
from fastdet.model import Model, load_model
from fastdet.train.blend import blend, offset, rate_offset
from fastdet.train.keyframes import read_annotated_frames
from fastdet.train.windows import FALSE_RATES, WindowScore, false_window_scores, near_window_scores, score_frames
from tools.scripts.keyframe_model import add_recipe_arguments, build, recipe_from_args
from tools.studies.loo import folds, misplaced, run_clip


def window_table(rows: list[tuple[str, WindowScore, WindowScore | None]]) -> str:
    """Markdown: per clip the placement-free window scores of the bundled model and of the
    held-out model (``before -> after``)."""
    head = ["clip", "frames", "targets", "reachable"] + [f"R @ {r:g} FW/frame" for r in FALSE_RATES]
    head += ["R @ p>0.5", "FW/frame @ p>0.5"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]

    def pair(a: float, b: float | None, digits: int = 2) -> str:
        def f(v: float | None) -> str:
            return "n/a" if v is None or not math.isfinite(v) else f"{v:.{digits}f}"

        return f(a) if b is None else f"{f(a)} -> **{f(b)}**"

    for name, base, new in rows:
        cells = [name, str(base.frames), str(base.targets), str(base.reachable)]
        cells += [pair(base.recall_at[r], None if new is None else new.recall_at[r]) for r in FALSE_RATES]
        cells += [pair(base.recall_half, None if new is None else new.recall_half),
                  pair(base.false_half, None if new is None else new.false_half, 1)]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def scored_model(held_out: Model, bundled: Model, train_clips: list[str], data: Path, mix: float | None,
                 calibrate: bool, log=print, on: str = "false") -> tuple[Model, dict[str, Any]]:
    """The model a fold's clips are scored with: ``held_out`` blended with ``bundled`` (``mix``,
    the held-out model's weight; ``None``: not blended) and, with ``calibrate``, offset to let
    through as many of the false windows of ``train_clips``' annotated frames as ``bundled``
    does at decision value 0 (module docstring; ``on`` ``"near"``: of their near windows,
    :func:`fastdet.train.windows.near_window_scores`); with what was done."""
    model, info = held_out, {}
    if mix is not None:
        model = blend([bundled, held_out], [1.0 - mix, mix])
        info["mix"] = mix
    if calibrate:
        frames = [f for c in train_clips for f in read_annotated_frames(data, c)]
        windows = near_window_scores if on == "near" else false_window_scores
        scores = windows([model, bundled], frames, cells_per_step=2)
        delta = rate_offset(scores[0], scores[1], 0.0)
        info.update(offset=delta, windows=on, false_windows=int(scores.shape[1]), frames=len(frames),
                    bundled_above_0=int((scores[1] > 0).sum()), model_above_0=int((scores[0] > 0).sum()))
        log(f"calibrated on {', '.join(train_clips)}: {info['frames']} frames, {info['false_windows']} {on} "
            f"windows; above 0: bundled {info['bundled_above_0']}, model {info['model_above_0']}; offset {delta:+.3f}")
        model = offset(model, delta, {"calibration": {**info, "clips": train_clips}})
    return model, info


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--work", type=Path, default=Path("/tmp/fastdet-model-loo"))
    p.add_argument("--clips", help="comma-separated clips to score (default: every annotated clip)")
    p.add_argument("--tag", default="", help="a name for this recipe's models (WORK/main_TAG_without_X.npz)")
    add_recipe_arguments(p)
    p.add_argument("--reuse-round1", action="store_true",
                   help="with --hard-rounds > 1: WORK/main_without_FOLD.npz (the default recipe's) is round 1")
    p.add_argument("--C", type=float, default=None)
    p.add_argument("--no-train", action="store_true", help="only score: every held-out model must exist")
    p.add_argument("--no-baseline", action="store_true", help="do not score the bundled model")
    p.add_argument("--refine-loo", type=Path, default=None,
                   help="the held-out box regressors, DIR/refine_without_CLIP.npz (refine_loo --out-dir)")
    p.add_argument("--mix", type=float, default=None, help="score the bundled and the held-out model blended, "
                                                            "this the held-out one's weight (0..1)")
    p.add_argument("--calibrate", action="store_true",
                   help="offset the scored model to the bundled model's false-window rate on its training clips")
    p.add_argument("--calibrate-on", choices=["false", "near"], default="false",
                   help="the training clips' windows --calibrate matches: false (touching nothing annotated) "
                        "or near (touching a target at IoU < 0.3)")
    p.add_argument("--offset", type=float, default=None,
                   help="lower the scored model's decision values by this much (a fixed shift, for sweeps)")
    p.add_argument("--held-out-rate", action="store_true",
                   help="also print the offset matching the bundled model's false-window rate on the held-out "
                        "clips (a diagnostic)")
    p.add_argument("--no-windows", action="store_true", help="skip the placement-free window scores")
    p.add_argument("--json", type=Path, help="also write every figure to this JSON file")
    args = p.parse_args(argv)
    if args.mix is not None and not 0 <= args.mix <= 1:
        p.error("--mix must be in 0..1")
    if args.offset is not None and not math.isfinite(args.offset):
        p.error("--offset must be finite")
    data = data_dir()
    clips = {c.name: c for c in annotated_clips(data)}
    want = args.clips.split(",") if args.clips else list(clips)
    unknown = sorted(set(want) - set(clips))
    if unknown:
        print(f"model_loo: not annotated clips: {', '.join(unknown)}", file=sys.stderr)
        return 2
    recipe = recipe_from_args(args)
    args.work.mkdir(parents=True, exist_ok=True)
    bundled = load_model(None)
    tag = f"_{args.tag}" if args.tag else ""
    pipe_base, pipe_new, win_rows = [], [], []
    out: dict[str, Any] = {"recipe": recipe.to_dict(), "C": args.C, "clips": {}}
    for fold in folds(list(clips)):
        scored = [c for c in fold.held_out if c in want]
        if not scored:
            continue
        path = args.work / f"main{tag}_without_{fold.name}.npz"
        if not path.exists():
            if args.no_train:
                print(f"model_loo: {path} missing (run without --no-train)", file=sys.stderr)
                return 2
            first = args.work / f"main_without_{fold.name}.npz"
            previous = [load_model(first)] if args.reuse_round1 and first.exists() else []
            build(path, list(fold.train), data, recipe, args.C, previous=previous)
        model = load_model(path)
        rule = ""
        if args.mix is not None or args.calibrate or args.offset is not None:
            cal = ("_cal" + ("near" if args.calibrate_on == "near" else "")) if args.calibrate else ""
            rule = ((f"_mix{args.mix:g}" if args.mix is not None else "") + cal
                    + (f"_off{args.offset:g}" if args.offset is not None else ""))
            path = args.work / f"main{tag}{rule}_without_{fold.name}.npz"
            model, info = scored_model(model, bundled, list(fold.train), data, args.mix, args.calibrate,
                                       on=args.calibrate_on)
            if args.offset is not None:
                model = offset(model, args.offset, {"fixed_offset": args.offset})
                info["fixed_offset"] = args.offset
            model.save(path)
            out.setdefault("rules", {})[fold.name] = info
        if args.held_out_rate:
            frames = [f for c in scored for f in read_annotated_frames(data, c)]
            sc = (near_window_scores if args.calibrate_on == "near" else false_window_scores)(
                [model, bundled], frames, cells_per_step=2)
            rate = {"offset": rate_offset(sc[0], sc[1], 0.0), "frames": len(frames), "false_windows": int(sc.shape[1]),
                    "bundled_above_0": int((sc[1] > 0).sum()), "model_above_0": int((sc[0] > 0).sum())}
            out.setdefault("held_out_rate", {})[fold.name] = rate
            print(f"held out {', '.join(scored)} (diagnostic): {rate['frames']} frames, {rate['false_windows']} "
                  f"{args.calibrate_on} windows; above 0: bundled {rate['bundled_above_0']}, "
                  f"model {rate['model_above_0']}; "
                  f"the offset matching the bundled model's rate {rate['offset']:+.3f}", flush=True)
        for name in scored:
            frames = [] if args.no_windows else read_annotated_frames(data, name)
            base_w = None if args.no_baseline or args.no_windows else score_frames(bundled, frames)
            new_w = None if args.no_windows else score_frames(model, frames)
            refine = None
            if args.refine_loo is not None:
                refine = args.refine_loo / f"refine_without_{name}.npz"
                if not refine.is_file():
                    print(f"model_loo: {refine} missing (python -m tools.studies.refine_loo --out-dir "
                          f"{args.refine_loo})", file=sys.stderr)
                    return 2
            held = PipelineConfig(refine_model=None if refine is None else str(refine))
            kept: list[Detections] = []
            if new_w is not None:
                win_rows.append((name, new_w, None) if base_w is None else (name, base_w, new_w))
            if not args.no_baseline:
                pipe_base.append(run_clip(clips[name], held, keep=kept))
            pipe_new.append(run_clip(clips[name], replace(held, model=str(path)), keep=kept))
            wrong = [misplaced(clips[name], k) for k in kept]
            out["clips"][name] = {"model": str(path), "trained_on": list(fold.train),
                                  "refine_model": None if refine is None else str(refine),
                                  "false_alarms_near_target_and_clear": wrong,
                                  "windows": None if new_w is None else new_w.to_dict(),
                                  "pipeline": pipe_new[-1].to_dict(),
                                  "bundled": None if args.no_baseline else {
                                      "windows": None if base_w is None else base_w.to_dict(),
                                      "pipeline": pipe_base[-1].to_dict()}}
            windows = "" if new_w is None else (
                f"; window recall @ 1 FW/frame {'' if base_w is None else f'{base_w.recall_at[1.0]:.3f} -> '}"
                f"{new_w.recall_at[1.0]:.3f}")
            print(f"{name}: pipeline F1 {'' if args.no_baseline else f'{pipe_base[-1].result.f1:.3f} -> '}"
                  f"{pipe_new[-1].result.f1:.3f}{windows}; "
                  f"pipeline boxes at IoU < 0.5 touching a target / touching nothing annotated: "
                  f"{' -> '.join(f'{a} / {b}' for a, b in wrong)}", flush=True)
    if pipe_base:
        print("\n(a) pipeline, the bundled model\n")
        print(markdown_table(pipe_base))
    print("\n(a) pipeline, held-out models (each clip scored by the model trained without its camera)\n")
    print(markdown_table(pipe_new))
    if win_rows:
        print("\n(b) placement-free windows" + ("" if args.no_baseline else ": bundled -> held-out model") + "\n")
        print(window_table(win_rows))
    if args.json:
        write_bytes(args.json, json.dumps(out, indent=1, sort_keys=True).encode())
    return 0


if __name__ == "__main__":
    sys.exit(main())
