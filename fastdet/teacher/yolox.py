"""A YOLOX-style CNN detector in ONNX, run with onnxruntime: :class:`TeacherDetector`.

The model (e.g. the shared ``teachers/yolox_nano.onnx``, see its README) must have

- one input: float32 ``(1, 3, H, W)``, BGR, values 0..255, ``H`` and ``W`` free (any
  multiple of 32) or fixed;
- one output: float32 ``(1, N, 85)``, one row per grid cell of the strides 8, 16 and 32 in
  that order, each level row-major (``N = sum (H/s)(W/s)``): ``dx, dy, log_w, log_h,
  objectness`` and the 80 COCO class probabilities (objectness and classes through a sigmoid
  already, the boxes not decoded).

Anything else is refused when the model is loaded, in one line
(:class:`~fastdet.errors.ModelError` "not a YOLOX-style detector: ..."): the checks read the
graph's declared input and output and then run it once on a small grey picture.

One frame (``detect``):

1. letterbox: the frame is resized (``cv2.INTER_LINEAR``) by ``r = min(W / w, H / h)`` to
   ``int(w r) x int(h r)`` and padded with grey 114 on the right and bottom to ``W x H``
   (the input size: :meth:`TeacherDetector.input_size`);
2. decode: the cell at column ``gx``, row ``gy`` of the level of stride ``s`` predicts the
   box centred at ``((dx + gx) s, (dy + gy) s)`` of size ``(exp(log_w) s, exp(log_h) s)``
   (input px), with score ``objectness x probability`` for each class; every (cell, class)
   pair of a kept class scoring at least ``min_score`` is a candidate;
3. the boxes are divided by ``r`` (frame px), suppressed class by class (greedy NMS: a box
   overlapping a higher-scoring box of its class by IoU > ``nms_iou`` is dropped; ties in
   score keep the earlier cell), then clipped to the frame; a box left less than 1 px wide
   or high (all of it in the padding) is dropped.

onnxruntime is an optional dependency (``pip install 'fastdet[teacher]'``): it is imported
only when a :class:`TeacherDetector` is made.
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from ..config.teacher import TeacherConfig
from ..detections import Detections
from ..errors import DataError, FastdetError, ModelError
from ..io.files import check_input

#: the grid strides of a YOLOX head, in the order of the output's rows
STRIDES: tuple[int, ...] = (8, 16, 32)
#: grey of the letterbox padding (0..255)
PAD_VALUE = 114
#: columns of an output row: 4 box values, objectness, 80 COCO class probabilities
ROW = 85
_PROBE = 64  # px, the side of the picture a free-size model is tried on when loaded
_INSTALL = "onnxruntime is not installed: the teacher needs it (pip install 'fastdet[teacher]')"


def _import_onnxruntime() -> Any:
    """The ``onnxruntime`` module, or one line (:class:`~fastdet.errors.FastdetError`)
    naming the extra that installs it."""
    try:
        import onnxruntime
    except ImportError:
        raise FastdetError(_INSTALL) from None
    return onnxruntime


def default_threads() -> int:
    """``NUMBA_NUM_THREADS`` when set to a whole number >= 1, else the cores this process
    may run on."""
    env = os.environ.get("NUMBA_NUM_THREADS", "").strip()
    if env.isdigit() and int(env) >= 1:
        return int(env)
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


def grid_rows(height: int, width: int) -> int:
    """Rows ``N`` of the output for a ``height x width`` input (px, multiples of 32)."""
    return sum((height // s) * (width // s) for s in STRIDES)


def cell_grid(height: int, width: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per output row of a ``height x width`` input: the cell's column ``gx``, row ``gy``
    and stride ``s``, each ``(N,) float64``, in the order of the output's rows."""
    gx, gy, st = [], [], []
    for s in STRIDES:
        rows, cols = height // s, width // s
        yy, xx = np.mgrid[0:rows, 0:cols]
        gx.append(xx.ravel())
        gy.append(yy.ravel())
        st.append(np.full(rows * cols, s))
    return (np.concatenate(gx).astype(np.float64), np.concatenate(gy).astype(np.float64),
            np.concatenate(st).astype(np.float64))


