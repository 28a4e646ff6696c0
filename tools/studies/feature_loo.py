"""Which window features carry over to other cameras: main models that differ only in their
features (trained by ``fastdet train`` on the data set's crops alone), each scored in the pipeline
on every annotated clip with the held-out box regressors (run by hand; docs/training.md "Which
features carry over to other cameras").

The models learn nothing from the clips, so every clip may score every model; the box regressor
is the one fitted without the clip (``--refine-loo DIR``: ``DIR/refine_without_CLIP.npz``, from
``python -m tools.studies.refine_loo --out-dir DIR``).

Per model:

- **crop accuracy, leak-free**: what ``fastdet train`` recorded for the data set's sequence
  split (:func:`fastdet.train.dataset.sequence_split`);
- **the pipeline** on every clip (``fastdet eval --all``'s scoring: keyframes, IoU 0.5): F1, P / R,
  false alarms a frame, hits by width (1280-wide pixels);
- **search cost** of a full 1280x720 scan at the reference horizon, the main model's share
  (:func:`cost`): features per window, HOG channel-cells (cells x HOG channels), windows,
  scoring multiply-adds, and the same over every model the pipeline runs (main + oncoming);
- with ``--crop-rate``, the same pipeline score once more with the model's decision values moved
  (:func:`fastdet.train.blend.offset`) by the constant at which it lets through as many of the
  sequence split's held-out **non-vehicle crops** as the first model (the reference, today's)
  does at decision value 0 (:func:`fastdet.train.blend.rate_offset` on the two split models'
  test decision values): a rule learnt from no clip, that puts every model at one operating point
  on the data set (written as ``WORK/NAME_croprate.npz``). The split models are the models'
  recipes (their ``training`` metadata: features, C, seed, mirrored and augmented copies) fitted
  again on the split's training part, their test decision values kept (``WORK/NAME.split.npz``; a
  rerun reads them); the confusion matrix at 0 must equal the one ``fastdet train`` recorded,
  which checks the refit.

With ``--windows``, also placement-free and free of any operating point (a diagnostic): on each
clip's annotated frames every row and window size searched (:func:`fastdet.train.windows.score_frames`,
as ``model_loo`` (b)), each target's best window at IoU >= 0.5 against the windows touching
nothing annotated: recall at 0.1 / 1 / 10 such false windows a frame. It compares the
features' separation on each camera with the threshold set on that clip itself, so it is never
a rule, only what a perfect per-camera threshold could give.

Pipeline scores are kept in ``WORK/feature_loo.json`` as they come (a rerun skips them).

    python -m tools.studies.feature_loo --work /tmp/s5-feat --refine-loo /tmp/s3r/final \\
        --model today=fastdet/models/default.npz --model hog3=/tmp/s5-feat/d_hog3.npz ... [--crop-rate]
"""
from __future__ import annotations

import argparse
import hashlib
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

from fastdet.config import PipelineConfig
from fastdet.data import data_dir
from fastdet.eval.clips import annotated_clips
from fastdet.io.atomic import write_bytes
from fastdet.model import Model, load_model
from fastdet.train.augment import augmented_copies
from fastdet.train.blend import offset, rate_offset
from fastdet.train.dataset import load_crops, sequence_split
from fastdet.train.fit import _flip, features_in_chunks, fit_classifier, metrics
from fastdet.train.keyframes import read_annotated_frames
from fastdet.train.windows import score_frames
from fastdet.video import make_detector
from tools.studies.band_cost import scan_cost
from tools.studies.loo import run_clip
from tools.studies.options_table import summary_of


def split_recipe(model: Model) -> dict[str, Any]:
    """What a refit of ``model``'s recipe on a split needs, read from its ``training`` metadata;
    ValueError for a model this study cannot refit (extra crops, a wide window, other crop size)."""
    t = model.metadata.get("training")
    if not t:
        raise ValueError("the model has no training metadata")
    d = t.get("data", {})
    if d.get("hard_negatives") or d.get("extra_positives") or model.config.window_height is not None \
            or t.get("crop_size", 64) != 64:
        raise ValueError("only models of the data set's 64x64 crops alone can be refitted here")
    a = t.get("augment", {})
    return {"C": float(t["C"]), "classifier": t["classifier"], "seed": int(t["seed"]), "flip": bool(t["flip"]),
            "truncate": float(a.get("truncate", 0.0)), "truncate_negatives": bool(a.get("truncate_negatives", True)),
            "reencode": float(a.get("reencode", 0.0)), "jpeg_quality": tuple(a.get("jpeg_quality", (30, 90))),
            "truncate_keep": tuple(a.get("truncate_keep", (0.5, 0.875)))}


