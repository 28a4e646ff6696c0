"""Training augmentation for known failures of the detector: cut cars, compression.

Truncated crops (:func:`truncate`): a car cut by the left or right image border. The
detector runs windows up to half a window past the frame edge, the missing columns filled by
replicating the frame's edge column (``SearchConfig.border``, ``border_mode='replicate'``,
:func:`fastdet.detect.bands.scaled_band`). A truncated copy is what such a window shows: the
crop cut at a column, the cut-off side filled with the last kept column, exactly
``np.pad(crop[:, :k], ..., mode='edge')`` (or its mirror for a cut on the left).

Re-encoded crops (:func:`reencode`): the artefacts of compressed video (OpenCV's mp4v and
MJPG writers, x264). Each copy is blown up by a random factor (a car in a frame is larger
than the 64-px window it is scored in), JPEG-encoded at a random quality (8x8 DCT blocks,
4:2:0 chroma), decoded and scaled back with ``INTER_AREA`` as the detector's band scaling
would; then mildly blurred and shifted by a few grey levels in brightness and chroma.

:func:`augmented_copies` draws the copies for a data set: which crops, and every random
choice, come from one ``numpy`` generator seeded by the training seed, so a run is
deterministic. Each copy remembers the crop it came from (``source``), so a split adds only
the copies of its *training* crops and its test figures stay comparable.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

#: smallest fraction of the crop's columns a truncated copy keeps (at least half the car)
MIN_KEEP = 0.5
#: largest fraction kept (at least one HOG cell's width is cut off)
MAX_KEEP = 0.875
#: JPEG qualities of the re-encoded copies (a random one in ``[lo, hi]``)
JPEG_QUALITY = (30, 90)
#: the copy is blown up by a random factor in ``[1, MAX_UPSCALE]`` before it is encoded
MAX_UPSCALE = 2.0
#: largest Gaussian blur sigma (pixels of the 64-px crop); the sigma is uniform in ``[0, this]``
MAX_BLUR = 0.7
#: largest brightness / chroma shift in grey levels (uniform integer in ``[-this, this]``)
MAX_SHIFT = 2

def truncate(crop: np.ndarray, keep: int, side: str) -> np.ndarray:
    """``crop`` (``(H, W, C) uint8``) with the columns beyond ``keep`` cut off on ``side``
    (``'right'``: columns ``[keep, W)`` lost, as for a car cut by the right frame edge;
    ``'left'``: columns ``[0, W - keep)``) and filled by repeating the last kept column, as
    the detector pads a window over the frame edge. Same shape and dtype."""
    w = crop.shape[1]
    if not 1 <= keep <= w:
        raise ValueError(f"keep must be in 1..{w}, got {keep}")
    if side == "right":
        return np.pad(crop[:, :keep], ((0, 0), (0, w - keep), (0, 0)), mode="edge")
    if side == "left":
        return np.pad(crop[:, w - keep:], ((0, 0), (w - keep, 0), (0, 0)), mode="edge")
    raise ValueError(f"side must be 'left' or 'right', got {side!r}")


def truncate_batch(images: np.ndarray, rng: np.random.Generator, min_keep: float = MIN_KEEP,
                   max_keep: float = MAX_KEEP) -> np.ndarray:
    """A truncated copy of every image (``(N, H, W, 3) uint8``): a random side, and a random
    number of kept columns in ``[ceil(min_keep W), floor(max_keep W)]``."""
    n, _, w = images.shape[:3]
    lo, hi = int(np.ceil(min_keep * w)), int(np.floor(max_keep * w))
    if not 1 <= lo <= hi <= w:
        raise ValueError(f"need 0 < min_keep <= max_keep <= 1 with a whole column between, got {min_keep}, {max_keep}")
    keeps = rng.integers(lo, hi + 1, n)
    sides = rng.integers(0, 2, n)
    out = np.empty_like(images)
    for i in range(n):
        out[i] = truncate(images[i], int(keeps[i]), "left" if sides[i] else "right")
    return out


@dataclass(frozen=True)
class ReencodeParams:
    """One re-encoded copy's random choices."""

    upscale: float
    quality: int
    blur: float
    brightness: int
    cr: int
    cb: int


