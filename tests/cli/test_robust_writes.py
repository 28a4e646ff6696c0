"""A failed write is a failure (issue 14, item 2). "Disk full" is a real file-size limit
(``RLIMIT_FSIZE`` in a subprocess): writes past it fail with EFBIG, as on a full disk.

Every case: a non-zero exit, one line on stderr, and no file under the final name.
"""
from __future__ import annotations

from pathlib import Path

import cv2
import pytest

from tests.media import fastdet_cmd, frames, leftovers, run_limited, write_video


@pytest.fixture(scope="module")
def clip(tmp_path_factory) -> Path:
    """60 frames of 640x360: ``video -o`` writes about 77 kB of them, 12 kB for five."""
    return write_video(tmp_path_factory.mktemp("w") / "clip.mp4", 60, w=640, h=360)


def _one_line_failure(r, match: str) -> str:
    assert r.returncode == 2, r.stdout + r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and match in lines[0], r.stderr
    assert "wrote" not in r.stdout
    return lines[0]


def test_video_on_a_full_disk_fails_and_keeps_nothing(clip, tmp_path):
    out = tmp_path / "o.mp4"
    r = run_limited(fastdet_cmd("video", clip, "-o", out, "--no-progress", "--no-oncoming"), 40_000)
    line = _one_line_failure(r, "writing the video failed")
    assert "file-size limit" in line
    assert list(tmp_path.iterdir()) == []


def test_video_cut_short_at_close_is_caught_by_the_final_check(clip, tmp_path):
    """Too few frames for the check while writing: the file is checked when closed (it
    does not open, or holds fewer frames than were written)."""
    out = tmp_path / "o.mp4"
    r = run_limited(fastdet_cmd("video", clip, "-o", out, "--frames", "5", "--no-progress", "--no-oncoming"), 6_000)
    _one_line_failure(r, "writing the video failed")
    assert list(tmp_path.iterdir()) == []


def test_box_files_on_a_full_disk(clip, tmp_path):
    boxes, js = tmp_path / "b.txt", tmp_path / "b.jsonl"
    r = run_limited(fastdet_cmd("video", clip, "--boxes", boxes, "--json", js, "--no-progress", "--no-oncoming"), 300)
    _one_line_failure(r, "cannot write")
    assert list(tmp_path.iterdir()) == []


def test_a_full_disk_removes_the_other_outputs_too(clip, tmp_path):
    """The video fails: the box files, complete as they are, are not kept either (a failed
    run keeps nothing)."""
    out, boxes = tmp_path / "o.mp4", tmp_path / "b.txt"
    r = run_limited(fastdet_cmd("video", clip, "-o", out, "--boxes", boxes, "--no-progress", "--no-oncoming"), 40_000)
    _one_line_failure(r, "writing the video failed")
    assert list(tmp_path.iterdir()) == []


def test_image_on_a_full_disk_does_not_blame_the_extension(tmp_path):
    img = tmp_path / "in.jpg"
    cv2.imwrite(str(img), next(frames(1, 640, 360)))
    out = tmp_path / "out" / "o.jpg"
    out.parent.mkdir()
    r = run_limited(fastdet_cmd("image", img, "-o", out), 20_000)
    line = _one_line_failure(r, "writing the image failed")
    assert "extension" not in line
    assert list(out.parent.iterdir()) == []


def test_mine_negatives_on_a_full_disk_says_so(tmp_path):
    img = tmp_path / "in.jpg"
    cv2.imwrite(str(img), next(frames(1, 1280, 720)))
    out = tmp_path / "neg"
    r = run_limited(fastdet_cmd("mine-negatives", img, "--out", out, "--x-range", "0", "1280",
                                "--threshold", "-5", "--no-progress"), 3000)
    _one_line_failure(r, "could not write the crop")
    assert "mined" not in r.stdout
    assert leftovers(out) == []


def test_a_stop_during_the_offline_redraw_keeps_no_truncated_video(clip, tmp_path, capsys, monkeypatch):
    """Issue 34 (3): ``video --offline`` stopped by SIGTERM while the video was redrawn said
    "60 frames ... wrote o.mp4, b.txt, ..." with o.mp4 holding 15 frames. The box files
    (complete: every frame) are kept, the video is not, and the line says exactly that."""
    import json
    import os
    import signal

    from fastdet.cli import video as video_cmd
    from fastdet.cli.main import main

    real_put = video_cmd.VideoSink.put
    puts = []

    def put(self, item):  # --offline: the sink gets frames only in the redraw
        puts.append(1)
        if len(puts) == 15:
            os.kill(os.getpid(), signal.SIGTERM)
        return real_put(self, item)

    monkeypatch.setattr(video_cmd.VideoSink, "put", put)
    out, boxes, summary = tmp_path / "o.mp4", tmp_path / "b.txt", tmp_path / "s.json"
    rc = main(["video", str(clip), "--offline", "-o", str(out), "--boxes", str(boxes), "--summary", str(summary),
               "--no-progress", "--no-oncoming"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 143 and len(err) == 1, err
    assert f"wrote {boxes}, {summary}" in err[0] and f"{out} not written" in err[0], err
    assert not out.exists() and sorted(p.name for p in tmp_path.iterdir()) == ["b.txt", "s.json"]
    assert {int(line.split(",")[0]) for line in boxes.read_text().splitlines()} <= set(range(1, 61))
    assert json.loads(summary.read_text())["outputs"] == [str(boxes)]