def split_scores(model: Model, data: Path, log=print, max_per_folder: int | None = None) -> dict[str, np.ndarray]:
    """The decision values, on the sequence split's test part, of ``model``'s recipe fitted on its
    training part (the training part as :func:`fastdet.train.fit.train` builds it: the crops,
    their mirrored copies, the augmented copies of training crops); ``{"scores", "labels"}``,
    ``(N,)`` each. ``max_per_folder``: as ``fastdet train --max-per-folder`` (quick runs)."""
    r = split_recipe(model)
    config = model.config
    crops = load_crops(data, max_per_folder=max_per_folder)
    x = features_in_chunks(crops.images, config, False)
    tr, te = sequence_split(crops.groups, crops.order, r["seed"])
    parts = [(x[tr], crops.labels[tr])]
    if r["flip"]:
        parts.append((features_in_chunks(_flip(crops.images[tr]), config, False), crops.labels[tr]))
    aug = augmented_copies(crops.images, crops.labels, r["seed"], r["truncate"], r["truncate_negatives"],
                           r["reencode"], r["jpeg_quality"], r["truncate_keep"])
    if len(aug):
        a = aug.in_training(tr)
        parts.append((features_in_chunks(aug.images[a], config, False), aug.labels[a]))
    x_test = x[te]
    del x
    xs, ys = zip(*parts)
    xt, yt = np.concatenate(xs), np.concatenate(ys)
    del parts, xs
    log(f"  split refit: {len(yt)} training crops, {len(te)} test crops, {config.n_features} features")
    scaler, clf = fit_classifier(xt, yt, r["classifier"], r["C"], r["seed"], in_place=True)
    return {"scores": clf.decision_function(scaler.transform(x_test)).astype(np.float64),
            "labels": crops.labels[te].astype(np.int64)}


def cached_split_scores(name: str, model: Model, work: Path, data: Path, log=print,
                        max_per_folder: int | None = None) -> dict[str, np.ndarray]:
    """:func:`split_scores`, kept in ``work/NAME.split.npz``; checked against the confusion matrix
    ``fastdet train`` recorded for the sequence split (a mismatch is an error: the refit is not the
    model's recipe)."""
    path = work / f"{name}.split.npz"
    if path.is_file():
        with np.load(path, allow_pickle=False) as z:
            out = {"scores": z["scores"], "labels": z["labels"]}
    else:
        log(f"{name}: refitting on the sequence split's training part")
        out = split_scores(model, data, log, max_per_folder)
        np.savez(path.with_suffix(".tmp.npz"), **out)
        path.with_suffix(".tmp.npz").replace(path)
    m = metrics(out["labels"], (out["scores"] > 0).astype(np.int64))
    want = model.metadata["training"].get("sequence_split", {}).get("confusion")
    if want is not None and want != m["confusion"]:
        raise RuntimeError(f"{name}: the split refit's confusion {m['confusion']} is not the recorded {want}")
    return out


def cost(path: str | None, shape: tuple[int, int] = (720, 1280)) -> dict[str, float]:
    """A full scan of a ``shape`` frame at the reference horizon by the pipeline with main model
    ``path``: the main model's features per window, HOG channel-cells (HOG cells x channels),
    windows and scoring multiply-adds, and the channel-cells and multiply-adds of every model."""
    det = make_detector(PipelineConfig(model=path, horizon=None))
    main = scan_cost(det, shape, parts=(det.parts[0],), channels=True)
    every = scan_cost(det, shape, channels=True)
    return {"features": float(det.scorers[0].config.n_features), "hog_channel_cells": main["hog_cells"],
            "windows": main["windows"], "score_macs": main["score_macs"],
            "all_hog_channel_cells": every["hog_cells"], "all_score_macs": every["score_macs"]}


