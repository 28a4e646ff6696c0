"""``python -m fastdet image INPUT.jpg -o OUT.jpg [--windows] [--heat] [--model M.npz] [--threshold T]``

Detects vehicles in one image: the positive windows of the Detector, then a single-frame
heat map (:class:`~fastdet.video.heatmap.HeatMap` with ``n_frames=1``) thresholded at
``HeatConfig.single_frame_threshold`` (or ``--threshold``), one box per blob, shape filter.
Draws the final boxes with their scores (peak heat); ``--windows`` also draws the positive
windows, coloured by search scale; ``--heat`` also writes the heat map as ``OUT.heat.jpg``
(same extension as OUT).

Outputs are written under a temporary name in the output folder (``.OUT.partial.jpg``)
and renamed when complete and readable, so a reader never sees half an image
(:func:`fastdet.io.images.write_image`: a full disk is reported as such). Bad input
(missing, unreadable or truncated image, a greyscale or too small picture, missing output
folder, an output extension OpenCV cannot write, a model that does not load) raises
:class:`~fastdet.errors.FastdetError`: one line, exit status 2, before any output exists.
"""
from __future__ import annotations

import argparse
import os
from pathlib import Path
from typing import Any

import cv2

from .._numba import ensure_compiled
from ..config import HeatConfig, PipelineConfig
from ..detect.checks import check_frame
from ..errors import DataError, FastdetError
from ..io import draw
from ..io.images import read_image, write_image
from ..io.paths import bundled_models, check_paths
from ..video.detector import detector_kernels, make_detector
from ..video.heatmap import KERNELS as HEAT_KERNELS
from ..video.heatmap import detect_image


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("input", metavar="INPUT.jpg", help="image file (anything cv2.imread reads)")
    parser.add_argument("-o", "--output", metavar="OUT.jpg", required=True, help="annotated image")
    parser.add_argument("--windows", action="store_true",
                        help="also draw the positive windows, coloured by search scale")
    parser.add_argument("--heat", action="store_true", help="also write the heat map as OUT.heat.jpg")
    parser.add_argument("--model", metavar="MODEL.npz", help="model file (default: the bundled model)")
    d = HeatConfig()
    parser.add_argument("--threshold", type=float, default=None, metavar="T",
                        help=f"heat a pixel needs to be part of a vehicle (default "
                             f"HeatConfig.single_frame_threshold = {d.single_frame_threshold})")


def heat_path(output: str | os.PathLike) -> Path:
    """Where ``--heat`` writes: ``OUT.heat.EXT`` beside ``OUT.EXT``."""
    p = Path(output)
    return p.with_name(f"{p.stem}.heat{p.suffix}")


def run(args: argparse.Namespace, detector: Any = None) -> int:
    """The ``image`` subcommand. ``detector`` replaces the model's Detector (tests)."""
    inp = args.input
    if not os.path.exists(inp):
        raise DataError(f"{inp}: file not found")
    if os.path.isdir(inp):
        raise DataError(f"{inp}: is a folder, not an image")
    out = Path(args.output)
    hout = heat_path(out) if args.heat else None
    check_paths([("INPUT", inp), ("--model", args.model), *bundled_models()],
                [("-o", out, "image"), ("--heat", hout, "image")])
    for p in (out, hout):
        if p is not None and not cv2.haveImageWriter(str(p)):
            raise DataError(f"{p}: cannot write an image there (extension {p.suffix or '(none)'!r} "
                            f"not supported? use .jpg or .png)")
    try:
        heat = HeatConfig().single_frame(args.threshold)
    except ValueError as exc:
        raise FastdetError(f"--threshold: {exc}") from None
    frame = read_image(inp)
    if detector is None:
        detector = make_detector(PipelineConfig(model=args.model, oncoming=False))  # its gate needs motion: video only
    elif args.model is not None:
        raise FastdetError("--model cannot be used with an injected detector")
    check_frame(detector, frame, inp)
    # every kernel the image needs at once (on a first run on every core, after saying so)
    ensure_compiled((*detector_kernels(detector), *HEAT_KERNELS))
    detector.warmup()

    windows, hm, boxes = detect_image(frame, detector, heat)
    img = frame.copy()
    if args.windows:
        draw.draw_windows(img, windows, 1)
    draw.draw_boxes(img, boxes.boxes, boxes.scores, thickness=3)
    write_image(out, img)
    written = [str(out)]
    if hout is not None:
        himg = draw.grid_to_frame(draw.heat_image(hm.heat, vmax=max(2.0 * heat.threshold, float(hm.heat.max()))),
                                  heat.cell, frame.shape)
        draw.draw_boxes(himg, boxes.boxes, None, thickness=2)
        write_image(hout, himg)
        written.append(str(hout))
    print(f"fastdet image: {len(boxes.boxes)} vehicle(s) from {len(windows.boxes)} positive window(s); "
          f"wrote {', '.join(written)}")
    return 0
