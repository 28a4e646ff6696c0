"""Build the main model from the crop folders plus the teacher-labelled frames of many cameras
(issue 31): ``fastdet/models/default.npz`` when given ``--out fastdet/models/default.npz``.

Training material: the data folder's 64x64 crops (``vehicles/``, ``non-vehicles/``) and every
teacher-labelled set of :func:`fastdet.labels.sets.shared_sets` (the 17 clips of ``teacher/``,
one camera each): positives around every teacher box, background and hard negatives (the
bundled model's false windows) from their frames (:func:`fastdet.train.pictures.train_on_pictures`).
No human-labelled picture is used, so every human-labelled set and clip scores it as a camera
it never saw (``kitti_tiny`` excepted: the KITTI crops are that camera; the Udacity clips: the
``non-vehicles/Extras`` crops come from that drive).

Usage (from the repository root)::

    python -m tools.scripts.cameras_model --out my_cameras.npz [--data DIR] [--sets A,B] [--no-progress]

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


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", type=Path, required=True, help="the model file to write (.npz + JSON metadata)")
    p.add_argument("--data", type=Path, default=None, help="data folder (default: $FASTDET_DATA or ../shared/data)")
    p.add_argument("--sets", help="only these teacher sets (comma-separated, e.g. teacher:tmo_night); default all")
    p.add_argument("--every-other", type=int, default=PictureRecipe.every_other,
                   help="keep one of every N labelled frames of a clip")
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
        model, report = train_on_pictures(data, pictures, PictureRecipe(every_other=args.every_other),
                                          progress=not args.no_progress)
        given = sys.argv[1:] if argv is None else argv
        report["command"] = "python -m tools.scripts.cameras_model " + shlex.join(given)
        report["sets"] = sorted(sets)
        model.save(args.out)
        print(f"wrote {args.out} ({time.perf_counter() - t0:.0f} s)")
        return 0
    except FastdetError as exc:
        print(f"cameras_model: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