def least_offset(scores: np.ndarray, reference: np.ndarray, threshold: float = 0.0) -> float:
    """The offset of smallest size at which a model with decision values ``scores`` lets through as
    many of some windows as a reference with ``reference`` does above ``threshold`` (``0`` when
    it already does): :func:`fastdet.train.blend.rate_offset` puts the threshold halfway between
    the two scores either side of that count instead, which in a sparse tail (two crops of
    thousands) moves even the reference itself by a decision unit or more. ``(N,)`` arrays."""
    s = np.sort(np.asarray(scores, np.float64).ravel())[::-1]
    k = int((np.asarray(reference, np.float64) > threshold).sum())
    hi = s[k - 1] if k > 0 else np.inf  # the k-th best must stay above the threshold
    lo = s[k] if k < len(s) else -np.inf  # the (k+1)-th must not be above it
    if lo <= threshold < hi:
        return 0.0
    if threshold < lo:
        return float(lo - threshold)
    return float(np.nextafter(hi, -np.inf) - threshold)


def model_key(path: str) -> str:
    """A digest of what a model computes (features, weights, scaler): a rerun rescores a clip only
    when the model file's contents changed."""
    m = load_model(path)
    h = hashlib.sha1(repr((m.config, m.classifier, float(m.intercept))).encode())
    for a in (m.coef, m.mean, m.scale):
        h.update(np.ascontiguousarray(a, np.float64).tobytes())
    return h.hexdigest()


