"""The table a batch prints at the end: done / skipped / failed, frames, frame rates."""
from __future__ import annotations

from collections.abc import Sequence
from typing import Any


def format_summary(done: Sequence[dict[str, Any]], skipped: Sequence[dict[str, Any]],
                   failed: Sequence[dict[str, Any]], wall: float, workers: int | None) -> str:
    """The end-of-batch report.

    ``frames/s (job)`` is the frames of this run over its wall time (start-up included):
    the throughput of the whole cluster. ``frames/s (task)`` is frames over the summed
    task times: what one worker does on one video. Skipped videos count with the frames
    recorded when they were done. Failed videos follow, one line each with their reason.
    """
    def frames(rows: Sequence[dict[str, Any]]) -> int:
        return sum(int(r.get("frames") or 0) for r in rows)

    task_s = sum(float(r.get("seconds") or 0.0) for r in done)
    n_done = frames(done)
    rows = [
        ("done", len(done), n_done, f"{n_done / wall:.1f}" if wall > 0 and n_done else "",
         f"{n_done / task_s:.1f}" if task_s > 0 and n_done else ""),
        ("skipped", len(skipped), frames(skipped), "", ""),
        ("failed", len(failed), frames(failed), "", ""),
    ]
    n_all = len(done) + len(skipped) + len(failed)
    on = f" on {workers} worker(s)" if workers else ""
    lines = [f"fastdet batch: {n_all} video(s) in {wall:.1f} s{on}",
             f"{'':<9}{'videos':>7}{'frames':>9}{'frames/s (job)':>16}{'frames/s (task)':>17}"]
    lines += [f"{a:<9}{b:>7}{c:>9}{d:>16}{e:>17}" for a, b, c, d, e in rows]
    for r in failed:
        where, err = str(r.get("input", r.get("name"))), str(r.get("error", "unknown error"))
        line = f"failed: {err}" if err.startswith(where) else f"failed: {where}: {err}"
        lines.append(line + (" (in an earlier run; unchanged since: --overwrite tries again)"
                             if r.get("earlier") else ""))
    return "\n".join(lines)
