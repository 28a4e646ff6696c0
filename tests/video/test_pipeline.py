"""VideoDetector, iter_video_detections and ``python -m fastdet video`` end to end, with a
FAKE detector (windows around bright regions) on a synthetic video of a moving bright
rectangle, so these tests do not depend on the real Detector or a trained model."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from fastdet import cli
from fastdet.cli import video
from fastdet.cli.main import build_parser
from fastdet.config import HeatConfig, PipelineConfig
from fastdet.errors import DataError
from fastdet.io.atomic import partial_name
from fastdet.video import VideoDetector, iter_video_detections, make_detector
from tests.fakes import BrightBoxDetector
from tests.reference import box_iou as iou

W, H = 320, 240
RECT_W, RECT_H = 80, 60
# each fake window has heat 2.5; 5 overlap inside the rectangle, 1 just outside it: with a
# threshold of 8 and a short memory the box is the rectangle, lagging a few pixels
HEAT = HeatConfig(n_frames=3, decay=0.5, threshold=8.0)
# the synthetic rectangles are not vehicles: the learned box refinement (trained on cars) is off
HEAT_ARGS = ("--heat-frames", "3", "--heat-decay", "0.5", "--heat-threshold", "8", "--no-refine")


def rect_at(i: int) -> tuple[int, int, int, int]:
    """Where the bright rectangle is in frame ``i`` (0-based): x1, y1, x2, y2."""
    x = 10 + 6 * i
    return x, 100, x + RECT_W, 100 + RECT_H


def synth_frame(i: int) -> np.ndarray:
    f = np.full((H, W, 3), 40, np.uint8)
    x1, y1, x2, y2 = rect_at(i)
    f[y1:y2, x1:x2] = 250
    return f


def write_video(path: Path, n: int, fourcc: str = "mp4v") -> Path:
    w = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*fourcc), 25, (W, H))
    assert w.isOpened()
    for i in range(n):
        w.write(synth_frame(i))
    w.release()
    return path


def count_frames(path: Path) -> int:
    cap = cv2.VideoCapture(str(path))
    assert cap.isOpened(), path
    n = 0
    while cap.read()[0]:
        n += 1
    cap.release()
    return n


def read_mot(path: Path) -> list[list[float]]:
    return [[float(v) for v in line.split(",")] for line in path.read_text().splitlines() if line.strip()]


def parse(*argv: str):
    return build_parser("video").parse_args(["video", *map(str, argv)])


@pytest.fixture(scope="module")
def clip(tmp_path_factory) -> Path:
    return write_video(tmp_path_factory.mktemp("clip") / "clip.mp4", 30)


# ------------------------------------------------------------------------- VideoDetector


def test_video_detector_follows_the_rectangle():
    fake = BrightBoxDetector()
    vd = VideoDetector(fake, PipelineConfig(heat=HEAT, refine=None))
    for i in range(20):
        out = vd.update(synth_frame(i))
        assert len(out.boxes) == 1
        assert iou(out.boxes[0], rect_at(i)) > 0.8
        assert len(vd.debug.windows.boxes) == 5
        assert vd.debug.windows.scale.tolist() == [1, 1.5, 2, 2.5, 3]
        assert vd.debug.heat.shape == (H // 4, W // 4)
        assert vd.debug.mask.dtype == bool and vd.debug.mask.any()
        assert vd.debug.labels.max() == 1
        assert set(vd.timings) >= {"resize_colour", "hog", "score", "heat", "label"}
    vd.update(synth_frame(0), rgb=True)
    assert fake.rgb_args[-1] is True
    vd.reset()
    assert vd.heatmap.n_seen == 0 and len(vd.debug.windows.boxes) == 0
    out = vd.update(np.zeros((120, 160, 3), np.uint8))  # another size: a new heat map
    assert len(out.boxes) == 0 and vd.heatmap.frame_shape == (120, 160)
    with pytest.raises(ValueError):
        vd.update(np.zeros((10, 10), np.uint8))


def test_iter_video_detections_numbers_frames_from_the_file(clip):
    out = list(iter_video_detections(clip, PipelineConfig(heat=HEAT, refine=None), detector=BrightBoxDetector(),
                                     progress=False))
    assert [f for f, _ in out] == list(range(1, 31))
    assert all(len(d.boxes) == 1 and iou(d.boxes[0], rect_at(f - 1)) > 0.8 for f, d in out)
    out = list(iter_video_detections(clip, start=3, frames=5, detector=BrightBoxDetector(), progress=False))
    assert [f for f, _ in out] == [4, 5, 6, 7, 8]
    with pytest.raises(DataError, match="past the end"):
        list(iter_video_detections(clip, start=30, detector=BrightBoxDetector(), progress=False))


# ------------------------------------------------------------------------- CLI end to end


def test_cli_end_to_end(clip, tmp_path, capsys):
    out, boxes, js = tmp_path / "out.mp4", tmp_path / "boxes.txt", tmp_path / "boxes.jsonl"
    fake = BrightBoxDetector()
    rc = video.run(parse(clip, "-o", out, "--boxes", boxes, "--json", js, "--debug", "--profile",
                         "--no-progress", "--start", 5, "--frames", 20, *HEAT_ARGS), detector=fake)
    assert rc == 0 and fake.warmed
    assert count_frames(out) == 20
    assert not partial_name(out).exists()
    rows = read_mot(boxes)
    assert [int(r[0]) for r in rows] == list(range(6, 26))  # one box per frame, frames of the file
    assert rows[0][1] >= 1 and {r[1] for r in rows} == {rows[0][1]}  # one rectangle: one track id
    for r in rows:
        assert r[7:] == [-1, -1, -1]
        x, y, w, h = r[2:6]
        assert iou((x, y, x + w, y + h), rect_at(int(r[0]) - 1)) > 0.8
    lines = [json.loads(line) for line in js.read_text().splitlines()]
    assert [o["frame"] for o in lines] == list(range(6, 26))
    assert lines[0]["boxes"][0] == [rows[0][2], rows[0][3], rows[0][2] + rows[0][4], rows[0][3] + rows[0][5]]
    printed = capsys.readouterr().out
    assert "20 frames" in printed and "fps" in printed
    for stage in ("decode", "resize/colour", "HOG", "scoring", "heat", "label", "draw", "encode"):
        assert stage in printed


def test_boxes_only_and_empty_frames(tmp_path, capsys):
    # a dark video: no windows, no boxes, an empty boxes file and a JSON line per frame
    path = tmp_path / "dark.avi"
    w = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 25, (W, H))
    for _ in range(4):
        w.write(np.zeros((H, W, 3), np.uint8))
    w.release()
    boxes, js = tmp_path / "b.txt", tmp_path / "b.jsonl"
    assert video.run(parse(path, "--boxes", boxes, "--json", js, "--no-progress"), detector=BrightBoxDetector()) == 0
    assert boxes.read_text() == ""
    assert [json.loads(x)["boxes"] for x in js.read_text().splitlines()] == [[]] * 4


def test_output_written_under_temporary_name_then_renamed(clip, tmp_path):
    out = tmp_path / "o.mp4"
    seen = []

    def check(k):
        seen.append((partial_name(out).exists(), out.exists()))

    video.run(parse(clip, "-o", out, "--no-progress", "--frames", 6), detector=BrightBoxDetector(on_frame=check))
    assert partial_name(out).parent == tmp_path and partial_name(out).name.startswith(".o.partial.")
    assert seen and all(s == (True, False) for s in seen)
    assert out.exists() and not partial_name(out).exists()


def test_ctrl_c_keeps_a_playable_video_and_complete_boxes(clip, tmp_path):
    out, boxes = tmp_path / "o.mp4", tmp_path / "b.txt"

    def interrupt(k):
        if k == 11:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        video.run(parse(clip, "-o", out, "--boxes", boxes, "--no-progress"), detector=BrightBoxDetector(interrupt))
    assert count_frames(out) == 10
    assert not partial_name(out).exists()
    assert [int(r[0]) for r in read_mot(boxes)] == list(range(1, 11))


def test_truncated_video_ends_where_decoding_ends(tmp_path, capsys):
    """The header of a truncated file still says 20 frames: the run processes the frames that
    decode, writes them all (video and boxes, aligned), exits 0 and says so in one note."""
    good = write_video(tmp_path / "good.avi", 20, fourcc="MJPG")
    data = good.read_bytes()
    bad = tmp_path / "bad.avi"
    bad.write_bytes(data[: len(data) // 2])  # truncated: the header still says 20 frames
    out, boxes = tmp_path / "o.mp4", tmp_path / "b.txt"
    assert video.run(parse(bad, "-o", out, "--boxes", boxes, "--no-progress"), detector=BrightBoxDetector()) == 0
    n = count_frames(out)
    assert 0 < n < 20
    assert [int(r[0]) for r in read_mot(boxes)] == list(range(1, n + 1))
    captured = capsys.readouterr()
    assert f"{n} frames in" in captured.out
    assert f"{n} frames decoded" in captured.err and "header estimated 20" in captured.err


# ------------------------------------------------------------------------- bad input


def _main_fails(argv, capsys, match: str):
    rc = cli.main(["video", *map(str, argv)])
    err = capsys.readouterr().err
    assert rc == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert "Traceback" not in err and match in lines[0], err
    return lines[0]


def test_bad_inputs(clip, tmp_path, capsys):
    txt = tmp_path / "notes.mp4"
    txt.write_text("this is not a video\n")
    zero = tmp_path / "zero.avi"
    w = cv2.VideoWriter(str(zero), cv2.VideoWriter_fourcc(*"MJPG"), 25, (W, H))
    w.release()
    out = tmp_path / "o.mp4"
    _main_fails([tmp_path / "missing.mp4", "-o", out], capsys, "file not found")
    _main_fails([txt, "-o", out], capsys, "not a video")
    _main_fails([zero, "-o", out], capsys, "no frames")
    _main_fails([clip, "-o", tmp_path / "nowhere" / "o.mp4"], capsys, "does not exist")
    _main_fails([clip, "--boxes", tmp_path / "nowhere" / "b.txt"], capsys, "does not exist")
    _main_fails([clip, "-o", tmp_path], capsys, "is a folder")
    _main_fails([clip], capsys, "nothing to write")
    _main_fails([clip, "-o", clip], capsys, "overwrite the input")
    _main_fails([clip, "-o", out, "--heat-decay", "0"], capsys, "decay")
    assert sorted(tmp_path.iterdir()) == sorted([txt, zero])  # no output was created


def test_output_folder_not_writable(clip, tmp_path, capsys):
    # a "folder" that is a file: no user (root included) can create files in it
    blocker = tmp_path / "file"
    blocker.write_text("x")
    _main_fails([clip, "-o", blocker / "o.mp4"], capsys, "does not exist")
    if os.geteuid() != 0:  # root ignores permissions
        ro = tmp_path / "ro"
        ro.mkdir()
        ro.chmod(0o500)
        try:
            _main_fails([clip, "-o", ro / "o.mp4"], capsys, "not writable")
        finally:
            ro.chmod(0o700)


def test_unwritable_extension_leaves_nothing(clip, tmp_path, capsys):
    with pytest.raises(DataError, match="cannot write a video"):
        video.run(parse(clip, "-o", tmp_path / "o.xyz", "--no-progress"), detector=BrightBoxDetector())
    assert list(tmp_path.iterdir()) == []


def test_bad_model_exits_2_without_traceback(clip, tmp_path):
    bad = tmp_path / "model.npz"
    bad.write_text("not a model")
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[2])}
    r = subprocess.run([sys.executable, "-m", "fastdet", "video", str(clip), "--boxes", str(tmp_path / "b.txt"),
                        "--model", str(bad), "--no-progress"], capture_output=True, text=True, env=env, timeout=120)
    assert r.returncode == 2, r.stderr
    assert "Traceback" not in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert "model" in r.stderr
    assert not (tmp_path / "b.txt").exists()


def test_bad_oncoming_model_exits_2_without_traceback(clip, tmp_path, capsys):
    bad = tmp_path / "wide.npz"
    bad.write_text("not a model")
    assert cli.main(["video", str(clip), "--boxes", str(tmp_path / "b.txt"), "--oncoming-model", str(bad),
                     "--no-progress"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "wide.npz" in err[0]
    assert not (tmp_path / "b.txt").exists()
    with pytest.raises(SystemExit) as exc:  # argparse: not both
        cli.main(["video", str(clip), "--boxes", str(tmp_path / "b.txt"), "--oncoming-model", str(bad),
                  "--no-oncoming"])
    assert exc.value.code == 2 and "not allowed with" in capsys.readouterr().err


def test_make_detector_oncoming_choices():
    from fastdet.model import ONCOMING_MODEL_PATH, load_model

    assert make_detector().oncoming_model is not None  # the bundled oncoming model
    assert make_detector(PipelineConfig(oncoming=False)).oncoming_model is None
    assert make_detector(PipelineConfig(oncoming=str(ONCOMING_MODEL_PATH))).oncoming_model is not None
    wide = load_model(ONCOMING_MODEL_PATH)
    assert wide.config.window_height == 24 and wide.config.win_w == 64
    from fastdet.errors import ModelError
    from fastdet.model import DEFAULT_MODEL_PATH

    with pytest.raises(ModelError, match="not a wide-window model"):
        make_detector(PipelineConfig(oncoming=DEFAULT_MODEL_PATH))


def test_a_detector_with_components_is_refused():
    """The heat map takes the main model's windows only, so a Detector's components would be
    searched and then dropped: VideoDetector says so instead."""
    from fastdet.config import SearchBand, SearchConfig
    from fastdet.detect import Detector

    comp = Detector(components=[(None, SearchConfig(bands=(SearchBand(1.0, 380, 480),)))])
    with pytest.raises(ValueError, match="components"):
        VideoDetector(comp)
    VideoDetector(Detector())  # without components: fine


# ------------------------------------------------------------------------- the real detector


def test_real_detector_on_the_test_video(data, tmp_path):
    """The real Detector (bundled model) through the whole CLI on 6 frames of the test clip:
    the interface VideoDetector relies on (stats timings, the scale and part columns, score_kind) still holds."""
    from fastdet.model import DEFAULT_MODEL_PATH

    if not DEFAULT_MODEL_PATH.exists():
        pytest.skip("no bundled model")
    clip = data / "videos" / "test_video.mp4"
    boxes, out = tmp_path / "b.txt", tmp_path / "o.mp4"
    assert video.run(parse(clip, "-o", out, "--boxes", boxes, "--debug", "--no-progress", "--start", 20,
                           "--frames", 6)) == 0
    assert count_frames(out) == 6
    rows = read_mot(boxes)
    assert rows and {int(r[0]) for r in rows} <= set(range(21, 27))
    vd = VideoDetector()
    cap = cv2.VideoCapture(str(clip))
    vd.update(cap.read()[1])
    vd.update(cap.read()[1])
    assert set(vd.timings) >= {"resize_colour", "hog", "score", "heat", "label", "motion"}
    assert len(vd.debug.windows.scale) == len(vd.debug.windows.part) == len(vd.debug.windows.boxes) > 0
    rows = read_mot(boxes)
    assert video.run(parse(clip, "--boxes", boxes, "--no-progress", "--start", 20, "--frames", 6,
                           "--no-oncoming")) == 0
    assert {tuple(r) for r in read_mot(boxes)} <= {tuple(r) for r in rows}  # the main boxes, nothing added