def fmt_clip(s: dict[str, Any]) -> str:
    """``F1 (P / R, FA; hits by width)`` of :func:`tools.studies.options_table.summary_of`."""
    widths = " ".join(f"{a}/{b}" for a, b in s["widths"] if b)
    return f"{s['f1']:.2f} ({s['p']:.2f} / {s['r']:.2f}, {s['fa']:.2f}; {widths})"


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--work", type=Path, required=True, help="split scores, offset models and results go here")
    p.add_argument("--refine-loo", type=Path, required=True, help="DIR/refine_without_CLIP.npz (refine_loo --out-dir)")
    p.add_argument("--model", action="append", required=True, metavar="NAME=PATH",
                   help="a main model to score (repeatable; the first is the reference of --crop-rate)")
    p.add_argument("--clips", help="comma-separated clips (default: every annotated clip)")
    p.add_argument("--crop-rate", action="store_true",
                   help="also score each model offset to the reference's rate on the held-out non-vehicle crops")
    p.add_argument("--crop-rule", choices=("midpoint", "least"), default="midpoint",
                   help="--crop-rate's offset: fastdet.train.blend.rate_offset (midpoint) or the smallest move "
                        "(least_offset)")
    p.add_argument("--no-pipeline", action="store_true", help="only the crop figures and the cost")
    p.add_argument("--windows", action="store_true",
                   help="also the placement-free window recall at 0.1 / 1 / 10 false windows a frame (diagnostic)")
    args = p.parse_args(argv)
    models: list[tuple[str, str]] = []
    for item in args.model:
        name, sep, path = item.partition("=")
        if not sep or not name or not Path(path).is_file():
            p.error(f"--model {item!r}: expected NAME=PATH of an existing model file")
        models.append((name, path))
    data = data_dir()
    clips = {c.name: c for c in annotated_clips(data)}
    want = args.clips.split(",") if args.clips else list(clips)
    for c in want:
        if c not in clips:
            p.error(f"not an annotated clip: {c}")
        if not (args.refine_loo / f"refine_without_{c}.npz").is_file():
            p.error(f"{args.refine_loo}/refine_without_{c}.npz missing")
    args.work.mkdir(parents=True, exist_ok=True)
    results_path = args.work / "feature_loo.json"
    results: dict[str, Any] = json.loads(results_path.read_text()) if results_path.is_file() else {}

    def save() -> None:  # merged into what is on disk: two runs may share a --work
        disk = json.loads(results_path.read_text()) if results_path.is_file() else {}
        for row, e in results.items():
            disk.setdefault(row, {}).update(e)
        write_bytes(results_path, json.dumps(disk, indent=1, sort_keys=True).encode())

    ref_neg = None
    if args.crop_rate:
        ref = cached_split_scores(models[0][0], load_model(models[0][1]), args.work, data)
        ref_neg = ref["scores"][ref["labels"] == 0]
    runs: list[tuple[str, str, str, dict[str, Any]]] = []  # (row name, model name, path, crop figures)
    for name, path in models:
        seq = load_model(path).metadata.get("training", {}).get("sequence_split", {})
        crop = {k: seq.get(k) for k in ("accuracy", "precision", "recall", "confusion")}
        crop["offset"] = 0.0
        runs.append((name, name, path, crop))
        if ref_neg is not None and name != models[0][0]:
            sp = cached_split_scores(name, load_model(path), args.work, data)
            neg, pos = sp["scores"][sp["labels"] == 0], sp["scores"][sp["labels"] == 1]
            delta = rate_offset(neg, ref_neg, 0.0) if args.crop_rule == "midpoint" else least_offset(neg, ref_neg)
            shifted = {"offset": delta, "fp": int((neg > delta).sum()), "recall": float((pos > delta).mean()),
                       "accuracy": float(((sp["scores"] > delta) == (sp["labels"] == 1)).mean())}
            if delta == 0.0:
                print(f"{name}: already at the reference's rate on the held-out non-vehicle crops (offset 0)")
                continue
            least = "" if args.crop_rule == "midpoint" else "_least"
            out = args.work / f"{name}_croprate{least}.npz"
            offset(load_model(path), delta, {"crop_rate": {"reference": models[0][0], "offset": delta,
                                                           "rule": args.crop_rule}}).save(out)
            runs.append((f"{name}, crop rate" + (" (least)" if least else ""), name, str(out), shifted))
    for row, name, path, crop in runs:
        entry = results.setdefault(row, {})
        entry["crop"] = crop
        entry["model"] = path
        if "cost" not in entry:
            entry["cost"] = cost(path)
        for c in [] if args.no_pipeline else want:
            key = f"clip:{c}"
            if key in entry and entry.get("model_key", {}).get(c) == model_key(path):
                continue
            held = PipelineConfig(model=path, refine_model=str(args.refine_loo / f"refine_without_{c}.npz"))
            entry[key] = summary_of(run_clip(clips[c], held))
            entry.setdefault("model_key", {})[c] = model_key(path)
            print(f"{row} {c}: {fmt_clip(entry[key])}", flush=True)
            save()
        for c in want if args.windows and ", crop rate" not in row else []:
            key = f"windows:{c}"
            if key in entry and entry.get("model_key", {}).get(key) == model_key(path):
                continue
            entry[key] = score_frames(load_model(path), read_annotated_frames(data, c)).to_dict()
            entry.setdefault("model_key", {})[key] = model_key(path)
            print(f"{row} {c}: window recall at 0.1 / 1 / 10 FW a frame "
                  f"{' / '.join(f'{v:.2f}' for v in entry[key]['recall_at'].values())}", flush=True)
            save()
        save()
    # the tables
    ref_cost = results[runs[0][0]]["cost"]
    head = ["model", *want, "leak-free crop acc / P / R (offset)", "features", "score MACs", "HOG ch-cells"]
    print("\n| " + " | ".join(head) + " |\n|" + "---|" * len(head))
    for row, _, _, crop in runs:
        e = results[row]
        cells = [row] + [fmt_clip(e[f"clip:{c}"]) if f"clip:{c}" in e else "-" for c in want]
        if "fp" not in crop:
            cells.append(f"{crop['accuracy']:.4f} / {crop['precision']:.4f} / {crop['recall']:.4f}")
        else:
            cells.append(f"{crop['accuracy']:.4f}, recall {crop['recall']:.4f}, FP {crop['fp']} "
                         f"(offset {crop['offset']:+.2f})")
        k = e["cost"]
        cells += [f"{k['features']:.0f}", f"{k['score_macs'] / ref_cost['score_macs']:.2f}x",
                  f"{k['hog_channel_cells'] / ref_cost['hog_channel_cells']:.2f}x"]
        print("| " + " | ".join(cells) + " |")
    if args.windows:
        print("\n| model (window recall at 0.1 / 1 / 10 false windows a frame) | " + " | ".join(want) + " |\n|"
              + "---|" * (len(want) + 1))
        for row, _, _, _ in runs:
            e = results[row]
            if ", crop rate" in row:
                continue
            print("| " + " | ".join([row] + [" / ".join(f"{v:.2f}" for v in e[f"windows:{c}"]["recall_at"].values())
                                             if f"windows:{c}" in e else "-" for c in want]) + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
