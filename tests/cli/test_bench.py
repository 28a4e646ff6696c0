"""``python -m fastdet bench``: a stage table on a test image, and one-line errors for bad input."""
from __future__ import annotations

import re
from pathlib import Path

import pytest

from fastdet import cli
from fastdet.cli import bench


def test_bench_image_prints_stage_table(test_images, capsys):
    rc = cli.main(["bench", str(test_images[0]), "--frames", "2", "--repeat", "1", "--threads", "1"])
    out = capsys.readouterr().out
    assert rc == 0
    assert "1280x720" in out and "2 frames x 1 repeats" in out and "1 thread(s)" in out
    for label, _ in bench.STAGES:
        assert re.search(rf"^{re.escape(label)}\s+\d+\.\d\d\s+\d+\.\d\d\s+\d+%$", out, re.M), label
    total = float(re.search(r"^total \(wall\)\s+(\d+\.\d+)", out, re.M).group(1))
    fps = float(re.search(r"^fps\s+(\d+\.\d+)", out, re.M).group(1))
    assert total > 0 and fps == pytest.approx(1e3 / total, rel=0.02)


def test_bench_default_input_is_test1(data, capsys):
    assert cli.main(["bench", "--frames", "2", "--repeat", "1"]) == 0
    assert "test1.jpg (image, 1280x720)" in capsys.readouterr().out


def test_bench_video_reports_decode(data, capsys):
    clip = data / "videos" / "test_small1.mp4"
    assert cli.main(["bench", str(clip), "--frames", "2", "--repeat", "1"]) == 0
    out = capsys.readouterr().out
    assert "(video, 1280x720), 2 frames" in out and "decode" in out


@pytest.mark.parametrize("kind", ["missing", "folder", "garbage.jpg", "garbage.mp4"])
def test_bench_bad_input_one_line_exit_2(tmp_path, capsys, kind):
    path = tmp_path / kind
    if kind == "folder":
        path.mkdir()
    elif kind != "missing":
        path.write_bytes(b"not an image, not a video\n" * 10)
    rc = cli.main(["bench", str(path), "--frames", "2"])
    captured = capsys.readouterr()
    assert rc == 2
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("fastdet bench: error: "), captured.err
    assert str(path) in lines[0]
    assert "Traceback" not in captured.err and captured.out == ""


def test_bench_too_many_threads(test_images, capsys):
    import numba

    rc = cli.main(["bench", str(test_images[0]), "--frames", "1", "--threads", str(numba.config.NUMBA_NUM_THREADS + 1)])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "NUMBA_NUM_THREADS" in err[0]


def test_bench_bad_frames_is_a_usage_error(capsys):
    with pytest.raises(SystemExit) as exc:
        cli.main(["bench", "--frames", "0"])
    assert exc.value.code == 2


def test_load_frames_video_is_shorter_than_asked(data):
    frames, kind, decode_ms = bench.load_frames(Path(data) / "videos" / "test_small1.mp4", 1000)
    assert kind == "video" and 80 <= len(frames) <= 91 and decode_ms > 0


def test_bench_missing_oncoming_model(test_images, capsys):
    rc = cli.main(["bench", str(test_images[0]), "--frames", "1", "--oncoming-model", "/nonexistent/wide.npz"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "wide.npz" in err[0]
