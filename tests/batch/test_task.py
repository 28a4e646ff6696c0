"""fastdet/batch/task.py: one video as a task: a failed write or a vanished temporary file is
not a property of the video (tried again next run); a bad video is."""
from __future__ import annotations

from pathlib import Path

import pytest

pytest.importorskip("distributed")

from fastdet.batch.manifest import Manifest, input_stat
from fastdet.batch.settings import Settings
from fastdet.batch.task import VideoTask, commit_outputs, run_video
from fastdet.errors import WriteError
from tests.media import cut


def test_a_failed_write_is_not_a_property_of_the_video(tmp_path: Path, data: Path, monkeypatch) -> None:
    """A full disk (a write that fails), a temporary file that vanished: recorded as failed
    but not ``permanent``, so the next run tries the video again."""
    clip = cut(data / "videos" / "test_small1.mp4", tmp_path / "c.mp4", 0, 3)
    s = Settings.create()
    from fastdet.io.motfiles import MotWriter

    def full(self, *a, **kw):
        raise WriteError(f"{self.name}: cannot write (No space left on device)")

    with monkeypatch.context() as m:
        m.setattr(MotWriter, "write_detections", full)
        summary = run_video(VideoTask(str(clip), "c", str(tmp_path / "o1"), s, None, "r1"))
    assert summary["status"] == "failed" and summary["permanent"] is False and "No space" in summary["error"]
    # a done task whose temporary file vanished before the batch renamed it
    (tmp_path / "o2").mkdir()
    summary = run_video(VideoTask(str(clip), "c", str(tmp_path / "o2"), s, None, "r2"))
    assert summary["status"] == "done" and not (tmp_path / "o2" / "c.boxes.txt").exists()  # not renamed yet
    Path(summary["partials"]["boxes"]).unlink()
    with pytest.raises(WriteError, match="vanished"):
        commit_outputs(summary, tmp_path / "o2")
    man = Manifest(tmp_path / "m.jsonl")
    man.append({"input": str(clip), "name": "c", "status": "failed", "permanent": False, "settings_hash": s.digest(),
                **input_stat(clip)})
    assert man.known_failure(clip, "c", s.digest()) is None  # tried again next run
    # a bad video is permanent
    bad = tmp_path / "bad.mp4"
    bad.write_bytes(b"not a video" * 50)
    summary = run_video(VideoTask(str(bad), "bad", str(tmp_path / "o3"), s, None, "r3"))
    assert summary["status"] == "failed" and summary["permanent"] is True


def test_a_video_with_a_long_name_runs(tmp_path: Path, data: Path) -> None:
    """Issue 34 (16): the temporary names held the output name and a token: a 240-character
    name failed at run time naming the temporary file."""
    from fastdet.batch.inputs import output_names

    clip = cut(data / "videos" / "test_small1.mp4", tmp_path / f"{'c' * 240}.mp4", 0, 3)
    s = Settings.create(video=True, json=True)
    out = tmp_path / "o"
    out.mkdir()
    [name] = output_names([clip])  # 240 characters: NAME.annotated.mp4 fits in 255
    summary = run_video(VideoTask(str(clip), name, str(out), s, None, "r1"))
    assert summary["status"] == "done", summary.get("error")
    commit_outputs(summary, out)
    assert (out / f"{name}.boxes.txt").exists() and (out / f"{name}.annotated.mp4").exists()
