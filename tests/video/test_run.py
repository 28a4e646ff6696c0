"""``fastdet.detect_video``: the Python API gives exactly what ``python -m fastdet video`` gives,
on real clips with the bundled models (byte-identical MOTChallenge box files)."""
from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np
import pytest

import fastdet
from fastdet import Detections, VideoDetector, detect_video
from fastdet.io.motfiles import MotWriter
from fastdet.video.horizon import HORIZON_FRAMES
from tests.processes import finished

ROOT = Path(__file__).resolve().parents[2]

# a 1280x720 clip at 25 fps (38 frames) and an 800x450 one at 20 fps (40 frames)
CLIPS = ["test_video", "boston_street"]


def _cli_boxes(clip: Path, out: Path) -> subprocess.Popen:
    """``python -m fastdet video CLIP --boxes OUT`` started in a process of its own, this
    checkout's code (:func:`_cli_done` waits for it and reads OUT): it runs while the test
    computes the same clip here."""
    env = {**os.environ, "PYTHONPATH": str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", "")}
    return subprocess.Popen([sys.executable, "-m", "fastdet", "video", str(clip), "--boxes", str(out), "--no-progress"],
                            cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _cli_done(p: subprocess.Popen, out: Path) -> bytes:
    r = finished(p, 600)
    assert r.returncode == 0, r.stderr
    return out.read_bytes()


@pytest.fixture(scope="module")
def api_frames(data: Path) -> Callable[[str], list[Detections]]:
    """``list(detect_video(clip))`` of a clip of :data:`CLIPS` with the default settings, run once
    for the module (the byte-for-byte test and the hand-loop test read the same run)."""
    runs: dict[str, list[Detections]] = {}

    def get(name: str) -> list[Detections]:
        if name not in runs:
            runs[name] = list(detect_video(data / "videos" / f"{name}.mp4"))
        return runs[name]

    return get


def _written(frames: list[Detections], path: Path) -> bytes:
    with MotWriter(path) as w:
        w.write_table(Detections.concat(frames))
    return path.read_bytes()


@pytest.mark.parametrize("name", CLIPS)
def test_detect_video_gives_the_cli_boxes_and_ids_byte_for_byte(data, tmp_path, name, api_frames):
    clip = data / "videos" / f"{name}.mp4"
    cli = _cli_boxes(clip, tmp_path / "cli.txt")
    try:
        frames = api_frames(name)
    except BaseException:
        cli.kill()
        cli.wait()
        raise
    want = _cli_done(cli, tmp_path / "cli.txt")
    n = int(cv2.VideoCapture(str(clip)).get(cv2.CAP_PROP_FRAME_COUNT))
    assert len(frames) == n  # one table a frame, empty ones included
    for i, d in enumerate(frames, 1):
        assert d.frames is not None and d.ids is not None and d.scores is not None
        assert (d.frames == i).all() and (d.ids >= 1).all()
    clip_table = Detections.concat(frames)
    assert len(clip_table) > 20 and clip_table.has_ids
    assert _written(frames, tmp_path / "api.txt") == want
    # frame by frame through the writer, as the CLI writes them: the same bytes too
    with MotWriter(tmp_path / "api2.txt") as w:
        for d in frames:
            if len(d):
                w.write_detections(int(d.frames[0]), d)
    assert (tmp_path / "api2.txt").read_bytes() == want


def test_the_documented_hand_loop_equals_detect_video(data, api_frames):
    """detect_video's docstring: the frame rate and the horizon primed from the first 75
    frames are what a ``VideoDetector().update`` loop lacks; with them it gives the same
    (``detect_video``'s run: the one the byte-for-byte test compares with the CLI's)."""
    clip = data / "videos" / "boston_street.mp4"
    cap = cv2.VideoCapture(str(clip))
    fps = cap.get(cv2.CAP_PROP_FPS)
    video = []
    while (ok_frame := cap.read())[0]:
        video.append(ok_frame[1])
    vd = VideoDetector(fps=fps)
    vd.prime_horizon(video[:HORIZON_FRAMES])
    by_hand = [vd.update(f) for f in video]
    api = api_frames("boston_street")
    assert len(by_hand) == len(api)
    for h, a in zip(by_hand, api):
        np.testing.assert_array_equal(h.boxes, a.boxes)
        np.testing.assert_array_equal(h.ids, a.ids)
        np.testing.assert_array_equal(h.scores, a.scores)


def test_detect_video_settings_start_frames_and_errors(data):
    clip = data / "videos" / "boston_street.mp4"
    got = list(detect_video(clip, start=5, frames=4, tracker=None))  # --start 5 --frames 4 --no-track
    assert len(got) == 4
    for fno, d in zip(range(6, 10), got):
        assert d.frames.tolist() == [fno] * len(d) and d.ids.tolist() == [-1] * len(d)
    with pytest.raises(TypeError):
        next(detect_video(clip, no_such_setting=1))
    with pytest.raises(ValueError, match="tracker"):
        next(detect_video(clip, offline=True, tracker=None))


def test_detect_video_is_exported():
    assert fastdet.detect_video is detect_video and "detect_video" in fastdet.__all__
    assert fastdet.Box is fastdet.detections.Box and "Box" in fastdet.__all__
