"""``python -m fastdet label``: the shared teacher files' format (one strict parser reads
both), boxes that agree with the shared teacher in kind, and every bad input, failed write
and stop signal ending in one line with no file under a final name."""
from __future__ import annotations

import os
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from fastdet.cli.main import main
from fastdet.eval.matching import match_frame
from tests.media import fastdet_cmd, leftovers, run_limited, write_video
from tests.teacher.onnx_bytes import FLOAT, write_identity_model

pytest.importorskip("onnxruntime")

from fastdet.teacher import TeacherDetector, label_video, teacher_text  # noqa: E402

# frame,-1,left,top,width,height,score,class,-1,-1: px with one decimal, the score with three
_LINE = re.compile(r"(\d+),-1,(\d+\.\d),(\d+\.\d),(\d+\.\d),(\d+\.\d),(0\.\d{3}|1\.000),(2|3|5|7),-1,-1")
_NUMBER = re.compile(r"[1-9]\d*")


def parse_teacher(boxes: Path, frames: Path) -> tuple[list[int], np.ndarray]:
    """Strictly: the frame list (increasing, one number a line) and the box lines
    ``(frame, left, top, width, height, score, class)`` (every line in the format, every
    frame a listed one, frames in order, scores >= 0.1)."""
    ftext, btext = frames.read_text(), boxes.read_text()
    assert ftext.endswith("\n") and (btext == "" or btext.endswith("\n"))
    numbers = []
    for line in ftext.splitlines():
        assert _NUMBER.fullmatch(line), f"{frames}: {line!r}"
        numbers.append(int(line))
    assert numbers == sorted(set(numbers)), frames
    rows = []
    for line in btext.splitlines():
        m = _LINE.fullmatch(line)
        assert m, f"{boxes}: {line!r}"
        rows.append([float(v) for v in m.groups()])
    a = np.array(rows, np.float64).reshape(-1, 7)
    assert set(a[:, 0].astype(int)) <= set(numbers), boxes
    assert np.all(np.diff(a[:, 0]) >= 0) and np.all(a[:, 5] >= 0.1), boxes
    return numbers, a


def matched_f1(ours: np.ndarray, theirs: np.ndarray, frames: list[int], score: float = 0.3) -> float:
    """F1 of our boxes against theirs (both at ``score`` or more), IoU 0.5, class-blind."""
    tp = fp = fn = 0

    def boxes(a: np.ndarray, f: int) -> np.ndarray:
        r = a[(a[:, 0] == f) & (a[:, 5] >= score)]
        return r[:, 1:5], r[:, 5]

    for f in frames:
        (pb, ps), (gb, _) = boxes(ours, f), boxes(theirs, f)
        to_xyxy = np.array([[1, 0, 0, 0], [0, 1, 0, 0], [1, 0, 1, 0], [0, 1, 0, 1]], np.float64).T
        hit, _, _ = match_frame(pb @ to_xyxy, ps, gb @ to_xyxy)
        tp += int(hit.sum())
        fp += int((~hit).sum())
        fn += len(gb) - int(hit.sum())
    return 2 * tp / (2 * tp + fp + fn)


@pytest.fixture(scope="module")
def model(yolox_nano: Path) -> Path:
    return yolox_nano


@pytest.fixture(scope="module")
def test_video(data: Path) -> Path:
    return data / "videos" / "test_video.mp4"


def _label(*args: object) -> int:
    return main(["label", *map(str, args), "--no-progress"])


def _one_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


# ------------------------------------------------------------------ format and agreement


def test_the_strict_parser_reads_every_shared_teacher_file(data):
    files = sorted((data / "teacher").glob("*.teacher.txt"))
    assert len(files) == 17
    for f in files:
        numbers, _ = parse_teacher(f, f.with_name(f.name.replace(".teacher.txt", ".frames")))
        assert numbers[:2] == [1, 6]


@pytest.mark.slow
def test_label_a_teacher_clip_like_the_shared_teacher(model, data, tmp_path, capsys):
    """neeraj_test (194 frames of 640x352): the same frames looked at, files the same parser
    reads, and boxes that agree with the shared teacher (a bigger ensemble at 960 px: F1 0.81
    when this was written; the floor leaves room for onnxruntime versions)."""
    clip = data / "videos" / "neeraj_test.mp4"
    assert _label(clip, "--teacher", model, "-o", tmp_path / "out") == 0
    summary = capsys.readouterr().out
    assert re.fullmatch(r"fastdet label: 1 clip, 39 frames labelled \(1 in 5 of 194 read\), \d+ boxes in "
                        r"[\d.]+ s; wrote 2 files into .*out\n", summary), summary
    ours_frames, ours = parse_teacher(tmp_path / "out" / "neeraj_test.teacher.txt",
                                      tmp_path / "out" / "neeraj_test.frames")
    shared_frames, shared = parse_teacher(data / "teacher" / "neeraj_test.teacher.txt",
                                          data / "teacher" / "neeraj_test.frames")
    assert ours_frames == shared_frames == list(range(1, 195, 5))
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["neeraj_test.frames", "neeraj_test.teacher.txt"]
    assert matched_f1(ours, shared, ours_frames) >= 0.7