def nms(boxes: np.ndarray, scores: np.ndarray, iou: float) -> np.ndarray:
    """Greedy non-maximum suppression: indices (into ``boxes``) of the boxes kept, highest
    score first. ``boxes`` ``(N, 4)`` x1, y1, x2, y2 (continuous), ``scores`` ``(N,)``; a box
    is dropped when its IoU with a kept, higher-scoring box is greater than ``iou``; equal
    scores keep the lower index first."""
    order = np.argsort(-scores, kind="stable")
    x1, y1, x2, y2 = (boxes[:, k] for k in range(4))
    areas = (x2 - x1) * (y2 - y1)
    keep: list[int] = []
    while order.size:
        i = int(order[0])
        keep.append(i)
        rest = order[1:]
        iw = np.maximum(0.0, np.minimum(x2[i], x2[rest]) - np.maximum(x1[i], x1[rest]))
        ih = np.maximum(0.0, np.minimum(y2[i], y2[rest]) - np.maximum(y1[i], y1[rest]))
        inter = iw * ih
        union = areas[i] + areas[rest] - inter
        ov = np.divide(inter, union, out=np.zeros_like(inter), where=union > 0)
        order = rest[ov <= iou]
    return np.asarray(keep, dtype=np.intp)


@dataclass(frozen=True, eq=False)
class TeacherBoxes:
    """One frame's boxes from a teacher.

    boxes: ``(N, 4) float64`` x1, y1, x2, y2 in frame px (continuous: ``x2 = left + width``),
        inside the frame.
    scores: ``(N,) float32``, objectness x class probability, in [``min_score``, 1].
    classes: ``(N,) int16`` COCO class ids (2 car, 3 motorcycle, 5 bus, 7 truck).

    Rows are ordered by score, highest first.
    """

    boxes: np.ndarray
    scores: np.ndarray
    classes: np.ndarray

    def __len__(self) -> int:
        return len(self.boxes)

    def __getitem__(self, index: Any) -> TeacherBoxes:
        return TeacherBoxes(self.boxes[index], self.scores[index], self.classes[index])

    def detections(self, source: str = "<memory>") -> Detections:
        """The boxes and scores as fastdet's box table (the classes left out)."""
        return Detections(self.boxes, self.scores, source=source)

    @classmethod
    def empty(cls) -> TeacherBoxes:
        return cls(np.zeros((0, 4)), np.zeros(0, np.float32), np.zeros(0, np.int16))


def _dim(d: Any) -> int | None:
    """A declared dimension: its size, or ``None`` when free (a name or unknown)."""
    return int(d) if isinstance(d, (int, np.integer)) and d > 0 else None


