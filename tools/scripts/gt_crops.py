"""Cut annotated boxes out of a clip as training crops (run by hand).

For every ``consider`` box of a MOTChallenge ground-truth file within a frame range (and
narrower than ``--max-width``), writes ``--jitter`` crops: the box's centre and width with
small random shifts and scale changes, the window's aspect ratio (``--height`` of 64), resized
to 64 x height. ``fastdet train --positives DIR`` then adds them as vehicles. Usage::

    python -m tools.scripts.gt_crops CLIP.mp4 CLIP.gt.txt OUT_DIR --frames 1 66 --height 24
"""
from __future__ import annotations

import argparse
from pathlib import Path

import cv2
import numpy as np

from fastdet.io.motfiles import read_gt


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("video", type=Path)
    ap.add_argument("gt", type=Path)
    ap.add_argument("out", type=Path)
    ap.add_argument("--frames", type=int, nargs=2, default=(1, 10 ** 9), metavar=("FIRST", "LAST"))
    ap.add_argument("--height", type=int, default=24, help="crop height (width 64)")
    ap.add_argument("--max-width", type=float, default=100.0)
    ap.add_argument("--jitter", type=int, default=8, help="crops per box (the first unjittered)")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    gt = read_gt(args.gt)
    args.out.mkdir(parents=True, exist_ok=True)
    cap = cv2.VideoCapture(str(args.video))  # a video, or an image sequence such as test%d.jpg
    stem = args.video.stem.replace("%", "")
    rng = np.random.default_rng(args.seed)
    i = n = 0
    while True:
        ok, frame = cap.read()
        if not ok:
            break
        i += 1
        if not args.frames[0] <= i <= args.frames[1]:
            continue
        sel = (gt.frames == i) & gt.consider
        for x1, y1, x2, y2 in gt.boxes[sel]:
            w, h = x2 - x1, y2 - y1
            if w > args.max_width:
                continue
            for k in range(args.jitter):
                dx, dy, ds = (0.0, 0.0, 1.0) if k == 0 else (rng.normal(0, 0.06), rng.normal(0, 0.08),
                                                             float(np.exp(rng.normal(0, 0.08))))
                cx, cy = (x1 + x2) / 2 + dx * w, (y1 + y2) / 2 + dy * h
                ww = w * ds
                hh = ww * args.height / 64
                a, b = int(round(cx - ww / 2)), int(round(cy - hh / 2))
                a2, b2 = int(round(cx + ww / 2)), int(round(cy + hh / 2))
                if a < 0 or b < 0 or a2 > frame.shape[1] or b2 > frame.shape[0]:
                    continue
                crop = cv2.resize(frame[b:b2, a:a2], (64, args.height), interpolation=cv2.INTER_AREA)
                cv2.imwrite(str(args.out / f"{stem}_f{i:05d}_{n}.png"), crop)
                n += 1
    print(f"wrote {n} crops to {args.out}")


if __name__ == "__main__":
    main()
