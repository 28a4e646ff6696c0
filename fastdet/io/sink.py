"""The annotated output video, drawn and encoded in a background thread (:class:`VideoSink`)."""
from __future__ import annotations

import queue
import threading
import time
from pathlib import Path

import cv2

from ..errors import DataError
from . import draw
from .atomic import commit, partial_name
from .reader import QUEUE_SIZE


class VideoSink:
    """Draws and encodes frames in a background thread; see the module docstring for the
    temporary name. ``put((frame, boxes, debug))`` then ``close()``."""

    def __init__(self, path: str, fps: float, size: tuple[int, int], debug: bool = False,
                 threshold: float | None = None) -> None:
        self.path = Path(path)
        self.tmp = partial_name(path)
        self.debug = debug
        self.threshold = threshold
        self._writer = cv2.VideoWriter(str(self.tmp), cv2.VideoWriter_fourcc(*"mp4v"), fps, size)
        if not self._writer.isOpened():
            self._writer.release()
            self.tmp.unlink(missing_ok=True)
            raise DataError(f"{path}: cannot write a video there (unknown extension "
                            f"{self.path.suffix or '(none)'!r}? use .mp4 or .avi; or no permission)")
        self.frames = 0
        self.draw_s = 0.0
        self.encode_s = 0.0
        self.error: BaseException | None = None
        self._q: queue.Queue = queue.Queue(maxsize=QUEUE_SIZE)
        self._thread = threading.Thread(target=self._run, name="fastdet-encode", daemon=True)
        self._thread.start()
        self._closed = False

    def put(self, item: tuple) -> None:
        while True:
            if self.error is not None or not self._thread.is_alive():
                raise RuntimeError(f"video writer thread failed: {self.error!r}")
            try:
                self._q.put(item, timeout=0.1)
                return
            except queue.Full:
                continue

    def _run(self) -> None:
        try:
            while True:
                item = self._q.get()
                if item is None:
                    return
                frame, boxes, dbg = item
                t0 = time.perf_counter()
                if dbg is not None:
                    draw.paste_panels(frame, draw.debug_panels(frame, *dbg, threshold=self.threshold,
                                                               boxes=boxes.boxes))
                draw.draw_boxes(frame, boxes.boxes, boxes.scores)
                t1 = time.perf_counter()
                self._writer.write(frame)
                t2 = time.perf_counter()
                self.draw_s += t1 - t0
                self.encode_s += t2 - t1
                self.frames += 1
        except BaseException as exc:  # reported by put() / close()
            self.error = exc

    def close(self) -> Path | None:
        """Finish the queued frames, close the file and give it its final name (``None``
        and no file when no frame was written)."""
        if self._closed:
            return self.path if self.frames else None
        self._closed = True
        if self._thread.is_alive():
            while True:
                try:
                    self._q.put(None, timeout=0.1)
                    break
                except queue.Full:
                    if not self._thread.is_alive():
                        break
            self._thread.join()
        self._writer.release()
        if self.frames:
            commit(self.tmp, self.path)
            return self.path
        self.tmp.unlink(missing_ok=True)
        return None


