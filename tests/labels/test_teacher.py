"""fastdet.labels.teacher: a CNN teacher's detections as training labels."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from fastdet.labels.teacher import read_teacher, read_teacher_clip

from ..media import write_video
from .synth import one_error, write


@pytest.fixture(scope="module")
def video(tmp_path_factory) -> Path:
    """A 320x240 clip of 12 frames."""
    return write_video(tmp_path_factory.mktemp("v") / "clip.mp4", 12)


def teacher(root: Path, video: Path, text: str, frames: str = "1\n6\n11\n", name: str = "c",
            suffix: str = ".mp4") -> Path:
    (root / "videos").mkdir(parents=True, exist_ok=True)
    (root / "videos" / f"{name}{suffix}").symlink_to(video)
    write(root / "teacher" / f"{name}.frames", frames)
    return write(root / "teacher" / f"{name}.teacher.txt", text)


def test_shared_teacher_clips(data):
    pics = read_teacher(data)
    clips = {p.source for p in pics}
    assert len(clips) == 17 and all(c.startswith("teacher:") for c in clips)
    listed = sum(len((data / "teacher" / f"{c.removeprefix('teacher:')}.frames").read_text().split()) for c in clips)
    assert len(pics) == listed == 2170
    assert all(p.labelled_by == "teacher" and not p.human and p.complete for p in pics)
    assert all(p.camera == p.source for p in pics)
    ebu = [p for p in pics if p.source == "teacher:ebuarip_640"]
    assert ebu[0].path.name == "ebuarip_640.avi" and (ebu[0].width, ebu[0].height) == (640, 480)
    # a stricter teacher: fewer targets, more ignore regions, the same boxes in all
    strict = read_teacher(data / "teacher" / "tmo_seattle1.teacher.txt", min_score=0.6)
    loose = [p for p in pics if p.source == "teacher:tmo_seattle1"]
    assert sum(len(p.targets) for p in strict) < sum(len(p.targets) for p in loose)
    assert sum(len(p.boxes) for p in strict) == sum(len(p.boxes) for p in loose)


def test_scores_and_classes(tmp_path, video):
    text = ("1,-1,10,10,100,80,0.9,2,-1,-1\n1,-1,120,10,100,80,0.2,7,-1,-1\n1,-1,230,10,60,80,0.5,3,-1,-1\n"
            "1,-1,10,100,60,80,0.95,0,-1,-1\n6,-1,10,10,100,80,0.31,5,-1,-1\n")
    teacher(tmp_path, video, text, suffix=".avi")
    one, six, eleven = read_teacher(tmp_path)
    np.testing.assert_allclose(one.targets, [[10, 10, 110, 90]])
    np.testing.assert_allclose(one.ignores, [[120, 10, 220, 90], [230, 10, 290, 90]])  # unsure car, motorcycle
    np.testing.assert_allclose(six.targets, [[10, 10, 110, 90]])
    assert eleven.boxes.shape == (0, 4)  # looked at, saw nothing
    assert one.name == "c:1" and one.frame == 1 and one.path.suffix == ".avi" and one.camera == "teacher:c"
    (six2,) = [p for p in read_teacher(tmp_path, min_score=0.4) if p.frame == 6]
    assert six2.targets.shape == (0, 4) and six2.ignores.shape == (1, 4)


def test_malformed(tmp_path, video):
    cases = {
        "fields": ("1,-1,10,10,100,80,0.9\n", "expected 10 comma-separated fields"),
        "number": ("1,-1,10,10,1e,80,0.9,2,-1,-1\n", "width is not a number: '1e'"),
        "frame": ("0,-1,10,10,100,80,0.9,2,-1,-1\n", "frame must be a whole number >= 1"),
        "score": ("1,-1,10,10,100,80,1.5,2,-1,-1\n", "score must be 0 to 1"),
        "class": ("1,-1,10,10,100,80,0.9,80,-1,-1\n", "unknown class '80'"),
        "unlisted": ("2,-1,10,10,100,80,0.9,2,-1,-1\n", "frame 2 is not in c.frames"),
        "outside": ("1,-1,-300,10,100,80,0.9,2,-1,-1\n", "entirely outside the 320x240 picture"),
    }
    for name, (bad, words) in cases.items():
        f = teacher(tmp_path / name, video, "1,-1,10,10,100,80,0.9,2,-1,-1\n" + bad)
        one_error(lambda r=tmp_path / name: read_teacher(r), f, words, line=2)
    f = teacher(tmp_path / "noframes", video, "")
    f.with_name("c.frames").unlink()
    one_error(lambda: read_teacher_clip(f), f.with_name("c.frames"), "file not found")
    (tmp_path / "empty").mkdir()
    one_error(lambda: read_teacher(tmp_path / "empty"), tmp_path / "empty", "no *.teacher.txt teacher files")
    one_error(lambda: read_teacher_clip(f, min_score=2), "min-score", "0 to 1")
