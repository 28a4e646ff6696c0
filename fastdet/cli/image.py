"""``python -m fastdet image PATH... [--boxes OUT.csv] [-o OUT_DIR] [--no-refine] [--no-progress]``

Finds the vehicles of single pictures: the whole picture searched at every scale
(:class:`~fastdet.config.PictureSearch`, :class:`~fastdet.video.picture.PictureDetector`:
the boxes :func:`fastdet.detect_picture` gives). PATH is an image file or a folder, searched
recursively for pictures (``.jpg .jpeg .png .bmp .tif .tiff .webp``), sorted by relative name.

Outputs:

- ``--boxes OUT.csv``: a header line ``image,x1,y1,x2,y2,score``, then one line a box; ``image``
  is the file name relative to the folder given (or the file name as given for a file);
  pixels, ``x2, y2`` exclusive; score: the box verifier's decision value, higher is more
  certain (:mod:`fastdet.detect.verifier`; with ``--no-refine``, the window's).
- ``-o OUT_DIR``: the annotated pictures, under the same relative names (the folder is made; a
  file given with an absolute path or ``..`` goes there under its base name).
- The single-file form of earlier versions, ``image IN.jpg -o OUT.jpg`` (one input file and an
  ``-o`` with an extension that is not an existing folder), writes that one annotated picture.

``--windows`` also draws the positive windows, coloured by scale.

Reliability: bad input (a missing path, a folder without pictures, a model that does not load,
an unwritable output, two inputs with one name) is one line, exit 2, before any output exists.
A picture that does not decode (or is too small for the smallest window, or is not a regular
file: a named pipe, a symlink loop, a dangling link with a picture's name in a folder) in a run
of several is skipped with one note on stderr naming it; the other pictures are processed and written, and the
command exits with status 1 at the end ("N of M pictures skipped"). With one input picture it
is an error (exit 2, no output). The box file is written under a temporary name and renamed
when complete; annotated pictures each through :func:`fastdet.io.images.write_image`. A stop
signal (Ctrl-C, SIGTERM, SIGHUP) stops after the current picture: the pictures written so far
stay, the box file is not written (it would be incomplete), exit 128 + signal.
"""
from __future__ import annotations

import argparse
import io
import os
import sys
from pathlib import Path
from typing import Any

import cv2

from .._numba import ensure_compiled
from ..config import PictureSearch
from ..config.picture import FIRST_STAGE_ONLY
from ..detect.checks import check_colour
from ..errors import DataError, FastdetError
from ..io import draw
from ..io.atomic import folder_writable, write_bytes
from ..io.files import not_found
from ..io.images import read_image, write_image
from ..io.paths import bundled_models, check_output, check_paths