def test_dir_every_and_the_python_api_agree(model, test_video, tmp_path, capsys):
    d = tmp_path / "in"
    d.mkdir()
    shutil.copy(test_video, d / "b.mp4")
    (d / "notes.txt").write_text("not a video, left out\n")
    (d / ".hidden.mp4").write_text("hidden, left out\n")
    (d / "sub").mkdir()
    assert _label(d, "--teacher", model, "-o", tmp_path / "new" / "out", "--every", "10", "--size", "320") == 0
    out = tmp_path / "new" / "out"
    assert sorted(p.name for p in out.iterdir()) == ["b.frames", "b.teacher.txt"]
    numbers, rows = parse_teacher(out / "b.teacher.txt", out / "b.frames")
    assert numbers == [1, 11, 21, 31]
    assert len(rows) >= 4  # two cars close by in every frame
    assert "1 clip, 4 frames labelled (1 in 10 of 38 read)" in capsys.readouterr().out
    labelled = label_video(test_video, TeacherDetector(model, size=320), every=10)
    boxes_text, frames_text = teacher_text(labelled)
    assert (out / "b.teacher.txt").read_text() == boxes_text
    assert (out / "b.frames").read_text() == frames_text


# ------------------------------------------------------------------ bad input: one line, nothing written


def test_bad_inputs_one_line_before_any_output(model, test_video, tmp_path, capsys):
    out = tmp_path / "out"
    text = tmp_path / "t.mp4"
    text.write_text("not a video\n")
    junk = tmp_path / "junk.onnx"
    junk.write_bytes(b"\x00\x01not onnx" * 50)
    identity = write_identity_model(tmp_path / "id.onnx", [((1, 3, "h", "w"), FLOAT)])
    empty = tmp_path / "empty"
    empty.mkdir()
    cases = [
        ((tmp_path / "missing.mp4", "--teacher", model), "missing.mp4: file not found"),
        ((text, "--teacher", model), "t.mp4: not a video OpenCV can read"),
        ((empty, "--teacher", model), "empty: no video files in this folder"),
        ((test_video, "--teacher", tmp_path / "none.onnx"), "none.onnx: file not found"),
        ((test_video, "--teacher", junk), "junk.onnx: not an ONNX model onnxruntime can load"),
        ((test_video, "--teacher", identity), "id.onnx: not a YOLOX-style detector: its output is"),
    ]
    for args, message in cases:
        assert _label(*args, "-o", out) == 2, args
        line = _one_line(capsys.readouterr().err)
        assert line.startswith("fastdet label: error: ") and message in line, line
        assert not out.exists()


def test_outputs_that_are_inputs_or_not_folders(model, test_video, tmp_path, capsys):
    a_file = tmp_path / "file"
    a_file.write_text("x\n")
    assert _label(test_video, "--teacher", model, "-o", a_file) == 2
    assert "is not a folder" in _one_line(capsys.readouterr().err)
    assert _label(test_video, "--teacher", model, "-o", a_file / "sub") == 2
    assert "cannot make the folder" in _one_line(capsys.readouterr().err)
    assert a_file.read_text() == "x\n"

    # the video is named like an output: OUT/c.frames would be the input
    d = tmp_path / "d"
    d.mkdir()
    video = d / "c.frames"
    shutil.copy(test_video, video)
    before = video.read_bytes()
    assert _label(video, "--teacher", model, "-o", d) == 2
    assert "would overwrite the input VIDEO" in _one_line(capsys.readouterr().err)
    assert video.read_bytes() == before and leftovers(d) == []

    # the teacher is named like an output
    shutil.copy(model, d / "test_video.teacher.txt")
    assert _label(test_video, "--teacher", d / "test_video.teacher.txt", "-o", d) == 2
    assert "would overwrite the input --teacher" in _one_line(capsys.readouterr().err)

    # two clips of one name in DIR
    two = tmp_path / "two"
    two.mkdir()
    shutil.copy(test_video, two / "a.mp4")
    shutil.copy(test_video, two / "a.mov")
    assert _label(two, "--teacher", model, "-o", tmp_path / "o2") == 2
    assert "are one file" in _one_line(capsys.readouterr().err)
    assert not (tmp_path / "o2").exists()  # the folder it made is gone again


