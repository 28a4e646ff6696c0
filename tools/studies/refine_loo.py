"""The box regressor fitted leave-one-clip-out on every annotated clip (run by hand;
docs/geometry.md "Small vehicles").

For each annotated clip E of ``$FASTDET_DATA`` (the two Udacity clips and the keyframe clips),
a regressor (:mod:`fastdet.train.refine`, the features and sampling of
:mod:`tools.scripts.refine_model`) is fitted on the annotated vehicles (``consider = 1``) of
every *other* clip -- keyframes only for a keyframe clip -- and the six test images, and the
default pipeline (or the settings of :mod:`tools.studies.small_boxes`) runs on E with it: E is
scored only by a regressor that never saw it. Prints the per-clip table of
``fastdet eval --all`` and the box measurements of :mod:`tools.studies.small_boxes`.

    python -m tools.studies.refine_loo [--out-dir DIR [--reuse]] [--clips A,B] [--jitter-scale LO HI]
        [--jitter-aspect A] [small_boxes options, e.g. --refine iterations=3]

``--ship PATH --ship-without CLIP`` then fits one regressor on every clip but CLIP (default
``test_small1``, so that ``fastdet eval`` on it stays a held-out figure) and writes it to
PATH with the leave-one-clip-out figures of this run in its metadata
(``leave_one_clip_out``). On the other clips ``fastdet eval`` with that regressor is
in-sample: their honest figures are this study's. The optional
``fastdet/models/refine_cameras.npz`` is made so (``--refine iterations=3 --ship``;
docs/geometry.md "Small vehicles and box formation").
"""
from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from fastdet.config import JitterConfig
from fastdet.detections import Detections
from fastdet.eval.clips import AnnotatedClip, annotated_clips, markdown_table, score_clip
from fastdet.io.reader import FrameReader
from fastdet.train.refine import collect_samples
from tools.scripts.refine_model import Annotated, add_feature_arguments, fit_box_regressor, spec_of, test_images

from .small_boxes import add_setting_arguments, config_from, fa_summary, measure, print_tables, run_clip, summary


def clip_vehicles(clip: AnnotatedClip, index: int) -> Annotated:
    """``(frame, vehicle boxes (M, 4), groups (M,))`` of every frame of ``clip`` with a
    ``consider = 1`` box (keyframes only, for a keyframe clip); groups from ``1000 * (index + 1)``
    plus the vehicle's id, so one vehicle's samples stay in one CV fold."""
    gt, kf = clip.gt(), clip.keyframes()
    want = set(int(f) for f in np.unique(gt.frames[gt.consider]))
    if kf is not None:
        want &= set(int(f) for f in kf)
    out = []
    reader = FrameReader(str(clip.video), notify=lambda _n: None)
    try:
        for fno, frame, _ in reader:
            if fno in want:
                sel = (gt.frames == fno) & gt.consider
                out.append((frame, gt.boxes[sel], 1000 * (index + 1) + gt.ids[sel]))
    finally:
        reader.close()
    return out


def fit_without(clips: list[AnnotatedClip], vehicles: dict[str, Annotated], held_out: str, a: argparse.Namespace,
                path: Path, metadata: dict[str, Any] | None = None) -> None:
    """Fit a regressor on every clip but ``held_out`` (and the test images) and save it to ``path``."""
    spec = spec_of(a)
    train = [v for c in clips if c.name != held_out for v in vehicles[c.name]]
    names = [c.name for c in clips if c.name != held_out]
    jitter = JitterConfig(per_box=a.per_box, scale=(a.jitter_scale[0], a.jitter_scale[1]), aspect=a.jitter_aspect)
    smp = collect_samples(train + test_images(), spec, seed=a.seed, jitter=jitter)
    reg = fit_box_regressor(smp, spec, metadata={
        "trained_on": names + ["test_images"], "held_out_clip": held_out,
        "command": "python -m tools.studies.refine_loo " + " ".join(sys.argv[1:]), **(metadata or {})})
    reg.save(path)
    fit = reg.metadata["fit"]
    print(f"{path}: without {held_out}: {fit['samples']} samples of {fit['groups']} vehicles, alpha {fit['alpha']:g}, "
          f"CV mean IoU {max(fit['cv_mean_iou']):.3f}", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out-dir", default=None, help="where the regressors go (default: a temporary folder)")
    ap.add_argument("--clips", default=None, help="held-out clips to score (default: every annotated clip)")
    ap.add_argument("--ship", default=None,
                    help="after the measurement, fit on every clip but --ship-without and write it here, with the "
                         "leave-one-clip-out figures in its metadata")
    ap.add_argument("--ship-without", default="test_small1")
    ap.add_argument("--reuse", action="store_true", help="use the regressors already in --out-dir (same options)")
    ap.add_argument("--jitter-scale", type=float, nargs=2, default=JitterConfig().scale, metavar=("LO", "HI"),
                    help="size factors of the training boxes about each vehicle (default: JitterConfig's)")
    ap.add_argument("--jitter-aspect", type=float, default=JitterConfig().aspect,
                    help="largest |log| aspect change of the training boxes (default: JitterConfig's)")
    add_feature_arguments(ap)
    add_setting_arguments(ap)
    a = ap.parse_args()
    out_dir = Path(a.out_dir or tempfile.mkdtemp(prefix="refine_loo_"))
    out_dir.mkdir(parents=True, exist_ok=True)
    clips = annotated_clips()
    vehicles: dict[str, Annotated] = {}

    def fit(held_out: str, path: Path, metadata: dict[str, Any] | None = None) -> None:
        if not vehicles:
            vehicles.update({c.name: clip_vehicles(c, i) for i, c in enumerate(clips)})
        fit_without(clips, vehicles, held_out, a, path, metadata)

    held = [c for c in clips if a.clips is None or c.name in a.clips.split(",")]
    scores, tables, fa_lines = [], [], []
    for clip in held:
        path = out_dir / f"refine_without_{clip.name}.npz"
        if not (a.reuse and path.is_file()):
            fit(clip.name, path)
        a.refine_model = str(path)
        config = config_from(a)
        frames, rec, rows, _ = run_clip(clip, config)
        preds = Detections.from_frames(frames, source=str(clip.video))
        scores.append(score_clip(clip.name, clip.gt(), preds, rows, clip.keyframes()))
        m = measure(clip, rec, rows, int(config.heat.cell))
        tables += summary(clip.name, m)
        fa_lines.append(fa_summary(clip.name, m, len(rec)))
    print(markdown_table(scores))
    print_tables(tables, fa_lines)
    if a.ship:
        keys = ("precision", "recall", "f1", "ap", "fp_per_frame", "tp", "fp")
        loo = {s.name: {k: s.result.to_dict()[k] for k in keys} for s in scores}
        refine = config_from(a).refine
        fit(a.ship_without, Path(a.ship), {"leave_one_clip_out": loo,
                                           "refine_config": None if refine is None else refine.to_dict()})


if __name__ == "__main__":
    main()
