"""Inputs that are valid but wrong for the job, arguments checked before the work, and
the wording of messages (issue 14, items 5, 6 and 7). Every refusal: exit 2, one line,
no output created."""
from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from fastdet.cli.main import main
from fastdet.config import PipelineConfig
from fastdet.detect.checks import check_frame_size, minimum_frame_size
from fastdet.errors import ModelError
from fastdet.model import DEFAULT_MODEL_PATH, ONCOMING_MODEL_PATH, load_model
from fastdet.video import make_detector
from tests.media import write_video


def _refused(argv, capsys, match: str) -> str:
    rc = main([str(a) for a in argv])
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert rc == 2 and len(lines) == 1 and match in lines[0], err
    assert "Traceback" not in err
    return lines[0]


# ------------------------------------------------------------------------- item 5


def test_wide_model_as_the_main_model_is_refused(tmp_path, capsys):
    with pytest.raises(ModelError, match="wide-window model"):
        make_detector(PipelineConfig(model=ONCOMING_MODEL_PATH))
    clip = write_video(tmp_path / "c.mp4", 3)
    _refused(["video", clip, "--boxes", tmp_path / "b.txt", "--model", ONCOMING_MODEL_PATH], capsys,
             "cannot be the main model")
    assert not (tmp_path / "b.txt").exists()


