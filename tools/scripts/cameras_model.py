"""Build a picture model from the crop folders plus the teacher-labelled frames of many cameras
(issue 31), for the single-picture search (``fastdet image --model M.npz``); measured, not
shipped: docs/training.md "Learning from many cameras".

Training material: the data folder's 64x64 crops (``vehicles/``, ``non-vehicles/``) and every
teacher-labelled set of :func:`fastdet.labels.sets.shared_sets` (the 17 clips of ``teacher/``,
one camera each): positives around every teacher box, background and hard negatives (the
bundled model's false windows, then the next round's model's) from their frames
(:func:`fastdet.train.pictures.train_on_pictures`). Its operating point is set on the teacher
frames it did not train on (every other labelled frame of each clip is kept out; a third of
those are searched): the NMS score that gives the best F1 against the teacher's boxes there is
folded into the model (:func:`fastdet.train.blend.offset`), so ``PictureSearch.nms_min_score``
stays the one setting.
No human-labelled picture is used, so every human-labelled set and clip scores it as a camera
it never saw (``kitti_tiny`` excepted: the KITTI crops are that camera; the Udacity clips: the
``non-vehicles/Extras`` crops come from that drive).

Usage (from the repository root)::

    python -m tools.scripts.cameras_model --out pictures.npz [--rounds 2] [--data DIR] [--sets A,B] [--no-progress]

The command that made a model is in its metadata (``metadata["training"]["command"]``).
"""
from __future__ import annotations

import argparse
import shlex
import sys
import time
from pathlib import Path

from fastdet.data import data_dir
from fastdet.errors import FastdetError
from fastdet.labels.sets import shared_sets, teacher_sets
from fastdet.train.pictures import PictureRecipe, train_on_pictures

#: the NMS scores tried for the operating point (decision values)
SCORES = (2.0, 4.0, 6.0, 8.0, 10.0, 12.0)


def operating_point(model, held) -> tuple[object, dict]:
    """``model`` shifted so that ``PictureSearch().nms_min_score`` is the score of ``SCORES``
    with the best F1 against the teacher's boxes of ``held`` (pictures it did not train on),
    and what was measured."""
    from fastdet.config import PictureSearch
    from fastdet.eval.pictures import score_source
    from fastdet.labels.load import load_pictures
    from fastdet.train.blend import offset
    from fastdet.video.picture import PictureDetector

    det = PictureDetector(model, PictureSearch(nms_min_score=min(SCORES), verify=False))
    frames = list(load_pictures(held))
    windows = [det.windows(img) for _, img in frames]
    f1 = {}
    for s in SCORES:
        det.config = PictureSearch(nms_min_score=s, verify=False)
        preds = [det.boxes_from_windows(w) for w in windows]
        f1[str(s)] = round(score_source("held-out teacher frames", held, preds).f1, 4)
    best = max(SCORES, key=lambda s: f1[str(s)])
    delta = best - PictureSearch().nms_min_score
    return offset(model, delta), {"pictures": len(held), "f1": f1, "chosen": best, "offset": delta}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", type=Path, required=True, help="the model file to write (.npz + JSON metadata)")
    p.add_argument("--data", type=Path, default=None, help="data folder (default: $FASTDET_DATA or ../shared/data)")
    p.add_argument("--sets", help="only these teacher sets (comma-separated, e.g. teacher:tmo_night); default all")
    p.add_argument("--every-other", type=int, default=PictureRecipe.every_other,
                   help="keep one of every N labelled frames of a clip")
    p.add_argument("--rounds", type=int, default=PictureRecipe.rounds, help="rounds of hard negatives")
    p.add_argument("--max-per-folder", type=int, default=None, help="at most N crops a crop folder (quick runs)")
    p.add_argument("--no-progress", action="store_true")
    args = p.parse_args(argv)
    try:
        data = args.data or data_dir()
        sets = teacher_sets(shared_sets(data))
        if args.sets:
            want = [s.strip() for s in args.sets.split(",") if s.strip()]
            missing = [s for s in want if s not in sets]
            if missing:
                raise FastdetError(f"--sets: no teacher set {missing[0]!r} (there are {', '.join(sorted(sets))})")
            sets = {k: sets[k] for k in want}
        pictures = [pic for pics in sets.values() for pic in pics]
        t0 = time.perf_counter()
        recipe = PictureRecipe(every_other=args.every_other, rounds=args.rounds)
        model, report = train_on_pictures(data, pictures, recipe, progress=not args.no_progress,
                                          max_per_folder=args.max_per_folder)
        given = sys.argv[1:] if argv is None else argv
        report["command"] = "python -m tools.scripts.cameras_model " + shlex.join(given)
        report["sets"] = sorted(sets)
        held = [pic for pics in sets.values() for pic in pics[1::args.every_other][::3]]
        model, point = operating_point(model, held)
        report["operating_point"] = point
        model.metadata["training"] = report
        model.save(args.out)
        print(f"operating point: NMS score {point['chosen']:g} on {point['pictures']} held-out teacher frames "
              f"(F1 {point['f1'][str(point['chosen'])]:.3f} against the teacher)")
        print(f"wrote {args.out} ({time.perf_counter() - t0:.0f} s)")
        return 0
    except FastdetError as exc:
        print(f"cameras_model: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
