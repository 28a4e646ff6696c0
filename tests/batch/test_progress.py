"""fastdet/batch/progress.py: the batch's progress bar counts frames of the current attempt."""
from __future__ import annotations

from fastdet.batch.progress import BatchProgress


def test_progress_counts_a_retried_attempt_once() -> None:
    p = BatchProgress(["a", "b"], enabled=False)
    p.on_event((0.0, {"name": "a", "token": "t1", "frames": 5, "expected": 10}))
    p.on_event((0.0, {"name": "a", "token": "t2", "frames": 2, "expected": 10}))  # the retry
    p.on_event((0.0, {"name": "b", "token": "t3", "frames": 4, "expected": 8}))
    p.on_event((0.0, "garbage"))
    assert sum(f for _, f in p._frames.values()) == 6
    p.close()
