"""Build the box verifier of the single-picture search (``fastdet/models/verifier.npz``,
:mod:`fastdet.detect.verifier`) from the data folder's teacher-labelled frames: the 17 clips of
``teacher/`` (17 cameras; no human label, so every human picture set and clip may score it).

The first stage is the picture search with the bundled main model and box regressor and no
verifier (``PictureSearch(nms_min_score=..., verify=False)``); its boxes on every teacher frame
are labelled against the teacher's boxes and fitted (:func:`fastdet.train.verifier.fit_verifier`:
operating point by the cascade rule on cameras held out of the fit).

Usage (from the repository root)::

    python -m tools.scripts.verifier_model [--out fastdet/models/verifier.npz] [--data DIR]
        [--every K] [--clips A,B,...] [--first-stage S] [--C C] [--keep F] [--no-score-input]
        [--model M.npz] [--refine-model R.npz]

``--model`` and ``--refine-model`` give the first stage other files than the bundled main model
and box regressor (``tools/scripts/rebuild_models.py`` passes the ones it has just built).

The bundled verifier is built with the defaults (every teacher frame; about 30 minutes on a
loaded 2-core machine, most of it the picture search); the command that made it is in its
metadata (``metadata["command"]``) with the held-out figures (``metadata["training"]``).
"""
from __future__ import annotations

import argparse
import hashlib
import shlex
import sys
import time
from pathlib import Path

from fastdet.config import PictureSearch
from fastdet.data import data_dir
from fastdet.errors import FastdetError
from fastdet.labels.sets import shared_sets, teacher_sets
from fastdet.train.verifier import VerifierRecipe, collect, fit_verifier, load_candidates, save_candidates
from fastdet.video.picture import PictureDetector
from fastdet.video.run import progress_bar


def _digest(path: Path) -> str:
    """SHA-256 of a file's bytes (``FastdetError`` when it cannot be read)."""
    try:
        return hashlib.sha256(path.read_bytes()).hexdigest()
    except OSError as exc:
        raise FastdetError(f"{path}: cannot read it ({exc.strerror or exc})") from None


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", type=Path, default=Path("fastdet/models/verifier.npz"))
    p.add_argument("--data", type=Path, default=None, help="data folder (default: $FASTDET_DATA or ../shared/data)")
    p.add_argument("--every", type=int, default=1, help="every K-th teacher frame of each clip (default 1: all)")
    p.add_argument("--clips", default=None, help="only these teacher clips (comma-separated names)")
    p.add_argument("--first-stage", type=float, default=0.0, metavar="S",
                   help="decision value a window needs to become a first-stage box (default 0)")
    d = VerifierRecipe()
    p.add_argument("--C", type=float, default=d.C, help=f"inverse regularisation (default {d.C})")
    p.add_argument("--keep", type=float, default=d.keep_fraction,
                   help=f"share of the first stage's matching boxes kept on held-out cameras "
                        f"(default {d.keep_fraction})")
    p.add_argument("--folds", type=int, default=d.folds, help=f"groups of held-out cameras (default {d.folds})")
    p.add_argument("--no-score-input", action="store_true", help="appearance only, not the first stage's score")
    p.add_argument("--cache", type=Path, default=None, metavar="C.npz",
                   help="keep the first stage's boxes here and reuse them when the settings are the same "
                        "(to refit with another --C or --keep in seconds)")
    p.add_argument("--model", type=Path, default=None,
                   help="the first stage's main model file (default: the bundled one)")
    p.add_argument("--refine-model", type=Path, default=None,
                   help="the first stage's box regressor file (default: the bundled one)")
    p.add_argument("--no-progress", action="store_true")
    args = p.parse_args(argv)
    command = "python -m tools.scripts.verifier_model " + shlex.join(argv if argv is not None else sys.argv[1:])
    try:
        if args.every < 1:
            raise FastdetError(f"--every must be >= 1, got {args.every}")
        recipe = VerifierRecipe(C=args.C, keep_fraction=args.keep, folds=args.folds,
                                score_input=not args.no_score_input)
        search = PictureSearch(nms_min_score=args.first_stage, verify=False)
        sets = teacher_sets(shared_sets(args.data or data_dir()))
        if args.clips is not None:
            want = {f"teacher:{c.strip()}" for c in args.clips.split(",") if c.strip()}
            missing = sorted(w.split(":", 1)[1] for w in want - set(sets))
            if missing:
                raise FastdetError(f"--clips: no teacher clip {', '.join(missing)}")
            sets = {k: v for k, v in sets.items() if k in want}
        pictures = [pic for pics in sets.values() for pic in pics[::args.every]]
        if not pictures:
            raise FastdetError("no teacher-labelled frames in the data folder (teacher/CLIP.teacher.txt)")
        key: dict = {"first_stage": search.to_dict(), "pictures": [f"{p.source}:{p.name}" for p in pictures]}
        # another model or regressor than the bundled one: a cache of other boxes (the bundled
        # files' caches keep the key they had)
        key.update({k: _digest(f) for k, f in (("model", args.model), ("refine_model", args.refine_model))
                    if f is not None})
        t0 = time.perf_counter()
        cands = load_candidates(args.cache, key) if args.cache is not None else None
        if cands is None:
            first = PictureDetector(args.model, search, refine_model=args.refine_model)
            with progress_bar(len(pictures), not args.no_progress, "first stage") as bar:
                cands = collect(pictures, first.detect, tick=lambda: bar.update(1))
            if args.cache is not None:
                save_candidates(args.cache, cands, key)
        t1 = time.perf_counter()
        verifier, report = fit_verifier(cands, recipe, {
            "command": command, "first_stage": search.to_dict(), "pictures": len(pictures),
            "sources": sorted(sets)})
        t2 = time.perf_counter()
        verifier.metadata["seconds"] = {"first_stage": round(t1 - t0, 1), "fit": round(t2 - t1, 1)}
        verifier.save(args.out)
    except (FastdetError, ValueError) as exc:
        print(f"verifier_model: {exc}", file=sys.stderr)
        return 2
    print(f"verifier_model: {len(pictures)} frames of {len(sets)} cameras, {report['boxes']} first-stage boxes "
          f"({report['positives']} match a teacher box, {report['negatives']} match none); threshold "
          f"{report['threshold']:.3f} keeps {report['held_out_positives_kept']:.3f} of the matching boxes and "
          f"passes {report['held_out_negatives_passed']:.3f} of the others on held-out cameras "
          f"({t1 - t0:.0f} s first stage, {t2 - t1:.0f} s fit); wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