def reencode(crop: np.ndarray, p: ReencodeParams) -> np.ndarray:
    """``crop`` (``(H, W, 3) uint8`` BGR) through the steps of the module docstring."""
    h, w = crop.shape[:2]
    img = crop
    if p.upscale > 1.0:
        img = cv2.resize(img, (round(w * p.upscale), round(h * p.upscale)), interpolation=cv2.INTER_LINEAR)
    ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, int(p.quality)])
    if not ok:  # pragma: no cover - OpenCV always encodes a uint8 BGR image
        raise RuntimeError("JPEG encoding failed")
    img = cv2.imdecode(buf, cv2.IMREAD_COLOR)
    if img.shape[:2] != (h, w):
        img = cv2.resize(img, (w, h), interpolation=cv2.INTER_AREA)
    if p.blur > 0:
        img = cv2.GaussianBlur(img, (0, 0), p.blur)
    if p.brightness or p.cr or p.cb:
        ycc = cv2.cvtColor(img, cv2.COLOR_BGR2YCrCb).astype(np.int16)
        ycc += np.array([p.brightness, p.cr, p.cb], np.int16)
        img = cv2.cvtColor(np.clip(ycc, 0, 255).astype(np.uint8), cv2.COLOR_YCrCb2BGR)
    return np.ascontiguousarray(img)


def reencode_params(rng: np.random.Generator, n: int, quality: tuple[int, int] = JPEG_QUALITY,
                    max_upscale: float = MAX_UPSCALE, max_blur: float = MAX_BLUR,
                    max_shift: int = MAX_SHIFT) -> list[ReencodeParams]:
    q0, q1 = quality
    if not 1 <= q0 <= q1 <= 100:
        raise ValueError(f"JPEG qualities must satisfy 1 <= Q1 <= Q2 <= 100, got {q0} {q1}")
    up = rng.uniform(1.0, max_upscale, n)
    q = rng.integers(q0, q1 + 1, n)
    blur = rng.uniform(0.0, max_blur, n)
    shifts = rng.integers(-max_shift, max_shift + 1, (n, 3))
    return [ReencodeParams(float(up[i]), int(q[i]), float(blur[i]), *(int(s) for s in shifts[i])) for i in range(n)]


def reencode_batch(images: np.ndarray, rng: np.random.Generator, quality: tuple[int, int] = JPEG_QUALITY) -> np.ndarray:
    """A re-encoded copy of every image (``(N, H, W, 3) uint8``)."""
    out = np.empty_like(images)
    for i, p in enumerate(reencode_params(rng, len(images), quality)):
        out[i] = reencode(images[i], p)
    return out


@dataclass(frozen=True)
class Augmented:
    """Augmented copies: ``images (M, H, W, 3) uint8``, ``labels (M,)``, ``source (M,)``: the
    index of the crop each copy was made from."""

    images: np.ndarray
    labels: np.ndarray
    source: np.ndarray

    def __len__(self) -> int:
        return len(self.labels)

    def in_training(self, train_idx: np.ndarray) -> np.ndarray:
        """Indices of the copies whose source crop is in ``train_idx``."""
        return np.flatnonzero(np.isin(self.source, train_idx))


def _pick(labels: np.ndarray, fraction: float, rng: np.random.Generator, which: tuple[int, ...]) -> np.ndarray:
    """``fraction`` of the crops of each label in ``which`` (rounded), chosen at random,
    in index order."""
    if not 0 <= fraction <= 1:
        raise ValueError(f"an augmentation fraction must be in [0, 1], got {fraction}")
    out = []
    for lab in which:
        members = np.flatnonzero(labels == lab)
        k = round(fraction * len(members))
        out.append(rng.choice(members, k, replace=False) if k else np.zeros(0, np.int64))
    return np.sort(np.concatenate(out)).astype(np.int64)


def augmented_copies(images: np.ndarray, labels: np.ndarray, seed: int, truncate_fraction: float = 0.0,
                     truncate_negatives: bool = True, reencode_fraction: float = 0.0,
                     jpeg_quality: tuple[int, int] = JPEG_QUALITY,
                     keep: tuple[float, float] = (MIN_KEEP, MAX_KEEP)) -> Augmented:
    """Truncated copies of ``truncate_fraction`` of the vehicle crops (and as many of the
    non-vehicle crops, with ``truncate_negatives``, so the padding itself is no sign of a
    vehicle) and re-encoded copies of ``reencode_fraction`` of the crops of both labels.
    Deterministic for ``seed`` (each kind draws from its own generator, so adding one kind leaves
    the others' copies as they were)."""
    parts_img, parts_src = [], []
    if truncate_fraction > 0:
        rng = np.random.default_rng([seed, 12])
        src = _pick(labels, truncate_fraction, rng, (1, 0) if truncate_negatives else (1,))
        parts_img.append(truncate_batch(images[src], rng, *keep))
        parts_src.append(src)
    if reencode_fraction > 0:
        rng = np.random.default_rng([seed, 14])
        src = _pick(labels, reencode_fraction, rng, (1, 0))
        parts_img.append(reencode_batch(images[src], rng, jpeg_quality))
        parts_src.append(src)
    if not parts_src:
        return Augmented(np.zeros((0, *images.shape[1:]), images.dtype), np.zeros(0, labels.dtype),
                         np.zeros(0, np.int64))
    source = np.concatenate(parts_src)
    return Augmented(np.concatenate(parts_img), labels[source], source)
