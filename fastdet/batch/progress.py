"""Progress of a batch: one tqdm bar over the frames of all videos, fed by the tasks' events.

Tasks send ``{"name", "token", "frames", "expected"}`` on a Dask event topic
(:mod:`fastdet.batch.task`); :meth:`BatchProgress.on_event` runs in the client's event-loop
thread and only records them, and the main thread redraws the bar
(:meth:`BatchProgress.refresh`) a few times a second. A retried task (its worker died)
sends a new ``token``: its count starts again from 0, so the bar may step back.

The bar's total is the frame counts of the videos started so far plus, for the videos not
yet started, their mean (frame counts come from the workers: the client does not open the
videos). Without a terminal (or with ``--no-progress``) there is no bar; every finished
video prints one line instead.
"""
from __future__ import annotations

import sys
import threading
from collections.abc import Iterable
from typing import Any

from tqdm import tqdm


class BatchProgress:
    """The bar over ``names`` (the videos being run); ``enabled`` False: no bar, a line
    per finished video on stderr."""

    def __init__(self, names: Iterable[str], enabled: bool) -> None:
        self.names = list(names)
        self._lock = threading.Lock()
        self._frames: dict[str, tuple[str, int]] = {}  # name -> (token, frames done)
        self._expected: dict[str, int] = {}
        self.done = self.failed = 0
        self.bar_shown = bool(enabled and sys.stderr.isatty())
        self._bar = tqdm(total=None, unit="frame", desc="fastdet batch", file=sys.stderr, dynamic_ncols=True,
                         disable=not self.bar_shown, smoothing=0.1)

    def on_event(self, event: Any) -> None:
        """Dask topic handler: ``event`` is ``(timestamp, message)``."""
        try:
            _, msg = event
            name, token, frames = msg["name"], msg["token"], int(msg["frames"])
            expected = msg.get("expected")
        except (TypeError, ValueError, KeyError):
            return
        with self._lock:
            old = self._frames.get(name)
            if old is None or old[0] != token or frames >= old[1]:
                self._frames[name] = (token, frames)
            if expected is not None:
                self._expected[name] = int(expected)

    def finished(self, summary: dict[str, Any]) -> None:
        """A video's task returned (or failed for good): fix its count, print its line."""
        name, frames = summary["name"], int(summary.get("frames") or 0)
        with self._lock:
            self._frames[name] = ("final", frames)
            self._expected[name] = frames
            if summary.get("status") == "done":
                self.done += 1
            else:
                self.failed += 1
        line = _line(summary, self.done + self.failed, len(self.names))
        if self.bar_shown:
            if summary.get("status") != "done":
                self._bar.write(line, file=sys.stderr)
        else:
            print(line, file=sys.stderr, flush=True)
        self.refresh()

    def refresh(self) -> None:
        """Redraw the bar (main thread)."""
        if not self.bar_shown:
            return
        with self._lock:
            n = sum(f for _, f in self._frames.values())
            known = [self._expected[k] for k in self.names if k in self._expected]
            remaining = len(self.names) - len(known)
            total = sum(known) + (round(remaining * sum(known) / len(known)) if known else 0)
            done, failed = self.done, self.failed
        bar = self._bar
        bar.total = max(total, n) if known else None
        if n >= bar.n:
            bar.update(n - bar.n)
        else:
            bar.n = n
        bar.set_postfix_str(f"videos {done + failed}/{len(self.names)}" + (f", {failed} failed" if failed else ""),
                            refresh=False)
        bar.refresh()

    def close(self) -> None:
        self.refresh()
        self._bar.close()


def _line(s: dict[str, Any], k: int, n: int) -> str:
    where = f"[{k}/{n}] {s['name']}"
    if s.get("status") == "done":
        secs = float(s.get("seconds") or 0.0)
        fps = s["frames"] / secs if secs > 0 else 0.0
        return f"{where}: {s['frames']} frames, {s.get('boxes', 0)} boxes, {fps:.1f} fps"
    return f"{where}: failed: {s.get('error', 'unknown error')}"
