"""CPU of ``Detector.detect`` per frame with the default main search and with other bands
(run by hand; ``docs/geometry.md``).

Both detectors (the video pipeline's: main + oncoming model, full search) score the same
frames, alternating, ``--repeat`` times; prints the median CPU milliseconds per frame
(``time.process_time``: all threads) and the ratio.

    NUMBA_NUM_THREADS=1 python -m tools.studies.band_cost --bands 0.75:400:460,1:400:496,... [--clip test_small1]
"""
from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Collection, Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from fastdet.config import PipelineConfig, SearchBand
from fastdet.data import data_dir
from fastdet.detect import Detector, DetectStats
from fastdet.io.reader import read_frames
from fastdet.video import make_detector


def parse_bands(text: str) -> tuple[SearchBand, ...]:
    """``scale:y0:y1[:x0:x1],...`` (1280x720 reference pixels) as bands."""
    out = []
    for item in text.split(","):
        p = item.split(":")
        out.append(SearchBand(float(p[0]), int(p[1]), int(p[2]), int(p[3]) if len(p) > 3 else None,
                              int(p[4]) if len(p) > 4 else None))
    return tuple(out)


def scan_cost(det: Detector, shape: tuple[int, int] = (720, 1280), parts: Collection[int] | None = None,
              channels: bool = False) -> dict[str, float]:
    """HOG cells, windows and scoring multiply-adds of a full scan of a ``shape`` frame by every
    model of ``det`` (its bands at its searches' horizons); ``parts``: only these models' bands
    (``det.parts``; ``None``: all); ``channels``: HOG cells counted once per channel the model
    takes HOG of (channel-cells)."""
    cells = wins = macs = 0.0
    for p, scorer in zip(det.parts, det.scorers):
        if parts is not None and p not in parts:
            continue
        cfg = scorer.config
        per_cell = len(cfg.hog_channels) if channels else 1
        for g in det.geometries(shape, p):
            cells += (g.scaled_h // cfg.pixels_per_cell) * (g.scaled_w // cfg.pixels_per_cell) * per_cell
            wins += g.n_windows
            macs += g.n_windows * cfg.n_features
    return {"hog_cells": cells, "windows": wins, "score_macs": macs}


def count_scored(det: Detector) -> list[float]:
    """Make ``det.detect`` count the windows it scores: the returned list grows with every call
    to ``[main model's windows, every model's windows, scoring multiply-adds]`` (a window is
    scored where its decision value is finite; guided search and motion gate included)."""
    counts = [0.0, 0.0, 0.0]
    inner = det.detect
    features = {p: s.config.n_features for p, s in zip(det.parts, det.scorers)}

    def counting(frame, *args, stats=None, **kw):
        st = stats if stats is not None else DetectStats()
        out = inner(frame, *args, stats=st, **kw)
        for part, _, values in st.bands:
            n = int(np.isfinite(values).sum())
            counts[1] += n
            counts[0] += n if part == 0 else 0
            counts[2] += n * features[part]
        return out

    det.detect = counting  # type: ignore[method-assign]
    return counts


def detect_cpu_ms(detectors: Sequence[Any], frames: Sequence[np.ndarray], repeat: int) -> list[float]:
    """Median CPU milliseconds (``time.process_time``: all threads) of ``detect`` per frame of
    each detector: each warmed up on the first frames, then all of them over ``frames`` in turn,
    ``repeat`` times, so that a busy machine slows them alike."""
    for d in detectors:
        d.warmup()
        for f in frames[:3]:
            d.detect(f)
    ms: list[list[float]] = [[] for _ in detectors]
    for _ in range(repeat):
        for i, d in enumerate(detectors):
            t = time.process_time()
            for f in frames:
                d.detect(f)
            ms[i].append((time.process_time() - t) / len(frames) * 1e3)
    return [statistics.median(m) for m in ms]


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--bands", required=True, help="scale:y0:y1[:x0:x1],... (1280x720 reference pixels)")
    ap.add_argument("--clip", default="test_small1")
    ap.add_argument("--frames", type=int, default=20)
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    bands = parse_bands(args.bands)
    frames = read_frames(data_dir() / "videos" / f"{args.clip}.mp4", frames=args.frames)
    today = make_detector(PipelineConfig())
    other = make_detector(PipelineConfig(search=replace(PipelineConfig().search, bands=tuple(bands))))
    a, b = detect_cpu_ms([today, other], frames, args.repeat)
    print(f"default bands {a:.1f} ms/frame CPU, --bands {b:.1f} ms/frame CPU: {b / a:.2f}x "
          f"({args.frames} frames of {args.clip}, median of {args.repeat})")


if __name__ == "__main__":
    main()
