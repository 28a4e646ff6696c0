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


def test_manifest_lines_nested_too_deeply_or_of_the_wrong_shape_are_dropped(tmp_path: Path, capsys) -> None:
    """issue 34, item 19: 200,000 nested ``[`` (RecursionError) and a line whose ``outputs`` is a
    list (AttributeError in the resume test) are damaged lines: dropped with one note."""
    video = tmp_path / "v.mp4"
    video.write_bytes(b"x")
    good = {"input": str(video), "status": "done", "name": "v", "settings_hash": "h",
            "outputs": {"boxes": "v.boxes.txt"}, "sizes": {"v.boxes.txt": 3}, **input_stat(video)}
    (tmp_path / "v.boxes.txt").write_text("abc")
    bad_outputs = {**good, "input": str(tmp_path / "w.mp4"), "outputs": ["v.boxes.txt"]}
    path = tmp_path / "manifest.jsonl"
    long_number = '{"input": "x", "frames": ' + "9" * 5000 + "}"  # a ValueError traceback (int_max_str_digits)
    lines = [json.dumps(good), "[" * 200_000, json.dumps(bad_outputs), long_number]
    path.write_text("\n".join(lines) + "\n")
    m = Manifest(path)
    assert m.dropped == 3 and list(m.entries) == [str(video)]
    assert "ignored 3 damaged line(s)" in capsys.readouterr().err
    assert m.is_complete(video, "v", "h", {"boxes": tmp_path / "v.boxes.txt"})
    assert not m.is_complete(tmp_path / "w.mp4", "v", "h", {"boxes": tmp_path / "v.boxes.txt"})