class TeacherDetector:
    """A YOLOX-style ONNX detector (see the module docstring) that boxes vehicles in frames.

    path: the ``.onnx`` file.
    size: the input width in px (:attr:`TeacherConfig.size`); overrides ``config.size``.
    min_score, threads: override ``config``'s.
    config: every setting (:class:`~fastdet.config.TeacherConfig`; default its defaults).

    Raises :class:`~fastdet.errors.ModelError` (one line) for a missing file, a file that is
    not ONNX, or a model of another layout; :class:`~fastdet.errors.FastdetError` when
    onnxruntime is not installed. ``detect(frame)`` gives a frame's :class:`TeacherBoxes`.
    """

    def __init__(self, path: str | os.PathLike[str], size: int | None = None, *, min_score: float | None = None,
                 threads: int | None = None, config: TeacherConfig | None = None) -> None:
        cfg = config if config is not None else TeacherConfig()
        changes = {k: v for k, v in (("size", size), ("min_score", min_score), ("threads", threads)) if v is not None}
        if changes:
            try:
                cfg = TeacherConfig(**{**cfg.to_dict(), **changes})
            except ValueError as exc:
                raise FastdetError(f"teacher: {exc}") from None
        self.config = cfg
        self.path = Path(path)
        name = os.fspath(path)
        try:  # missing, a symlink loop, a folder, a FIFO or a device: one line, before onnxruntime opens it
            check_input(name, "ONNX model")
        except DataError as exc:
            raise ModelError(str(exc)) from None
        ort = _import_onnxruntime()
        self.threads = cfg.threads if cfg.threads is not None else default_threads()
        opts = ort.SessionOptions()
        opts.intra_op_num_threads = self.threads
        opts.inter_op_num_threads = 1
        opts.log_severity_level = 3  # errors only: no warnings about the graph on stderr
        # no busy-waiting between operators: the frame reader's thread decodes meanwhile, and the
        # cores are shared (measured on 2 loaded cores at 640: 134 ms a frame instead of 152,
        # 70 ms of CPU instead of 77)
        opts.add_session_config_entry("session.intra_op.allow_spinning", "0")
        try:
            self._session = ort.InferenceSession(name, sess_options=opts, providers=["CPUExecutionProvider"])
        except Exception as exc:  # noqa: BLE001 - onnxruntime's own exception types
            first = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
            raise ModelError(f"{name}: not an ONNX model onnxruntime can load ({first[:200]})") from None
        self._check_layout(name)
        self._grids: dict[tuple[int, int], tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
        self._probe(name)

    # ---- the model's layout ------------------------------------------------------------
    def _check_layout(self, name: str) -> None:
        bad = f"{name}: not a YOLOX-style detector:"
        ins, outs = self._session.get_inputs(), self._session.get_outputs()
        if len(ins) != 1:
            raise ModelError(f"{bad} it has {len(ins)} inputs, expected one (1, 3, H, W) float32 image")
        if len(outs) != 1:
            raise ModelError(f"{bad} it has {len(outs)} outputs, expected one (1, N, 85) float32 array")
        inp, out = ins[0], outs[0]
        shape = list(inp.shape or [])
        if inp.type != "tensor(float)" or len(shape) != 4 or _dim(shape[0]) not in (None, 1) \
                or _dim(shape[1]) not in (None, 3):
            raise ModelError(f"{bad} its input is {inp.type} {tuple(shape)}, expected float32 (1, 3, H, W)")
        self._fixed_h, self._fixed_w = _dim(shape[2]), _dim(shape[3])
        for side in (self._fixed_h, self._fixed_w):
            if side is not None and side % 32:
                raise ModelError(f"{bad} its input is {tuple(shape)}: H and W must be multiples of 32")
        oshape = list(out.shape or [])
        if out.type != "tensor(float)" or len(oshape) != 3 or _dim(oshape[0]) not in (None, 1) \
                or _dim(oshape[2]) not in (None, ROW):
            raise ModelError(f"{bad} its output is {out.type} {tuple(oshape)}, expected float32 (1, N, {ROW})")
        if self._fixed_w is not None and self.config.size is not None \
                and self.config.input_width() != self._fixed_w:
            raise ModelError(f"{name}: the model's input is fixed at {self._fixed_w}x{self._fixed_h}; "
                             f"leave out the size or give {self._fixed_w}")
        self._input_name = inp.name

    def _probe(self, name: str) -> None:
        """Run the model once on a grey picture: it runs, and its output has the rows and
        columns of a YOLOX head for that input."""
        h = self._fixed_h or _PROBE
        w = self._fixed_w or _PROBE
        try:
            raw = self._run(np.full((1, 3, h, w), PAD_VALUE, np.float32))
        except ModelError:
            raise
        except Exception as exc:  # noqa: BLE001 - onnxruntime's own exception types
            first = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
            raise ModelError(f"{name}: not a YOLOX-style detector: it does not run on a {w}x{h} input "
                             f"({first[:200]})") from None
        self._check_output(raw, h, w, name)

    def _check_output(self, raw: np.ndarray, h: int, w: int, name: str | None = None) -> None:
        want = (1, grid_rows(h, w), ROW)
        if raw.dtype != np.float32 or raw.shape != want:
            raise ModelError(f"{name or self.path}: not a YOLOX-style detector: on a {w}x{h} input its output is "
                             f"{raw.dtype} {raw.shape}, expected float32 {want} (cells of strides 8, 16, 32)")

    def _run(self, blob: np.ndarray) -> np.ndarray:
        out = self._session.run(None, {self._input_name: blob})
        return np.asarray(out[0])

    # ---- one frame -------------------------------------------------------------------
    def input_size(self, frame_shape: tuple[int, ...]) -> tuple[int, int]:
        """``(height, width)`` of the network input for frames of ``frame_shape``
        (``(h, w, ...)``, px): the model's own when fixed; else the width from
        :meth:`TeacherConfig.input_width` and the height ``width x h / w`` rounded up to a
        multiple of 32."""
        fh, fw = int(frame_shape[0]), int(frame_shape[1])
        w = self.config.input_width(self._fixed_w)
        if self._fixed_h is not None:
            return self._fixed_h, w
        return max(32, -(-int(np.ceil(w * fh / fw)) // 32) * 32), w

    def preprocess(self, frame: np.ndarray) -> tuple[np.ndarray, float]:
        """The letterboxed input of a frame: ``(1, 3, H, W) float32`` BGR 0..255, and the
        resize factor ``r`` (input px per frame px). ``frame``: ``(h, w, 3) uint8`` BGR."""
        if frame.ndim != 3 or frame.shape[2] != 3 or frame.dtype != np.uint8:
            raise ValueError(f"TeacherDetector: expected an (h, w, 3) uint8 BGR frame, got {frame.dtype} {frame.shape}")
        fh, fw = frame.shape[:2]
        h, w = self.input_size(frame.shape)
        r = min(w / fw, h / fh)
        nw, nh = max(1, int(fw * r)), max(1, int(fh * r))
        padded = np.full((h, w, 3), PAD_VALUE, np.uint8)
        padded[:nh, :nw] = cv2.resize(frame, (nw, nh), interpolation=cv2.INTER_LINEAR)
        blob = np.ascontiguousarray(padded.transpose(2, 0, 1)[None], dtype=np.float32)
        return blob, r

    def run_input(self, blob: np.ndarray) -> np.ndarray:
        """The model's undecoded output ``(1, N, 85) float32`` for an input ``blob``
        (:meth:`preprocess`); :class:`~fastdet.errors.ModelError` when it is not the
        output of a YOLOX head for that input size."""
        out = self._run(blob)
        self._check_output(out, blob.shape[2], blob.shape[3])
        return out

    def raw(self, frame: np.ndarray) -> tuple[np.ndarray, float]:
        """The model's undecoded output for a frame, ``(1, N, 85) float32``, and ``r``
        (:meth:`preprocess`)."""
        blob, r = self.preprocess(frame)
        return self.run_input(blob), r

    def decode(self, raw: np.ndarray, r: float, frame_shape: tuple[int, ...]) -> TeacherBoxes:
        """Boxes of a frame of ``frame_shape`` from the model's output ``raw`` (``(1, N, 85)``
        for the input of :meth:`input_size`) and the resize factor ``r``: steps 2 and 3 of
        the module docstring."""
        cfg = self.config
        fh, fw = int(frame_shape[0]), int(frame_shape[1])
        h, w = self.input_size(frame_shape)
        grid = self._grids.get((h, w))
        if grid is None:
            grid = self._grids[(h, w)] = cell_grid(h, w)
        gx, gy, st = grid
        rows = raw[0]
        classes = np.asarray(cfg.classes, np.intp)
        # float64, as a plain per-cell reading of the output would compute it
        scores = rows[:, 4:5].astype(np.float64) * rows[:, 5 + classes].astype(np.float64)
        cell, k = np.nonzero(scores >= cfg.min_score)
        if cell.size == 0:
            return TeacherBoxes.empty()
        v = rows[cell, :4].astype(np.float64)
        s = st[cell]
        cx, cy = (v[:, 0] + gx[cell]) * s, (v[:, 1] + gy[cell]) * s
        bw, bh = np.exp(v[:, 2]) * s, np.exp(v[:, 3]) * s
        boxes = np.stack([cx - bw / 2, cy - bh / 2, cx + bw / 2, cy + bh / 2], axis=1) / r
        score = scores[cell, k]
        cls = classes[k]
        keep = []
        for c in classes:  # class-wise NMS, candidates in the order of the output's rows
            idx = np.flatnonzero(cls == c)
            if idx.size:
                keep.append(idx[nms(boxes[idx], score[idx], cfg.nms_iou)])
        sel = np.concatenate(keep)
        boxes, score, cls = boxes[sel], score[sel], cls[sel]
        boxes[:, [0, 2]] = np.clip(boxes[:, [0, 2]], 0.0, fw)
        boxes[:, [1, 3]] = np.clip(boxes[:, [1, 3]], 0.0, fh)
        ok = (boxes[:, 2] - boxes[:, 0] >= 1.0) & (boxes[:, 3] - boxes[:, 1] >= 1.0)
        boxes, score, cls = boxes[ok] + 0.0, score[ok], cls[ok]  # + 0.0: no -0.0
        order = np.argsort(-score, kind="stable")
        return TeacherBoxes(boxes[order], score[order].astype(np.float32), cls[order].astype(np.int16))

    def detect(self, frame: np.ndarray) -> TeacherBoxes:
        """The vehicles in one ``(h, w, 3) uint8`` BGR frame (module docstring, steps 1-3)."""
        raw, r = self.raw(frame)
        return self.decode(raw, r, frame.shape)

    def __repr__(self) -> str:
        return f"TeacherDetector({os.fspath(self.path)!r}, config={self.config!r}, threads={self.threads})"