@pytest.mark.parametrize(("option", "value"), [
    ("--every", "0"), ("--every", "x"), ("--every", "-5"), ("--size", "31"), ("--size", "4097"), ("--size", "6.5"),
    ("--min-score", "0"), ("--min-score", "nan"), ("--min-score", "1.5"), ("--min-score", "inf"), ("--threads", "0"),
])
def test_numbers_out_of_their_domain(model, test_video, tmp_path, capsys, option, value):
    with pytest.raises(SystemExit) as exc:
        _label(test_video, "--teacher", model, "-o", tmp_path / "out", option, value)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert f"argument {option}" in err and "Traceback" not in err
    assert not (tmp_path / "out").exists()


def test_without_onnxruntime_one_line(model, test_video, tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "onnxruntime", None)  # import onnxruntime -> ImportError
    assert _label(test_video, "--teacher", model, "-o", tmp_path / "out") == 2
    assert "install 'fastdet[teacher]'" in _one_line(capsys.readouterr().err)
    assert not (tmp_path / "out").exists()


def test_fastdet_and_the_other_commands_do_not_import_onnxruntime():
    code = ("import sys, fastdet, fastdet.teacher, fastdet.cli.label\n"
            "from fastdet.cli.main import build_parser\n"
            "build_parser(None)\n"  # every command's module
            "assert 'onnxruntime' not in sys.modules, 'imported'\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=False)
    assert r.returncode == 0, r.stderr


# ------------------------------------------------------------------ failed writes and stop signals


@pytest.mark.slow
def test_a_failed_write_leaves_no_file(model, test_video, tmp_path):
    out = tmp_path / "out"
    r = run_limited(fastdet_cmd("label", test_video, "--teacher", model, "-o", out, "--no-progress"), 100)
    assert r.returncode == 2, r.stderr
    line = _one_line(r.stderr)
    assert "test_video.teacher.txt: cannot write" in line
    assert not out.exists() and r.stdout == ""


@pytest.fixture(scope="module")
def long_clip(tmp_path_factory) -> Path:
    """Long enough (1500 frames, each labelled) that no run ends before the signal reaches it."""
    return write_video(tmp_path_factory.mktemp("long") / "long.mp4", 1500, ("-c:v", "mpeg4", "-q:v", "8"))


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_a_stop_signal_leaves_no_file_under_the_final_name(model, long_clip, tmp_path, sig):
    out = tmp_path / "out"
    p = subprocess.Popen(fastdet_cmd("label", long_clip, "--teacher", model, "-o", out, "--every", "1",
                                     "--no-progress"),
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    end = time.monotonic() + 120
    while not out.exists():  # made after every check, just before the first frame
        assert p.poll() is None, p.communicate()
        assert time.monotonic() < end
        time.sleep(0.05)
    time.sleep(1.0)  # well into the frames
    os.kill(p.pid, sig)
    stdout, err = p.communicate(timeout=120)
    assert p.returncode == 128 + sig, err
    line = _one_line(err)
    assert f"interrupted ({signal.Signals(sig).name})" in line and "wrote nothing" in line, line
    assert "1 clip not labelled" in line and stdout == ""
    assert not (out / "long.teacher.txt").exists() and not (out / "long.frames").exists()
    assert not out.exists() or (list(out.iterdir()) == [] and leftovers(out) == [])


@pytest.mark.slow
def test_a_stop_keeps_the_clips_done_before_it(model, test_video, long_clip, tmp_path):
    d = tmp_path / "in"
    d.mkdir()
    shutil.copy(test_video, d / "a.mp4")
    shutil.copy(long_clip, d / "b.mp4")
    out = tmp_path / "out"
    p = subprocess.Popen(fastdet_cmd("label", d, "--teacher", model, "-o", out, "--every", "1", "--no-progress"),
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    end = time.monotonic() + 180
    while not (out / "a.frames").exists():  # clip a done, b begun
        assert p.poll() is None, p.communicate()
        assert time.monotonic() < end
        time.sleep(0.05)
    time.sleep(0.5)
    os.kill(p.pid, signal.SIGTERM)
    _, err = p.communicate(timeout=120)
    assert p.returncode == 143, err
    line = _one_line(err)
    assert "interrupted (SIGTERM); 1 clip, 38 frames labelled" in line and "1 clip not labelled" in line, line
    assert sorted(x.name for x in out.iterdir()) == ["a.frames", "a.teacher.txt"]
    numbers, _ = parse_teacher(out / "a.teacher.txt", out / "a.frames")
    assert numbers == list(range(1, 39))
