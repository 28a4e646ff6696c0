"""fastdet/batch/inputs.py: the videos a batch's inputs name (folders, globs, list files), in
order and each once, never one of the batch's own outputs; the output names."""
from __future__ import annotations

from pathlib import Path

import pytest

from fastdet.batch.inputs import batch_writes, expand_inputs, output_names
from fastdet.batch.settings import MANIFEST_NAME, SUFFIXES
from fastdet.errors import DataError


def test_inputs_folders_globs_lists_in_order_each_once(tmp_path: Path) -> None:
    (tmp_path / "d" / "sub").mkdir(parents=True)
    (tmp_path / "d" / ".hidden").mkdir()
    for rel in ("d/b.mp4", "d/a.MP4", "d/sub/c.avi", "d/notes.txt.bak", "d/.x.mp4", "d/.hidden/h.mp4", "e.mkv"):
        (tmp_path / rel).write_bytes(b"x")
    lst = tmp_path / "list.txt"
    lst.write_text("# clips\n\ne.mkv\nd/b.mp4\n")
    got = expand_inputs([str(tmp_path / "d"), str(tmp_path / "*.mkv"), str(lst)])
    rel = [p.relative_to(tmp_path).as_posix() for p in got]
    assert rel == ["d/a.MP4", "d/b.mp4", "d/sub/c.avi", "e.mkv"]
    assert all(p.is_absolute() for p in got)
    with pytest.raises(DataError, match="file not found"):
        expand_inputs([str(tmp_path / "nope.mp4")])
    with pytest.raises(DataError, match="matches no video"):
        expand_inputs([str(tmp_path / "*.mov")])
    (tmp_path / "empty").mkdir()
    with pytest.raises(DataError, match="no video found"):
        expand_inputs([str(tmp_path / "empty")])


def test_output_names_unique_and_stable() -> None:
    vids = [Path("/x/day1/clip.mp4"), Path("/x/day2/clip.mp4"), Path("/y/clip.avi"), Path("/y/clip.mp4"),
            Path("/z/other clip.mp4")]
    names = output_names(vids)
    assert names[4] == "other_clip"
    assert len({n.lower() for n in names}) == len(names)
    assert names[:2] == ["day1_clip", "day2_clip"]
    # a name depends on the videos, not on their order
    assert output_names(vids[::-1]) == names[::-1]


def test_batch_never_reads_what_it_writes(tmp_path: Path) -> None:
    d = tmp_path / "d"
    d.mkdir()
    for n in ("a.mp4", "a.annotated.mp4", "b.mov"):
        (d / n).write_bytes(b"v")
    writes = batch_writes(d, SUFFIXES.values(), [d / MANIFEST_NAME])
    # a folder (or glob) holding the batch's own outputs: they are left out
    assert [p.name for p in expand_inputs([str(d)], writes)] == ["a.mp4", "b.mov"]
    assert [p.name for p in expand_inputs([str(d / "*.mp4")], writes)] == ["a.mp4"]
    # named as an input (directly, through a symlink, in a list file): refused in one line
    (tmp_path / "link.mp4").symlink_to(d / "a.annotated.mp4")
    (tmp_path / "list.txt").write_text(f"{d / 'a.mp4'}\n{d / 'a.annotated.mp4'}\n")
    for arg in (d / "a.annotated.mp4", tmp_path / "link.mp4", tmp_path / "list.txt"):
        with pytest.raises(DataError, match="is a file this batch writes"):
            expand_inputs([str(d / "a.mp4"), str(arg)], writes)
    # the same folder as input with the output folder elsewhere: every video is an input
    assert len(expand_inputs([str(d)], batch_writes(tmp_path / "o", SUFFIXES.values()))) == 3


def test_long_video_names_give_output_names_that_fit(tmp_path: Path) -> None:
    """Issue 34 (16): a video name of 236-245 characters gave outputs (and temporary files)
    longer than the file system takes; the run failed on every rerun."""
    from fastdet.batch.settings import SUFFIXES, max_name_length

    limit = max_name_length(tmp_path)
    vids = [Path("/v") / f"{'x' * n}.mp4" for n in (236, 240, 245, 251)] + [Path("/w") / f"{'x' * 245}.mp4"]
    names = output_names(vids, limit)
    assert len({n.lower() for n in names}) == len(names)
    for n in names:
        for suffix in SUFFIXES.values():
            (tmp_path / f"{n}{suffix}").write_bytes(b"")  # fits the file system
    assert output_names([Path("/v/short.mp4")], limit) == ["short"]