def test_grey_image_and_grey_video_are_refused(tmp_path, capsys):
    colour = np.dstack([np.tile(np.arange(640, dtype=np.uint8) // 3, (360, 1))] * 3)
    colour[100:200, 100:300] = (20, 200, 90)
    grey = cv2.cvtColor(cv2.cvtColor(colour, cv2.COLOR_BGR2GRAY), cv2.COLOR_GRAY2BGR)
    cv2.imwrite(str(tmp_path / "grey.jpg"), cv2.cvtColor(grey, cv2.COLOR_BGR2GRAY))  # a 1-channel JPEG
    _refused(["image", tmp_path / "grey.jpg", "-o", tmp_path / "o.jpg"], capsys, "greyscale")
    clip = write_video(tmp_path / "grey.mp4", 3, grey=True)
    _refused(["video", clip, "--boxes", tmp_path / "b.txt"], capsys, "greyscale")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["grey.jpg", "grey.mp4"]


def _faded_intro(path: Path, grey_frames: int, n: int) -> Path:
    """A colour clip whose first ``grey_frames`` frames are grey (a faded intro)."""
    import subprocess

    from tests.media import FFMPEG, INTRA, frames

    p = subprocess.Popen([FFMPEG, "-v", "error", "-y", "-f", "rawvideo", "-pix_fmt", "bgr24", "-s", "320x240",
                          "-r", "25", "-i", "-", *INTRA, str(path)], stdin=subprocess.PIPE)
    assert p.stdin is not None
    for i, f in enumerate(frames(n)):
        if i < grey_frames:
            f[:] = f.mean(axis=2, keepdims=True).astype(np.uint8)
        p.stdin.write(f.tobytes())
    p.stdin.close()
    assert p.wait() == 0
    return path


@pytest.mark.parametrize("grey_frames", [5, 70])
def test_colour_video_with_a_grey_intro_runs(tmp_path, capsys, grey_frames):
    """Issue 34 (6): a colour video whose first 5 frames are grey was refused as greyscale.
    70 grey frames: past the frames decoded ahead, found by the sample through the file."""
    clip = _faded_intro(tmp_path / "intro.mp4", grey_frames, 80)
    rc = main(["video", str(clip), "--boxes", str(tmp_path / "b.txt"), "--no-progress", "--frames", "80"])
    err = capsys.readouterr().err
    assert rc == 0 and "greyscale" not in err, err
    assert (tmp_path / "b.txt").exists()


def test_truncated_jpeg_is_refused(data, tmp_path, capsys):
    src = (data / "test_images" / "test1.jpg").read_bytes()
    cut = tmp_path / "cut.jpg"
    cut.write_bytes(src[: len(src) // 2])
    line = _refused(["image", cut, "-o", tmp_path / "o.jpg"], capsys, "cut short")
    assert "Premature" not in line
    _refused(["bench", cut, "--frames", "1"], capsys, "cut short")
    assert [p.name for p in tmp_path.iterdir()] == ["cut.jpg"]


@pytest.mark.parametrize("w, h", [(2, 2), (16, 720), (720, 10), (1280, 16)])
def test_frames_too_small_name_the_minimum(tmp_path, capsys, w, h):
    det = make_detector()
    mw, mh = minimum_frame_size(det)
    check_frame_size(det, (mh, mw), "minimum")  # the size the message names does run
    rng = np.random.default_rng(0)
    img = rng.integers(0, 255, (h, w, 3), dtype=np.uint8)
    cv2.imwrite(str(tmp_path / "in.png"), img)
    # the single-picture search has its own minimum: its smallest window (1/32 of the width, >= 16 px)
    from fastdet.config import PictureSearch

    if not PictureSearch().scales((h, w)):  # a 16x720 strip holds a 16-px window: searched
        _refused(["image", tmp_path / "in.png", "-o", tmp_path / "o.jpg"], capsys,
                 "too small for the picture search")
    frames_dir = tmp_path / "seq"
    frames_dir.mkdir()
    for i in range(3):
        cv2.imwrite(str(frames_dir / f"f{i}.png"), img)
    out = tmp_path / "out"
    out.mkdir()
    _refused(["video", frames_dir / "f%d.png", "-o", out / "o.mp4", "--boxes", out / "b.txt"], capsys,
             "too small for the vehicle search")
    assert list(out.iterdir()) == []


# ------------------------------------------------------------------------- item 6


@pytest.mark.parametrize("flag, value, match", [
    ("--max-per-folder", "0", "must be >= 1"),
    ("--max-per-folder", "-5", "must be >= 1"),
    ("--orientations", "0", "must be >= 1"),
    ("--C", "-1", "must be > 0"),
    ("--C", "0", "must be > 0"),
])
def test_train_arguments_are_checked_before_loading(tmp_path, capsys, flag, value, match):
    with pytest.raises(SystemExit) as exc:
        main(["train", "--data", str(tmp_path / "nothing"), "--out", str(tmp_path / "m.npz"), flag, value])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert match in err and flag in err


def test_train_output_folder_checked_before_the_data(tmp_path, capsys):
    # /sys is read-only even for root (a file-mode check would say "writable" to root)
    _refused(["train", "--data", tmp_path / "nothing", "--out", "/sys/m.npz"], capsys, "not writable")
    _refused(["train", "--data", tmp_path / "nothing", "--out", tmp_path / "m.npz"], capsys, "not found")
    _refused(["train", "--data", tmp_path, "--out", tmp_path / "m.npz", "--spatial-size", "7"], capsys,
             "feature options")


# ------------------------------------------------------------------------- item 7


def test_webm_blames_the_codec_before_any_work(tmp_path, capsys):
    clip = write_video(tmp_path / "c.mp4", 3)
    line = _refused(["video", clip, "-o", tmp_path / "o.webm"], capsys, "cannot write a video there")
    assert "mp4v" in line and ".mp4" in line
    assert "[webm" not in capsys.readouterr().err


def test_mine_negatives_read_only_out_is_refused_before_the_work(data, capsys):
    # /sys is read-only even for root: "mined N" with nothing written is what this replaces
    img = data / "test_images" / "test1.jpg"
    _refused(["mine-negatives", img, "--out", "/sys", "--x-range", "0", "1280"], capsys, "not writable")
    _refused(["mine-negatives", img, "--out", "/sys/negs", "--x-range", "0", "1280"], capsys, "not writable")


def test_mine_negatives_checks_its_input_before_creating_out(tmp_path, capsys):
    txt = tmp_path / "notes.txt"
    txt.write_text("not a video\n")
    out = tmp_path / "neg"
    line = _refused(["mine-negatives", txt, "--out", out, "--x-range", "0", "9"], capsys, "not a video")
    assert "WARN" not in line and not out.exists()


def _bad_model(tmp_path: Path, name: str, **changes) -> Path:
    with np.load(DEFAULT_MODEL_PATH) as npz:
        arrays = dict(npz)
    meta = json.loads(arrays["metadata"].tobytes())
    meta.update(changes.pop("meta", {}))
    arrays["metadata"] = np.frombuffer(json.dumps(meta).encode(), np.uint8)
    arrays.update(changes)
    path = tmp_path / name
    np.savez(path, **arrays)
    return path


def test_model_messages(tmp_path):
    with pytest.raises(ModelError, match=r"must be the number 1, got str \"1\""):
        load_model(_bad_model(tmp_path, "v.npz", meta={"format_version": "1"}))
    coef = np.load(DEFAULT_MODEL_PATH)["coef"]
    with pytest.raises(ModelError, match="'coef' holds"):
        load_model(_bad_model(tmp_path, "s.npz", coef=np.array(["abc"] * len(coef))))


def test_image_sequence_in_video_and_bench(tmp_path, capsys):
    from tests.media import frames

    for i, f in enumerate(frames(3, 640, 360), start=1):
        cv2.imwrite(str(tmp_path / f"test{i}.jpg"), f)
    assert main(["video", str(tmp_path / "test%d.jpg"), "--boxes", str(tmp_path / "b.txt"), "--no-progress"]) == 0
    assert main(["bench", str(tmp_path / "test%d.jpg"), "--frames", "2", "--repeat", "1"]) == 0
    assert "3 frames in" in capsys.readouterr().out


def test_unknown_flag_prints_the_commands_usage(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["video", "x.mp4", "--bogus"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "usage: python -m fastdet video INPUT" in err and "unrecognized arguments: --bogus" in err


def test_console_script_names_itself(tmp_path):
    import shutil
    import subprocess

    exe = shutil.which("fastdet")
    if exe is None:
        pytest.skip("the fastdet console script is not installed")
    r = subprocess.run([exe, "video", "x.mp4", "--bogus"], capture_output=True, text=True, check=False)
    assert r.returncode == 2 and "usage: fastdet video" in r.stderr and "python -m" not in r.stderr
