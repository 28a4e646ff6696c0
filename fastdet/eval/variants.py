"""Camera-shift variants of an annotated clip: frames and ground truth transformed together.

fastdet's annotated clips come from one camera. To see how the detector fares on another
one without new footage, :class:`Variant` makes a transformed copy of each frame and
moves the ground truth with the pixels (:func:`transform_gt`). A variant is a sequence of
geometric steps, applied in order:

- :class:`Resize` ``(W, H)``: another resolution (``cv2.INTER_AREA`` when shrinking,
  ``INTER_LINEAR`` when enlarging). Boxes scale by ``W / w`` and ``H / h``.
- :class:`Zoom` ``z``: a wider lens. The picture shrinks by ``z`` about the frame centre
  into a canvas of the same size; the border it leaves is filled by replicating the
  picture's edge pixels (no invented cars; a reflection would add unannotated ones).
- :class:`ShiftY` ``f``: the horizon moved. The picture moves down by ``f`` x the frame
  height (up when ``f < 0``), the rows it uncovers are filled by replication.
- :class:`Crop` ``(left, right)``: columns cut off both sides (fractions of the width): a
  narrower field of view, and cars cut by the image border.
- :class:`Mirror`: flipped left-right (traffic on the other side of the road).

Re-encoding (``Variant.codec``) changes pixels only; the tool that runs the suite
(``tools/studies/camera_shift.py``) does it, since it needs an encoder.

Ground-truth rules (:func:`transform_gt`), the annotation rules of ``../shared/data``
re-applied to the transformed picture:

- A box is moved with the pixels (continuous coordinates, ``x2 = left + width``) and clipped
  to the part of the output frame that holds picture (not the replicated fill). A box with
  nothing left is dropped.
- A target (``consider = 1``) stays a target when at least ``min_visible`` (0.5) of its
  transformed area is left after clipping and its clipped width is at least ``min_width``
  (40) **reference pixels**: pixels of the same frame scaled to ``ref_rows`` = 720 rows
  (for a 16:9 frame, the "1280-wide pixels" the annotations were counted in). A resolution
  change keeps every target a target; a wider lens makes small cars ignore regions, as an
  annotator of that footage would have. Otherwise it becomes an ignore region.
- Ignore regions stay ignore regions.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import cv2
import numpy as np

from ..detections import Detections

#: rows of the reference frame the annotation rules are stated in (1280x720)
REF_ROWS = 720
#: narrowest target in reference pixels (the annotations' rule)
MIN_TARGET_WIDTH = 40.0
#: smallest visible fraction of a target (the annotations' rule)
MIN_VISIBLE = 0.5


def _rect(a: float, b: float, c: float, d: float) -> np.ndarray:
    return np.array([a, b, c, d], np.float64)


@dataclass(frozen=True)
class Resize:
    """Scale the whole frame to ``width`` x ``height`` pixels."""

    width: int
    height: int

    def out_shape(self, shape: tuple[int, int]) -> tuple[int, int]:
        return (self.height, self.width)

    def frame(self, img: np.ndarray) -> np.ndarray:
        h, w = img.shape[:2]
        if (h, w) == (self.height, self.width):
            return img
        interp = cv2.INTER_AREA if self.width < w else cv2.INTER_LINEAR
        return cv2.resize(img, (self.width, self.height), interpolation=interp)

    def boxes(self, b: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
        h, w = shape
        return b * np.array([self.width / w, self.height / h] * 2)


@dataclass(frozen=True)
class Zoom:
    """Shrink the picture by ``factor`` (0 < factor <= 1) about the frame centre into a canvas
    of the same size; the border is the picture's edge replicated."""

    factor: float

    def __post_init__(self) -> None:
        if not 0 < self.factor <= 1:
            raise ValueError(f"zoom factor must be in (0, 1], got {self.factor}")

    def out_shape(self, shape: tuple[int, int]) -> tuple[int, int]:
        return shape

    def _place(self, shape: tuple[int, int]) -> tuple[int, int, int, int]:
        h, w = shape
        pw, ph = max(1, round(w * self.factor)), max(1, round(h * self.factor))
        return pw, ph, (w - pw) // 2, (h - ph) // 2

    def frame(self, img: np.ndarray) -> np.ndarray:
        h, w = img.shape[:2]
        pw, ph, ox, oy = self._place((h, w))
        small = cv2.resize(img, (pw, ph), interpolation=cv2.INTER_AREA)
        return cv2.copyMakeBorder(small, oy, h - ph - oy, ox, w - pw - ox, cv2.BORDER_REPLICATE)

    def boxes(self, b: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
        h, w = shape
        pw, ph, ox, oy = self._place(shape)
        return b * np.array([pw / w, ph / h] * 2) + np.array([ox, oy] * 2)


@dataclass(frozen=True)
class ShiftY:
    """Move the picture down by ``fraction`` x the frame height (up when negative); the rows
    uncovered are the picture's edge row replicated."""

    fraction: float

    def __post_init__(self) -> None:
        if not -1 < self.fraction < 1:
            raise ValueError(f"shift fraction must be in (-1, 1), got {self.fraction}")

    def out_shape(self, shape: tuple[int, int]) -> tuple[int, int]:
        return shape

    def rows(self, shape: tuple[int, int]) -> int:
        """The shift in pixels (positive: down)."""
        return round(self.fraction * shape[0])

    def frame(self, img: np.ndarray) -> np.ndarray:
        h = img.shape[0]
        dy = self.rows(img.shape[:2])
        if dy > 0:
            return cv2.copyMakeBorder(img[: h - dy], dy, 0, 0, 0, cv2.BORDER_REPLICATE)
        if dy < 0:
            return cv2.copyMakeBorder(img[-dy:], 0, -dy, 0, 0, cv2.BORDER_REPLICATE)
        return img

    def boxes(self, b: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
        return b + np.array([0, self.rows(shape)] * 2)


@dataclass(frozen=True)
class Crop:
    """Cut ``left`` and ``right`` (fractions of the width) off the sides of the frame."""

    left: float = 0.0
    right: float = 0.0

    def __post_init__(self) -> None:
        if self.left < 0 or self.right < 0 or self.left + self.right >= 1:
            raise ValueError(f"crop fractions must be >= 0 and leave some width, got {self.left}, {self.right}")

    def _cols(self, w: int) -> tuple[int, int]:
        return round(self.left * w), w - round(self.right * w)

    def out_shape(self, shape: tuple[int, int]) -> tuple[int, int]:
        a, b = self._cols(shape[1])
        return (shape[0], b - a)

    def frame(self, img: np.ndarray) -> np.ndarray:
        a, b = self._cols(img.shape[1])
        return np.ascontiguousarray(img[:, a:b])

    def boxes(self, b: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
        a, _ = self._cols(shape[1])
        return b - np.array([a, 0] * 2)


@dataclass(frozen=True)
class Mirror:
    """Flip the frame left-right."""

    def out_shape(self, shape: tuple[int, int]) -> tuple[int, int]:
        return shape

    def frame(self, img: np.ndarray) -> np.ndarray:
        return np.ascontiguousarray(img[:, ::-1])

    def boxes(self, b: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
        w = shape[1]
        return np.stack([w - b[:, 2], b[:, 1], w - b[:, 0], b[:, 3]], axis=1)


Step = Resize | Zoom | ShiftY | Crop | Mirror


@dataclass(frozen=True)
class Variant:
    """A named camera shift: geometric ``steps`` applied in order, then an optional re-encode.

    codec: ``None``, ``'x264'`` (libx264 at ``crf``) or ``'mp4v'`` (OpenCV's MPEG-4 writer);
        applied by whoever writes the frames (``tools/studies/camera_shift.py``), not here.
    """

    name: str
    steps: tuple[Step, ...] = ()
    codec: str | None = None
    crf: int = 23

    def __post_init__(self) -> None:
        object.__setattr__(self, "steps", tuple(self.steps))
        if self.codec not in (None, "x264", "mp4v"):
            raise ValueError(f"codec must be None, 'x264' or 'mp4v', got {self.codec!r}")

    def out_shape(self, shape: tuple[int, int]) -> tuple[int, int]:
        """``(H, W)`` of the variant of a frame of ``shape``."""
        s = (int(shape[0]), int(shape[1]))
        for st in self.steps:
            s = st.out_shape(s)
        return s

    def frame(self, img: np.ndarray) -> np.ndarray:
        """The variant of one frame (``(H, W, 3) uint8``, any channel order)."""
        for st in self.steps:
            img = st.frame(img)
        return np.ascontiguousarray(img)

    def boxes(self, boxes: np.ndarray, shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
        """``(moved, region)``: ``boxes (N, 4) x1, y1, x2, y2`` of a frame of ``shape`` moved
        with the pixels (not clipped), and the rectangle of the output frame that holds
        picture (the frame less the replicated fill), ``(4,) float64``."""
        b = np.asarray(boxes, np.float64).reshape(-1, 4)
        s = (int(shape[0]), int(shape[1]))
        region = _rect(0, 0, s[1], s[0])
        for st in self.steps:
            b = st.boxes(b, s)
            r = st.boxes(region[None], s)[0]
            s = st.out_shape(s)
            region = np.array([max(r[0], 0), max(r[1], 0), min(r[2], s[1]), min(r[3], s[0])])
        return b, region


def transform_gt(gt: Detections, variant: Variant, shape: tuple[int, int], min_width: float = MIN_TARGET_WIDTH,
                 min_visible: float = MIN_VISIBLE, ref_rows: int = REF_ROWS) -> Detections:
    """The ground truth of ``variant`` of a clip whose frames have ``shape = (H, W)`` (module
    docstring: moved, clipped to the picture, the annotation rules re-applied)."""
    moved, region = variant.boxes(gt.boxes.astype(np.float64), shape)
    clipped = np.stack([np.clip(moved[:, 0], region[0], region[2]), np.clip(moved[:, 1], region[1], region[3]),
                        np.clip(moved[:, 2], region[0], region[2]), np.clip(moved[:, 3], region[1], region[3])], 1)
    cw, ch = clipped[:, 2] - clipped[:, 0], clipped[:, 3] - clipped[:, 1]
    keep = (cw > 0) & (ch > 0)
    full = np.maximum((moved[:, 2] - moved[:, 0]) * (moved[:, 3] - moved[:, 1]), 1e-12)
    visible = cw * ch / full
    ref_w = cw * ref_rows / variant.out_shape(shape)[0]
    tol = 1e-9  # a resize must not turn a 40.0-px car into 39.999...
    consider = gt.targets & (visible >= min_visible - tol) & (ref_w >= min_width - tol)
    return replace(gt[keep], boxes=clipped[keep], consider=consider[keep], source=f"{gt.source}#{variant.name}")


@dataclass(frozen=True)
class SuiteSpec:
    """Parameters of :func:`standard_variants` (defaults: the camera-shift suite of docs/accuracy.md)."""

    resolutions: tuple[tuple[int, int], ...] = ((960, 540), (640, 360), (1920, 1080))
    zooms: tuple[float, ...] = (0.8, 0.6)
    shift: float = 0.1
    crops_right: tuple[float, ...] = (0.125, 0.25)
    codecs: tuple[str, ...] = ("x264", "mp4v")
    extra: tuple[Variant, ...] = field(default=())


def standard_variants(spec: SuiteSpec | None = None) -> list[Variant]:
    """The camera-shift suite: the original, other resolutions, wider lenses, the horizon
    moved up and down, the right side cut off (a car cut by the border: 12.5% cuts the
    nearest car of ``test_video``, 25% the car ahead in ``test_small1``), mirrored, re-encoded."""
    spec = spec if spec is not None else SuiteSpec()
    out = [Variant("original")]
    out += [Variant(f"{w}x{h}", (Resize(w, h),)) for w, h in spec.resolutions]
    out += [Variant(f"wide{z:g}", (Zoom(z),)) for z in spec.zooms]
    out += [Variant("horizon_up", (ShiftY(-spec.shift),)), Variant("horizon_down", (ShiftY(spec.shift),))]
    out += [Variant(f"cut_right{round(c * 100)}", (Crop(0.0, c),)) for c in spec.crops_right]
    out.append(Variant("mirror", (Mirror(),)))
    out += [Variant(c, codec=c) for c in spec.codecs]
    return out + list(spec.extra)