#: file extensions taken from a folder
IMAGE_EXTENSIONS = (".jpg", ".jpeg", ".png", ".bmp", ".tif", ".tiff", ".webp")
#: exit status of a run that skipped pictures that do not decode
SKIPPED_EXIT = 1


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("inputs", nargs="+", metavar="PATH", help="image files or folders (searched recursively)")
    parser.add_argument("--boxes", metavar="OUT.csv", help="one line a box: image,x1,y1,x2,y2,score (with a header)")
    parser.add_argument("-o", "--output", metavar="OUT_DIR",
                        help="write the annotated pictures into this folder (same relative names); "
                             "IN.jpg -o OUT.jpg with one input file: that one annotated picture")
    parser.add_argument("--windows", action="store_true",
                        help="also draw the positive windows, coloured by search scale")
    parser.add_argument("--model", metavar="MODEL.npz", help="model file (default: the bundled model)")
    parser.add_argument("--no-refine", action="store_true",
                        help="the first stage alone: no box refinement and no verifier (windows above "
                             "decision value 2 after NMS, as found)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


def collect(inputs: list[str]) -> list[tuple[str, Path]]:
    """``(name, path)`` of every picture of ``inputs`` (module docstring); DataError for a
    missing path, a folder without pictures or two pictures of one name."""
    out: list[tuple[str, Path]] = []
    for inp in inputs:
        p = Path(inp)
        if not p.exists():
            raise not_found(p, f"{inp}: file not found")
        if p.is_dir():
            # every entry with a picture's name but a folder: a named pipe, a symlink loop, a
            # dangling link are taken too, and skipped by name when read (read_image's line)
            found = sorted((f.relative_to(p).as_posix(), f) for f in p.rglob("*")
                           if f.suffix.lower() in IMAGE_EXTENSIONS and not f.is_dir())
            if not found:
                raise DataError(f"{inp}: no pictures in this folder ({' '.join(IMAGE_EXTENSIONS)})")
            out += found
        else:
            out.append((inp, p))
    seen: dict[str, Path] = {}
    for name, path in out:
        if name in seen:
            raise DataError(f"two pictures are named {name} ({seen[name]} and {path}): give them in separate runs")
        seen[name] = path
    return out


def out_name(name: str) -> str:
    """Where a picture named ``name`` goes in ``-o OUT_DIR``: ``name`` itself when it is a
    relative path inside the folder (no ``..``), else its base name (a file given as
    ``/abs/x.jpg`` or ``../x.jpg`` goes to ``OUT_DIR/x.jpg``)."""
    p = Path(name)
    return p.name if p.is_absolute() or ".." in p.parts else p.as_posix()


def _legacy(args: argparse.Namespace) -> bool:
    """The single-file form: one input file and an ``-o`` with an extension that is not a folder."""
    return (args.output is not None and len(args.inputs) == 1 and not os.path.isdir(args.inputs[0])
            and Path(args.output).suffix != "" and not os.path.isdir(args.output))


def run(args: argparse.Namespace, detector: Any = None) -> int:
    """The ``image`` subcommand. ``detector`` replaces the :class:`PictureDetector` (tests)."""
    from .. import signals
    from ..video.picture import PictureDetector
    from ..video.run import progress_bar

    legacy = _legacy(args)
    if args.boxes is None and args.output is None:
        raise FastdetError("give --boxes OUT.csv and/or -o OUT_DIR")
    pictures = collect(list(args.inputs))
    out_dir = None if legacy or args.output is None else Path(args.output)
    check_paths([*(("PATH", str(p)) for _, p in pictures), ("--model", args.model), *bundled_models()],
                [("--boxes", args.boxes, "box"), ("-o", args.output if legacy else None, "image")])
    if legacy and not cv2.haveImageWriter(str(args.output)):
        p = Path(args.output)
        raise DataError(f"{p}: cannot write an image there (extension {p.suffix or '(none)'!r} "
                        f"not supported? use .jpg or .png)")
    if out_dir is not None:
        if out_dir.exists() and not out_dir.is_dir():
            raise DataError(f"-o {out_dir}: is a file; give a folder for the annotated pictures")
        if out_dir.is_dir():
            if not folder_writable(out_dir):
                raise DataError(f"-o {out_dir}: the folder is not writable")
        else:
            check_output(out_dir, "folder", "-o")  # its parent exists and is writable
        outs: dict[str, str] = {}
        for name, _ in pictures:
            if out_name(name) in outs:
                raise DataError(f"-o: {outs[out_name(name)]} and {name} would both be written as {out_name(name)}")
            outs[out_name(name)] = name
            if not cv2.haveImageWriter(str(out_dir / out_name(name))):
                raise DataError(f"-o: cannot write {name} as an image (extension not supported)")
        inputs = {os.path.realpath(p) for _, p in pictures}
        for name, _ in pictures:
            if os.path.realpath(out_dir / out_name(name)) in inputs:
                raise DataError(f"-o {out_dir}: would overwrite the input {name}; give another folder")
    config = FIRST_STAGE_ONLY if args.no_refine else PictureSearch()
    first = read_image(pictures[0][1]) if len(pictures) == 1 else None  # one picture: its errors are errors
    if detector is None:
        detector = PictureDetector(args.model, config)
    elif args.model is not None:
        raise FastdetError("--model cannot be used with an injected detector")
    if first is not None:
        try:
            detector.detector(first.shape)
        except ValueError as exc:
            raise DataError(f"{pictures[0][0]}: {exc}") from None
    ensure_compiled(detector.kernels)

    csv = io.StringIO()
    csv.write("image,x1,y1,x2,y2,score\n")
    skipped: list[str] = []
    n_boxes = 0
    bar = progress_bar(len(pictures), not args.no_progress, "image")
    bar.unit = "picture"
    try:
        for name, path in pictures:
            try:
                img = first if first is not None else read_image(path)
                check_colour(detector.detector(img.shape), img, str(path))
                windows = detector.windows(img)
            except (DataError, ValueError) as exc:
                if len(pictures) == 1:
                    raise DataError(str(exc)) from None
                msg = str(exc) if str(exc).startswith(str(path)) else f"{name}: {exc}"
                print(f"fastdet image: note: skipped {msg}", file=sys.stderr, flush=True)
                skipped.append(name)
                bar.update(1)
                continue
            boxes = detector.second_stage(img, detector.boxes_from_windows(windows))
            n_boxes += len(boxes)
            for b, s in zip(boxes.boxes, boxes.scores):
                csv.write(f"{name},{int(b[0])},{int(b[1])},{int(b[2])},{int(b[3])},{float(s):.4f}\n")
            if args.output is not None:
                out = Path(args.output) if legacy else Path(args.output) / out_name(name)
                ann = img.copy()
                if args.windows:
                    draw.draw_windows(ann, windows, 1)
                draw.draw_boxes(ann, boxes.boxes, boxes.scores, thickness=3)
                out.parent.mkdir(parents=True, exist_ok=True)
                write_image(out, ann)
            bar.update(1)
            signals.check()
    finally:
        bar.close()
    if args.boxes is not None:
        write_bytes(args.boxes, csv.getvalue().encode())
    done = len(pictures) - len(skipped)
    wrote = [w for w in (args.boxes, args.output) if w is not None]
    print(f"fastdet image: {n_boxes} vehicle(s) in {done} picture(s); wrote {', '.join(map(str, wrote))}")
    if skipped:
        print(f"fastdet image: {len(skipped)} of {len(pictures)} picture(s) skipped (they do not decode, are "
              f"too small or are not regular files): {', '.join(skipped[:5])}{' ...' if len(skipped) > 5 else ''}",
              file=sys.stderr)
        return SKIPPED_EXIT
    return 0
