"""Drawing helpers: boxes with scores, windows coloured by scale, heat maps, debug panels.

Every function takes and returns BGR ``uint8`` images (OpenCV order). Functions named
``draw_*`` draw in place and return the same array; the others return new images.

The number drawn on a vehicle's box (``python -m fastdet image``; beside the ``#id`` of the
``video --debug`` overlay) is its score, the *peak heat* of its heat-map blob (about 6 to 100
with the defaults; :class:`~fastdet.detections.Detections`), not a probability; the plain
``video`` overlay labels a box with its track id ``#id`` only.
"""
from __future__ import annotations

import math
from collections import deque
from typing import Sequence

import cv2
import numpy as np

from ..detections import Detections

BOX_COLOR = (0, 255, 0)  # final boxes: green
TEXT_COLOR = (255, 255, 255)
PANEL_BORDER = (255, 255, 255)

# scale → colour: log-scale position between these two scales on the JET colour map, so a
# given scale has the same colour in every frame whatever other scales fired.
_SCALE_LO, _SCALE_HI = 1.0, 3.0
_JET = cv2.applyColorMap(np.arange(256, dtype=np.uint8).reshape(-1, 1), cv2.COLORMAP_JET).reshape(256, 3)
# label colours: a fixed, well-spread palette (golden-angle hues)
_PALETTE = cv2.cvtColor(
    np.array([[[(i * 137.508) % 180, 200, 255] for i in range(64)]], np.uint8), cv2.COLOR_HSV2BGR
).reshape(64, 3)


def scale_color(scale: float) -> tuple[int, int, int]:
    """BGR colour of windows of ``scale``: blue (scale 1 and below) → red (scale 3 and above)."""
    s = max(float(scale), 1e-6)
    t = (math.log(s) - math.log(_SCALE_LO)) / (math.log(_SCALE_HI) - math.log(_SCALE_LO))
    b, g, r = _JET[int(round(min(max(t, 0.0), 1.0) * 255))]
    return int(b), int(g), int(r)


def label_color(label: int) -> tuple[int, int, int]:
    """BGR colour of blob ``label`` (1-based) from a fixed palette."""
    b, g, r = _PALETTE[(int(label) - 1) % len(_PALETTE)]
    return int(b), int(g), int(r)


def draw_boxes(img: np.ndarray, boxes: np.ndarray, scores: np.ndarray | None = None,
               color: tuple[int, int, int] = BOX_COLOR, thickness: int = 2,
               fmt: str = "{:.1f}", scale: float = 1.0) -> np.ndarray:
    """Draw ``x1, y1, x2, y2`` (exclusive) boxes, with ``scores`` as labels above them when given
    (for vehicle boxes the peak heat of their blob, for windows the model's score: the
    module docstring).

    ``scale`` multiplies the coordinates first (to draw on a resized image)."""
    boxes = np.asarray(boxes).reshape(-1, 4)
    font_scale = 0.5 if img.shape[0] >= 360 else 0.35
    for i, b in enumerate(boxes):
        x1, y1, x2, y2 = (int(round(v * scale)) for v in b)
        cv2.rectangle(img, (x1, y1), (max(x1, x2 - 1), max(y1, y2 - 1)), color, thickness)
        if scores is not None:
            text = fmt.format(float(scores[i]))
            (tw, th), base = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, font_scale, 1)
            ty = y1 - 3 if y1 - th - 4 >= 0 else y1 + th + 3
            cv2.rectangle(img, (x1, ty - th - 2), (x1 + tw + 2, ty + base - 1), color, -1)
            cv2.putText(img, text, (x1 + 1, ty), cv2.FONT_HERSHEY_SIMPLEX, font_scale,
                        (0, 0, 0), 1, cv2.LINE_AA)
    return img


#: frames of a track's trail (its box centres) drawn behind it
TRAIL_LENGTH = 20


