"""fastdet/batch/manifest.py: when a video counts as done (resume rules), a line cut short by a
crash, a failure that is tried again."""
from __future__ import annotations

import json
from pathlib import Path

from fastdet.batch.manifest import Manifest, input_stat


def test_manifest_resume_rules_and_a_cut_short_line(tmp_path: Path) -> None:
    video = tmp_path / "v.mp4"
    video.write_bytes(b"0123")
    box = tmp_path / "v.boxes.txt"
    box.write_text("1,-1,1,2,3,4,0.5,-1,-1,-1\n")
    m = Manifest(tmp_path / "manifest.jsonl")
    entry = {"input": str(video), "name": "v", "status": "done", "settings_hash": "h",
             "outputs": {"boxes": box.name}, "sizes": {box.name: box.stat().st_size}, **input_stat(video)}
    m.append(entry)
    outs = {"boxes": box}
    assert Manifest(m.path).is_complete(video, "v", "h", outs)
    assert not Manifest(m.path).is_complete(video, "v", "other settings", outs)
    assert not Manifest(m.path).is_complete(video, "w", "h", outs)
    assert not Manifest(m.path).is_complete(video, "v", "h", {**outs, "json": tmp_path / "v.boxes.jsonl"})
    box.write_text("1,-1,1,2,3,4,0.5,-1,-1,-1\n2,-1,1,2,3,4,0.5,-1,-1,-1\n")  # changed size
    assert not Manifest(m.path).is_complete(video, "v", "h", outs)
    # a crash mid-line: the line is ignored and the file rewritten without it
    with open(m.path, "a") as fh:
        fh.write('{"input": "/b.mp4", "sta')
    m2 = Manifest(m.path)
    assert list(m2.entries) == [str(video)]
    assert m.path.read_text().endswith("\n") and [json.loads(line) for line in m.path.read_text().splitlines()] != []
    assert len(m.path.read_text().splitlines()) == 1
