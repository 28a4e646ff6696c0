"""fastdet.labels.mot: annotated clips (dense and keyframe) as one picture per annotated frame."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from fastdet.labels.mot import read_mot, read_mot_clip

from ..media import write_video
from .synth import one_error, write


@pytest.fixture(scope="module")
def video(tmp_path_factory) -> Path:
    """A 320x240 clip of 12 frames."""
    return write_video(tmp_path_factory.mktemp("v") / "clip.mp4", 12)


def clip(root: Path, video: Path, gt: str, frames: str | None = None, name: str = "c") -> Path:
    (root / "videos").mkdir(parents=True, exist_ok=True)
    (root / "videos" / f"{name}.mp4").symlink_to(video)
    if frames is not None:
        write(root / "annotations" / f"{name}.frames", frames)
    return write(root / "annotations" / f"{name}.gt.txt", gt)


@pytest.mark.parametrize("name, frames, targets, ignores", [
    ("test_video", 38, 76, 261), ("test_small1", 88, 124, 276), ("highway_640", 30, 48, 250),
    ("boston_street", 8, 42, 43), ("motorcycle_highway", 14, 42, 67)])
def test_real_clips_match_the_readme_table(data, name, frames, targets, ignores):
    pics = read_mot_clip(data / "annotations" / f"{name}.gt.txt", every=1)
    assert len(pics) == frames
    assert sum(len(p.targets) for p in pics) == targets and sum(len(p.ignores) for p in pics) == ignores
    assert all(p.camera == f"clip:{name}" and p.source == name and p.complete and p.human for p in pics)
    assert pics[0].path.parent == data / "videos" and pics[0].name == f"{name}:{pics[0].frame}"


def test_every_nth_frame_of_dense_clips_keyframes_of_the_others(data):
    pics = read_mot(data)
    by = {}
    for p in pics:
        by.setdefault(p.source, []).append(p.frame)
    assert by["test_video"] == list(range(1, 39, 5)) and by["test_small1"] == list(range(1, 89, 5))
    assert by["highway_640"] == list(range(1, 292, 10)) and by["boston_street"] == list(range(1, 37, 5))
    assert len(read_mot(data / "annotations" / "test_video.gt.txt", every=10)) == 4  # 1, 11, 21, 31


def test_dense_clip(tmp_path, video):
    gt = clip(tmp_path, video, "1,1,10,10,100,80,1,1,1\n1,5,200,10,20,20,0,1,1\n2,1,12,10,100,80,1,1,1\n"
                               "4,1,14,10,100,80,1,1,1\n4,2,300,100,10,50,1\n")
    pics = read_mot(tmp_path, every=3)
    assert [p.frame for p in pics] == [1, 4] and pics[0].path == tmp_path / "videos" / "c.mp4"
    assert (pics[0].width, pics[0].height) == (320, 240)
    np.testing.assert_allclose(pics[0].targets, [[10, 10, 110, 90]])
    np.testing.assert_allclose(pics[0].ignores, [[200, 10, 220, 30]])  # consider = 0
    np.testing.assert_allclose(pics[1].ignores, [[300, 100, 310, 150]])  # too small
    assert read_mot(gt, camera="cam")[0].camera == "cam"


def test_keyframe_clip(tmp_path, video):
    clip(tmp_path, video, "1,1,10,10,100,80,1,1,1\n6,1,12,10,100,80,1,1,1\n", frames="1\n6\n11\n")
    pics = read_mot(tmp_path)
    assert [p.frame for p in pics] == [1, 6, 11]
    assert pics[2].boxes.shape == (0, 4)  # listed without lines: no vehicle


def test_malformed(tmp_path, video):
    cases = {
        "fields": ("1,1,10,10,100\n", "expected 6 to 10 comma-separated columns", 2),
        "number": ("1,1,10,x,100,80,1,1,1\n", "top is not a number", 2),
        "consider": ("1,1,10,10,100,80,2,1,1\n", "consider must be 0 or 1", 2),
        "outside": ("1,1,400,10,100,80,1,1,1\n", "entirely outside the 320x240 picture", 2),
        "keyframe": ("3,1,10,10,100,80,1,1,1\n", "frame 3 is not a keyframe", 2),
    }
    for name, (bad, words, line) in cases.items():
        gt = clip(tmp_path / name, video, "1,1,10,10,100,80,1,1,1\n" + bad, frames="1\n2\n")
        one_error(lambda r=tmp_path / name: read_mot(r), gt, words, line=line)
    gt = clip(tmp_path / "kf", video, "1,1,10,10,100,80,1,1,1\n", frames="1\nx\n")
    one_error(lambda: read_mot(tmp_path / "kf"), gt.with_name("c.frames"), "expected a frame number", line=2)


def test_missing_video_and_empty(tmp_path, video):
    gt = write(tmp_path / "a" / "annotations" / "c.gt.txt", "1,1,10,10,100,80,1,1,1\n")
    one_error(lambda: read_mot(gt), gt, "no video")
    gt = clip(tmp_path / "b", video, "")
    one_error(lambda: read_mot(gt), gt, "no annotated frames")
    (tmp_path / "d").mkdir()
    one_error(lambda: read_mot(tmp_path / "d"), tmp_path / "d", "no *.gt.txt ground-truth files")
    junk = write(tmp_path / "e" / "videos" / "c.mp4", "not a video")
    gt = write(tmp_path / "e" / "annotations" / "c.gt.txt", "1,1,10,10,100,80,1,1,1\n")
    one_error(lambda: read_mot(gt), junk, "not a video")