class Trails:
    """The last ``length`` box centres of each track id, for :func:`draw_tracks`.

    ``update(dets)`` once per frame with that frame's :class:`Detections` (``ids`` set); a
    track not seen for ``length`` frames is forgotten."""

    def __init__(self, length: int = TRAIL_LENGTH) -> None:
        self.length = int(length)
        self._pts: dict[int, deque[tuple[int, int]]] = {}
        self._seen: dict[int, int] = {}
        self._frame = 0

    def update(self, dets: Detections) -> None:
        self._frame += 1
        if dets.ids is not None:
            for b, i in zip(dets.boxes, dets.ids):
                if i < 1:
                    continue
                pts = self._pts.setdefault(int(i), deque(maxlen=self.length))
                pts.append((int(b[0] + b[2]) // 2, int(b[1] + b[3]) // 2))
                self._seen[int(i)] = self._frame
        for i in [i for i, f in self._seen.items() if self._frame - f >= self.length]:
            del self._pts[i], self._seen[i]

    def points(self, track_id: int) -> list[tuple[int, int]]:
        """The centres of ``track_id``, oldest first (empty when unknown)."""
        return list(self._pts.get(int(track_id), ()))


def draw_tracks(img: np.ndarray, dets: Detections, trails: Trails | None = None,
                scores: bool = False, thickness: int = 2) -> np.ndarray:
    """Draw tracked boxes, each in the colour of its id (:func:`label_color`) with the label
    ``#id`` (and its score, the blob's peak heat, with ``scores``: ``#3 41.5``), and the trail
    of its recent centres (thicker towards now). Rows with id < 1 are drawn as :func:`draw_boxes` draws them."""
    ids = dets.ids if dets.ids is not None else np.full(len(dets), -1, np.int64)
    font_scale = 0.5 if img.shape[0] >= 360 else 0.35
    for b, s, i in zip(dets.boxes, dets.scores, ids):
        if i < 1:
            draw_boxes(img, b[None], [s], thickness=thickness)
            continue
        color = label_color(int(i))
        if trails is not None:
            pts = trails.points(int(i))
            for k in range(1, len(pts)):
                cv2.line(img, pts[k - 1], pts[k], color, max(1, thickness * k // len(pts)), cv2.LINE_AA)
        x1, y1, x2, y2 = (int(v) for v in b)
        cv2.rectangle(img, (x1, y1), (max(x1, x2 - 1), max(y1, y2 - 1)), color, thickness)
        text = f"#{int(i)}" + (f" {float(s):.1f}" if scores else "")
        (tw, th), base = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, font_scale, 1)
        ty = y1 - 3 if y1 - th - 4 >= 0 else y1 + th + 3
        cv2.rectangle(img, (x1, ty - th - 2), (x1 + tw + 2, ty + base - 1), color, -1)
        cv2.putText(img, text, (x1 + 1, ty), cv2.FONT_HERSHEY_SIMPLEX, font_scale, (0, 0, 0), 1, cv2.LINE_AA)
    return img


def draw_track_states(img: np.ndarray, tracks: Sequence[tuple[int, str, np.ndarray]]) -> np.ndarray:
    """Debug view of the tracker: every live track's predicted box (thin), labelled with its
    id (``?`` while tentative) and state (``tracked``, ``lost``, ``tentative``)."""
    for tid, state, box in tracks:
        color = label_color(tid) if tid >= 1 else (200, 200, 200)
        x1, y1, x2, y2 = (int(round(v)) for v in box)
        cv2.rectangle(img, (x1, y1), (max(x1, x2 - 1), max(y1, y2 - 1)), color, 1)
        text = f"{tid if tid >= 1 else '?'} {state}"
        cv2.putText(img, text, (x1, y2 + 12), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 0, 0), 3, cv2.LINE_AA)
        cv2.putText(img, text, (x1, y2 + 12), cv2.FONT_HERSHEY_SIMPLEX, 0.4, color, 1, cv2.LINE_AA)
    return img


def draw_windows(img: np.ndarray, windows: Detections, thickness: int = 1, scale: float = 1.0) -> np.ndarray:
    """Draw positive windows, each in the colour of its search scale (:func:`scale_color`;
    the wide model's windows in the colour of the negated scale)."""
    boxes = windows.boxes
    scales = windows.scale if windows.scale is not None else np.ones(len(windows), np.float32)
    scales = np.where(windows.is_oncoming, -scales, scales)
    for b, s in zip(boxes, scales):
        x1, y1, x2, y2 = (int(round(v * scale)) for v in b)
        cv2.rectangle(img, (x1, y1), (max(x1, x2 - 1), max(y1, y2 - 1)), scale_color(s), thickness)
    return img


def heat_image(heat: np.ndarray, vmax: float | None = None) -> np.ndarray:
    """Heat map as a BGR image (INFERNO colour map, 0 → black, ``vmax`` → yellow-white).

    ``vmax`` defaults to the map's maximum (at least 1, so an empty map stays black)."""
    h = np.asarray(heat, np.float64)
    if vmax is None:
        top = max(float(h.max()) if h.size else 0.0, 1.0)
    else:
        top = max(float(vmax), 1e-12)
    u8 = np.clip(h * (255.0 / top), 0, 255).astype(np.uint8)
    return cv2.applyColorMap(u8, cv2.COLORMAP_INFERNO)


def grid_to_frame(img: np.ndarray, cell: int, shape: tuple[int, ...]) -> np.ndarray:
    """A heat-grid image (one pixel per ``cell x cell`` frame pixels) at frame size
    ``shape[:2]``: each grid pixel repeated ``cell`` times, cropped to the frame."""
    h, w = int(shape[0]), int(shape[1])
    big = cv2.resize(img, (img.shape[1] * cell, img.shape[0] * cell), interpolation=cv2.INTER_NEAREST)
    return np.ascontiguousarray(big[:h, :w])


def label_image(labels: np.ndarray, mask: np.ndarray | None = None) -> np.ndarray:
    """Blob labels as a BGR image: each label in its :func:`label_color`, background black;
    mask pixels without a label (if ``mask`` is given) grey."""
    labels = np.asarray(labels)
    lut = np.zeros((int(labels.max(initial=0)) + 1, 3), np.uint8)
    for i in range(1, len(lut)):
        lut[i] = label_color(i)
    out = lut[labels]
    if mask is not None:
        out[(labels == 0) & np.asarray(mask, bool)] = (128, 128, 128)
    return out


def _caption(img: np.ndarray, text: str) -> None:
    cv2.putText(img, text, (4, 14), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 0, 0), 3, cv2.LINE_AA)
    cv2.putText(img, text, (4, 14), cv2.FONT_HERSHEY_SIMPLEX, 0.4, TEXT_COLOR, 1, cv2.LINE_AA)


def paste_panels(img: np.ndarray, panels: Sequence[np.ndarray], margin: int = 8) -> np.ndarray:
    """Paste ``panels`` (BGR images) side by side along the top of ``img``, in place, each
    with a thin border. Panels that would run past the right edge are left out."""
    x = margin
    H, W = img.shape[:2]
    for p in panels:
        ph, pw = p.shape[:2]
        if x + pw + margin > W or margin + ph > H:
            break
        img[margin:margin + ph, x:x + pw] = p
        cv2.rectangle(img, (x - 1, margin - 1), (x + pw, margin + ph), PANEL_BORDER, 1)
        x += pw + margin
    return img


def debug_panels(frame: np.ndarray, windows: Detections,
                 heat: np.ndarray, labels: np.ndarray, mask: np.ndarray | None = None,
                 threshold: float | None = None, width: int | None = None,
                 boxes: np.ndarray | None = None) -> list[np.ndarray]:
    """Three picture-in-picture panels for a debug video, each ``width`` px wide (default a
    quarter of the frame width):

    1. the frame with the raw positive windows coloured by scale,
    2. the heat map (colour scale fixed at 6x ``threshold`` when given, so colours are
       comparable across frames and the threshold shows as dark red),
    3. the thresholded heat map: each blob (label) in its own colour, and the final
       ``boxes`` (frame pixels) when given.
    """
    H, W = frame.shape[:2]
    pw = int(width or max(W // 4, 1))
    ph = max(int(round(H * pw / W)), 1)
    f = pw / W
    p1 = cv2.resize(frame, (pw, ph), interpolation=cv2.INTER_AREA)
    draw_windows(p1, windows, 1, scale=f)
    _caption(p1, f"windows: {len(windows)}")
    vmax = 6.0 * threshold if threshold else None
    p2 = cv2.resize(heat_image(heat, vmax), (pw, ph), interpolation=cv2.INTER_NEAREST)
    _caption(p2, f"heat (max {float(np.max(heat, initial=0)):.1f})")
    p3 = cv2.resize(label_image(labels, mask), (pw, ph), interpolation=cv2.INTER_NEAREST)
    if boxes is not None:
        draw_boxes(p3, boxes, None, thickness=1, scale=f)
    _caption(p3, f"blobs: {int(np.max(labels, initial=0))}")
    return [p1, p2, p3]
