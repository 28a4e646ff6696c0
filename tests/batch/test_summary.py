"""fastdet/batch/summary.py: the end-of-batch table, its frame rates worked out by hand."""
from __future__ import annotations

from fastdet.batch.summary import format_summary


def _table(text: str) -> dict[str, list[str]]:
    return {line.split()[0]: line.split()[1:] for line in text.splitlines()[2:] if not line.startswith("failed:")}


def test_rows_and_frame_rates() -> None:
    done = [{"name": "a", "frames": 100, "seconds": 4.0}, {"name": "b", "frames": 50, "seconds": 1.0}]
    skipped = [{"name": "c", "frames": 30}, {"name": "d"}]
    failed = [{"name": "e", "input": "/v/e.mp4", "error": "not a video", "frames": None}]
    text = format_summary(done, skipped, failed, wall=10.0, workers=2)
    lines = text.splitlines()
    assert lines[0] == "fastdet batch: 5 video(s) in 10.0 s on 2 worker(s)"
    assert lines[1].split() == ["videos", "frames", "frames/s", "(job)", "frames/s", "(task)"]
    rows = _table(text)
    # job: 150 frames / 10 s wall; task: 150 frames / (4 + 1) s of tasks
    assert rows["done"] == ["2", "150", "15.0", "30.0"]
    assert rows["skipped"] == ["2", "30"] and rows["failed"] == ["1", "0"]
    assert lines[-1] == "failed: /v/e.mp4: not a video"


def test_no_rate_without_frames_or_time_and_failures_said_once() -> None:
    failed = [{"name": "x", "input": "/v/x.mp4", "error": "/v/x.mp4: cannot read", "earlier": True},
              {"name": "y"}]
    text = format_summary([{"frames": 0, "seconds": 0.0}], [], failed, wall=0.0, workers=None)
    assert text.splitlines()[0] == "fastdet batch: 3 video(s) in 0.0 s"
    assert _table(text)["done"] == ["1", "0"]  # no frames/s columns
    fails = [line for line in text.splitlines() if line.startswith("failed:")]
    assert fails == ["failed: /v/x.mp4: cannot read (in an earlier run; unchanged since: --overwrite tries again)",
                     "failed: y: unknown error"]
