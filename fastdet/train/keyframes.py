"""Training crops cut from annotated video frames: positives around the hand-read vehicle
boxes, negatives where no box is.

An annotated clip is ``videos/CLIP.mp4`` with ``annotations/CLIP.gt.txt`` (MOTChallenge
lines, see the data README); when ``annotations/CLIP.frames`` exists, only the frames it
lists are annotated (a *keyframe* clip) and nothing is learnt from the others -- a frame
without box lines there has no vehicle. A fully annotated clip gives every ``every``-th
frame (its hand-read frames are every 5th; the others are interpolated).

Windows of a model are ``win_w x win_h`` pixels (:class:`~fastdet.config.FeatureConfig`).
A vehicle box becomes a positive crop through :func:`window_around`: the box grown to the
window's aspect ratio (the short side grows, centred) and then by ``margin`` of its size on
every side, as the data set's crops frame their cars; parts past the frame edge are the
edge pixels repeated. Negatives never touch an annotated box, target or ignore region alike
(a far-away or half-hidden vehicle is not a negative).
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from ..boxes import intersection
from ..errors import DataError
from ..io.reader import FrameReader, read_frames_at


@dataclass(frozen=True)
class AnnotatedFrame:
    """One annotated frame: ``image (H, W, 3) uint8`` BGR; ``targets (N, 4)`` and
    ``ignores (M, 4)`` float64 boxes ``x1, y1, x2, y2`` (frame pixels); ``frame`` 1-based."""

    clip: str
    frame: int
    image: np.ndarray
    targets: np.ndarray
    ignores: np.ndarray

    @property
    def boxes(self) -> np.ndarray:
        """Every annotated box, targets then ignore regions: ``(N + M, 4)``."""
        return np.concatenate([self.targets, self.ignores])


def annotated_frame_numbers(data: Path, clip: str, every: int = 5) -> list[int]:
    """The frames of ``clip`` to learn from (1-based): those of ``annotations/CLIP.frames``,
    or for a fully annotated clip every ``every``-th frame from 1 up to its last box line."""
    ann = Path(data) / "annotations"
    gt = ann / f"{clip}.gt.txt"
    if not gt.is_file():
        raise DataError(f"{gt}: no ground truth for clip {clip!r}")
    listed = ann / f"{clip}.frames"
    if listed.is_file():
        return sorted({int(v) for v in listed.read_text().split()})
    rows = np.loadtxt(gt, delimiter=",", ndmin=2)
    return list(range(1, int(rows[:, 0].max()) + 1, max(1, int(every))))


def read_annotated_frames(data: Path, clip: str, every: int = 5) -> list[AnnotatedFrame]:
    """The frames :func:`annotated_frame_numbers` names, decoded
    (:func:`~fastdet.io.reader.read_frames_at`), with their boxes. A video that ends before
    its last annotated frame is a :class:`~fastdet.errors.DataError`."""
    data = Path(data)
    rows = np.loadtxt(data / "annotations" / f"{clip}.gt.txt", delimiter=",", ndmin=2)
    wanted = annotated_frame_numbers(data, clip, every)
    video = data / "videos" / f"{clip}.mp4"
    images = read_frames_at(video, wanted)
    if len(images) != len(wanted):
        raise DataError(f"{video}: ends after {_frames_in(video)} frames, before annotated frame {max(wanted)}")
    out = []
    for n in wanted:
        r = rows[rows[:, 0] == n]
        xyxy = np.c_[r[:, 2], r[:, 3], r[:, 2] + r[:, 4], r[:, 3] + r[:, 5]].reshape(-1, 4)
        out.append(AnnotatedFrame(clip, n, images[n], xyxy[r[:, 6] == 1], xyxy[r[:, 6] == 0]))
    return out


def _frames_in(video: Path) -> int:
    """The number of the last frame of ``video`` that decodes (for the message of a video
    shorter than its annotation; decodes it again)."""
    with FrameReader(video, notify=lambda _: None) as reader:
        return max((number for number, _, _ in reader), default=0)


def window_around(box: np.ndarray, win_w: int, win_h: int, margin: float) -> np.ndarray:
    """``(4,)`` float64: ``box`` grown to the aspect ``win_w / win_h`` (its short side, centred)
    and then by ``margin`` x its grown size on each side."""
    x1, y1, x2, y2 = (float(v) for v in box)
    w, h = x2 - x1, y2 - y1
    aspect = win_w / win_h
    if w / h < aspect:
        w = h * aspect
    else:
        h = w / aspect
    w, h = w * (1 + 2 * margin), h * (1 + 2 * margin)
    cx, cy = (x1 + x2) / 2, (y1 + y2) / 2
    return np.array([cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2])


def cut(image: np.ndarray, box: np.ndarray, win_w: int, win_h: int) -> np.ndarray:
    """The pixels of ``box`` (frame pixels, may run past the edge: edge pixels repeated)
    resized to ``(win_h, win_w, 3)`` with ``INTER_AREA``."""
    h, w = image.shape[:2]
    x1, y1, x2, y2 = (int(round(v)) for v in box)
    pad = max(0, -x1, -y1, x2 - w, y2 - h)
    src = image
    if pad:
        src = cv2.copyMakeBorder(image, pad, pad, pad, pad, cv2.BORDER_REPLICATE)
    crop = src[y1 + pad: y2 + pad, x1 + pad: x2 + pad]
    if crop.shape[0] < 2 or crop.shape[1] < 2:
        raise ValueError(f"box {box} is too small to cut")
    return cv2.resize(crop, (win_w, win_h), interpolation=cv2.INTER_AREA)


def aspect_of(boxes: np.ndarray) -> np.ndarray:
    """Width over height of ``(N, 4)`` boxes."""
    boxes = np.asarray(boxes, np.float64).reshape(-1, 4)
    return (boxes[:, 2] - boxes[:, 0]) / np.maximum(boxes[:, 3] - boxes[:, 1], 1e-9)


def positive_crops(frames: Sequence[AnnotatedFrame], win_w: int, win_h: int,
                   aspect_range: tuple[float, float] = (0.0, np.inf), min_width: float = 0.0,
                   margin: float = 0.0625, jitter: int = 0, shift: float = 0.05, zoom: float = 0.1,
                   seed: int = 0) -> np.ndarray:
    """``(N, win_h, win_w, 3) uint8``: one crop per target whose aspect (w / h) is in
    ``[aspect_range[0], aspect_range[1])`` and whose width is at least ``min_width`` x the
    frame width (:func:`window_around`), plus ``jitter`` copies each moved by up to ``shift``
    of the window size and rescaled by up to ``1 +- zoom`` (uniform, seeded)."""
    rng = np.random.default_rng(seed)
    out = []
    for f in frames:
        fw = f.image.shape[1]
        a = aspect_of(f.targets)
        for box, asp in zip(f.targets, a):
            if not aspect_range[0] <= asp < aspect_range[1] or box[2] - box[0] < min_width * fw:
                continue
            win = window_around(box, win_w, win_h, margin)
            out.append(cut(f.image, win, win_w, win_h))
            ww, wh = win[2] - win[0], win[3] - win[1]
            for _ in range(jitter):
                dx, dy = rng.uniform(-shift, shift, 2) * (ww, wh)
                s = rng.uniform(1 - zoom, 1 + zoom)
                cx, cy = (win[0] + win[2]) / 2 + dx, (win[1] + win[3]) / 2 + dy
                out.append(cut(f.image, np.array([cx - s * ww / 2, cy - s * wh / 2, cx + s * ww / 2, cy + s * wh / 2]),
                               win_w, win_h))
    return np.stack(out) if out else np.zeros((0, win_h, win_w, 3), np.uint8)


def background_crops(frames: Sequence[AnnotatedFrame], win_w: int, win_h: int, per_frame: int,
                     widths: tuple[float, float] = (0.05, 0.4), seed: int = 0, tries: int = 50) -> np.ndarray:
    """``(N, win_h, win_w, 3) uint8``: up to ``per_frame`` windows of the model's aspect per
    frame at random places inside the frame, ``widths`` (fractions of the frame width, drawn
    log-uniformly) wide, touching no annotated box (targets and ignore regions)."""
    rng = np.random.default_rng(seed)
    out = []
    for f in frames:
        h, w = f.image.shape[:2]
        boxes = f.boxes
        got = 0
        for _ in range(per_frame * tries):
            if got >= per_frame:
                break
            bw = w * np.exp(rng.uniform(np.log(widths[0]), np.log(widths[1])))
            bh = bw * win_h / win_w
            if bw >= w or bh >= h:
                continue
            x1, y1 = rng.uniform(0, w - bw), rng.uniform(0, h - bh)
            win = np.array([x1, y1, x1 + bw, y1 + bh])
            if len(boxes) and np.any(intersection(win[None], boxes) > 0):
                continue
            out.append(cut(f.image, win, win_w, win_h))
            got += 1
    return np.stack(out) if out else np.zeros((0, win_h, win_w, 3), np.uint8)


def false_window_crops(frames: Sequence[AnnotatedFrame], windows: Sequence[np.ndarray], win_w: int,
                       win_h: int, limit: int | None = None, seed: int = 0) -> np.ndarray:
    """Hard negatives: ``(N, win_h, win_w, 3) uint8``, the boxes of ``windows[i]`` (``(K, 4)``
    positive windows a model gave on ``frames[i]``) that touch no annotated box, cut and
    resized; at most ``limit`` per frame (a seeded random choice)."""
    clear = []
    for f, wins in zip(frames, windows):
        wins = np.asarray(wins, np.float64).reshape(-1, 4)
        boxes = f.boxes
        if len(boxes) and len(wins):
            wins = wins[~np.any(intersection(wins, boxes) > 0, axis=1)]
        clear.append(wins)
    return window_crops(frames, clear, win_w, win_h, limit, seed)


def window_crops(frames: Sequence[AnnotatedFrame], windows: Sequence[np.ndarray], win_w: int, win_h: int,
                 limit: int | None = None, seed: int = 0) -> np.ndarray:
    """``(N, win_h, win_w, 3) uint8``: the boxes ``windows[i]`` (``(K, 4)``) of ``frames[i]``
    at least 8 x 4 pixels, whatever they touch, cut and resized; at most ``limit`` per frame
    (a seeded random choice)."""
    rng = np.random.default_rng(seed)
    out = []
    for f, wins in zip(frames, windows):
        wins = np.asarray(wins, np.float64).reshape(-1, 4)
        wins = wins[(wins[:, 2] - wins[:, 0] >= 8) & (wins[:, 3] - wins[:, 1] >= 4)]
        if limit is not None and len(wins) > limit:
            wins = wins[rng.choice(len(wins), limit, replace=False)]
        out += [cut(f.image, b, win_w, win_h) for b in wins]
    return np.stack(out) if out else np.zeros((0, win_h, win_w, 3), np.uint8)
