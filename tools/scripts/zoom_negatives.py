"""Scale-matched negatives for a wide-window model (run by hand).

The wide search looks at 64x24 windows at scales below 1 (40x15 px of the frame at scale
0.625), where the 64x64 non-vehicle crops, taken at about 64 px, never showed the model
that texture. This cuts ``--per-crop`` random sub-windows of ``64 s x 24 s`` px
(``s`` uniform in ``--scale``) out of every non-vehicle crop and resizes them to 64x24::

    python -m tools.scripts.zoom_negatives OUT_DIR [--per-crop 1] [--scale 0.55 0.9] [--limit N]

``fastdet train --window-rows 12 36 --negatives OUT_DIR`` then adds them.
"""
from __future__ import annotations

import argparse
from pathlib import Path

import cv2
import numpy as np

from fastdet.data import data_dir


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("out", type=Path)
    ap.add_argument("--per-crop", type=int, default=1)
    ap.add_argument("--scale", type=float, nargs=2, default=(0.55, 0.9), metavar=("LO", "HI"))
    ap.add_argument("--height", type=int, default=24, help="window height (width 64)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--limit", type=int, default=None, help="only the first N non-vehicle crops (a quick run)")
    args = ap.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    args.out.mkdir(parents=True, exist_ok=True)
    n = 0
    for path in sorted((data_dir() / "non-vehicles").glob("*/*.png"))[:args.limit]:
        img = cv2.imread(str(path))
        if img is None:
            continue
        for k in range(args.per_crop):
            s = rng.uniform(*args.scale)
            w, h = int(round(64 * s)), int(round(args.height * s))
            x, y = rng.integers(0, img.shape[1] - w + 1), rng.integers(0, img.shape[0] - h + 1)
            crop = cv2.resize(img[y: y + h, x: x + w], (64, args.height), interpolation=cv2.INTER_LINEAR)
            cv2.imwrite(str(args.out / f"{path.parent.name}_{path.stem}_{k}.png"), crop)
            n += 1
    print(f"wrote {n} crops to {args.out}")


if __name__ == "__main__":
    main()
