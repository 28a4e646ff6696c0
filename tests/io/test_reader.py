"""A video is what decodes (issue 14, item 1), on files made with a real muxer.

- ``ffmpeg -ss ... -c copy`` cuts: the header counts more frames than decode; every command
  that reads video ends at the end of the stream with exit 0 and at most one note.
- Damage in the middle: the frames that fail are reported in one note and skipped, the
  frames after them are processed and keep their numbers in the file.
- Live input: a clip served over HTTP from 127.0.0.1, a camera index, an image sequence.
"""
from __future__ import annotations

import json

import cv2
import pytest

from fastdet.cli.main import main
from fastdet.io.motfiles import read_predictions
from fastdet.io.reader import FrameReader, read_frames, read_frames_at, source_kind
from tests.media import (
    GOP12,
    INTRA,
    cut_copy,
    damage,
    decoded_count,
    frames,
    header_count,
    http_server,
    write_video,
)


@pytest.fixture(scope="module")
def cut(tmp_path_factory):
    """A real ``-ss 0.7 -c copy`` cut: its header counts more frames than decode."""
    d = tmp_path_factory.mktemp("cut")
    src = write_video(d / "src.mp4", 60, GOP12)
    out = cut_copy(src, d / "cut.mp4", 0.7)
    n, header = decoded_count(out), header_count(out)
    assert 0 < n < header  # what the tests below are about
    return out, n, header


@pytest.fixture(scope="module")
def damaged(tmp_path_factory):
    """An intra-only clip of 40 frames whose frames 16-18 (1-based) are zeroed."""
    d = tmp_path_factory.mktemp("damaged")
    src = write_video(d / "src.mp4", 40, INTRA)
    return damage(src, d / "damaged.mp4", [15, 16, 17])


def _err_lines(capsys) -> tuple[str, list[str]]:
    cap = capsys.readouterr()
    return cap.out, [ln for ln in cap.err.splitlines() if ln.strip()]


def test_reader_ends_where_decoding_ends(cut):
    path, n, header = cut
    notes = []
    with FrameReader(path, notify=notes.append) as r:
        got = [fno for fno, frame, _ in r]
    assert got == list(range(1, n + 1))
    assert r.decoded == n and r.skipped == []
    assert len(notes) == 1 and f"{n} frames decoded" in notes[0] and str(header) in notes[0]


def test_read_frames_is_every_frame_the_reader_yields(cut):
    path, n, _ = cut
    notes: list[str] = []
    got = read_frames(path, notify=notes.append)
    assert len(got) == n == decoded_count(path) and len(notes) == 1  # the header's count, once
    cap = cv2.VideoCapture(str(path))
    for frame in got:
        ok, want = cap.read()
        assert ok and (frame == want).all()
    cap.release()
    assert len(read_frames(path, start=2, frames=3, notify=notes.append)) == 3


def test_read_frames_at_gives_the_numbered_frames_only(cut):
    path, n, _ = cut
    every = read_frames(path, notify=lambda _: None)
    got = read_frames_at(path, [n, 2, 1, 2, n + 5], notify=lambda _: None)
    assert sorted(got) == [1, 2, n]  # 1-based; a number past the end is missing
    for k, frame in got.items():
        assert (frame == every[k - 1]).all()
    assert read_frames_at(path, []) == {}


def test_reader_no_note_when_stopped_by_frames(cut):
    path, _, _ = cut
    notes = []
    with FrameReader(path, start=2, frames=5, notify=notes.append) as r:
        assert [fno for fno, *_ in r] == [3, 4, 5, 6, 7]
    assert notes == []


def test_reader_skips_damage_and_keeps_numbers(damaged):
    notes = []
    with FrameReader(damaged, notify=notes.append) as r:
        got = [fno for fno, *_ in r]
    assert got == [*range(1, 16), *range(19, 41)]
    assert r.skipped == [(16, 18)] and r.n_skipped == 3
    assert len(notes) == 1 and "frames 16-18 could not be decoded" in notes[0]


@pytest.mark.parametrize("ahead", [0, 1, 10, 17, 200])
def test_peek_then_iterate_yields_every_frame_once(damaged, ahead):
    """peek(n) gives the next n frames (fewer at the end) and iteration yields them again,
    then the rest: the same numbers, pixels, notes and skipped ranges as without it."""
    with FrameReader(damaged, start=2, notify=lambda _n: None) as plain:
        want = [(fno, frame.copy()) for fno, frame, _ in plain]
    notes = []
    with FrameReader(damaged, start=2, notify=notes.append) as r:
        peeked = r.peek(ahead)
        assert len(peeked) == min(ahead, len(want))
        for (fno, frame), p in zip(want, peeked):
            assert (frame == p).all()
        assert r.peek(ahead) == peeked or all((a == b).all() for a, b in zip(r.peek(ahead), peeked))
        got = [(fno, frame) for fno, frame, _ in r]
    assert [f for f, _ in got] == [f for f, _ in want]
    assert all((a == b).all() for (_, a), (_, b) in zip(got, want))
    assert r.decoded == len(want) and r.skipped == [(16, 18)]
    assert len(notes) == 1


def test_peek_keeps_a_decoding_error_for_the_iteration(tmp_path):
    """A decoding error inside the frames peeked at is raised when the iteration reaches it,
    after the frames before it were yielded."""
    from fastdet.errors import DataError

    path = write_video(tmp_path / "v.mp4", 6, INTRA)
    r = FrameReader(path)
    real = r._read
    calls = [0]

    def failing():
        calls[0] += 1
        if calls[0] == 3:
            raise RuntimeError("boom")
        return real()

    r._read = failing
    try:
        assert len(r.peek(10)) == 3  # the first frame and two more, then the error
        got = []
        with pytest.raises(DataError, match="boom"):
            for fno, *_ in r:
                got.append(fno)
        assert got == [1, 2, 3]
    finally:
        r.close()


def test_video_cli_on_a_cut_exits_0_with_every_output(cut, tmp_path, capsys):
    path, n, header = cut
    out, boxes, js = tmp_path / "o.mp4", tmp_path / "b.txt", tmp_path / "b.jsonl"
    rc = main(["video", str(path), "-o", str(out), "--boxes", str(boxes), "--json", str(js), "--no-progress"])
    stdout, err = _err_lines(capsys)
    assert rc == 0, err
    assert f"{n} frames in" in stdout
    assert len(err) == 1 and "header" in err[0] and str(header) in err[0]  # one informational line
    assert decoded_count(out) == n
    lines = js.read_text().splitlines()
    assert [json.loads(ln)["frame"] for ln in lines] == list(range(1, n + 1))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["b.jsonl", "b.txt", "o.mp4"]


def test_video_cli_on_damage_processes_the_frames_after(damaged, tmp_path, capsys):
    js = tmp_path / "b.jsonl"
    rc = main(["video", str(damaged), "--json", str(js), "--no-progress"])
    stdout, err = _err_lines(capsys)
    assert rc == 0, err
    assert "3 damaged frames skipped" in stdout
    assert len(err) == 1 and "frames 16-18 could not be decoded" in err[0]
    frames = [json.loads(ln)["frame"] for ln in js.read_text().splitlines()]
    assert frames == [*range(1, 16), *range(19, 41)]


def test_eval_video_on_a_cut_prints_metrics(cut, tmp_path, capsys):
    path, n, _ = cut
    gt = tmp_path / "gt.txt"
    gt.write_text("".join(f"{f},1,10,80,60,50,1,1,1\n" for f in range(1, n + 1)))
    rc = main(["eval", "--gt", str(gt), "--video", str(path), "--json"])
    stdout, err = _err_lines(capsys)
    assert rc == 0, err
    result = json.loads(stdout)
    assert "error" not in stdout and result["video"] == str(path)


def test_bench_more_frames_than_decode(cut, capsys):
    path, n, header = cut
    rc = main(["bench", str(path), "--frames", str(header), "--repeat", "1", "--no-oncoming"])
    stdout, err = _err_lines(capsys)
    assert rc == 0, err
    assert f"{n} frames" in stdout


def test_live_http_stream(tmp_path, capsys):
    """A clip served over HTTP from 127.0.0.1 (MPEG-TS, as live streams are): no frame
    count, boxes for every frame."""
    write_video(tmp_path / "live.ts", 30, ("-c:v", "mpeg2video", "-q:v", "4"), extra=("-f", "mpegts"))
    boxes = tmp_path / "out" / "b.jsonl"
    boxes.parent.mkdir()
    with http_server(tmp_path) as url:
        with FrameReader(f"{url}/live.ts") as r:
            assert r.live and r.frame_count is None and r.expected is None
            assert sum(1 for _ in r) == 30
        rc = main(["video", f"{url}/live.ts", "--json", str(boxes), "--no-progress"])
    _, err = _err_lines(capsys)
    assert rc == 0, err
    assert [json.loads(ln)["frame"] for ln in boxes.read_text().splitlines()] == list(range(1, 31))


def test_live_sources_are_not_files(tmp_path, capsys):
    assert source_kind("rtsp://example.invalid/x") == "url"
    assert source_kind("7") == "camera" and source_kind(3) == "camera"
    rc = main(["video", "97", "--boxes", str(tmp_path / "b.txt")])
    _, err = _err_lines(capsys)
    assert rc == 2 and len(err) == 1 and "camera" in err[0] and "not found" not in err[0], err
    with http_server(tmp_path) as url:
        rc = main(["video", f"{url}/nothing.ts", "--boxes", str(tmp_path / "b.txt")])
    _, err = _err_lines(capsys)
    assert rc == 2 and len(err) == 1 and "not found" not in err[0], err
    assert list(tmp_path.iterdir()) == []


def test_image_sequence_is_a_video(tmp_path, capsys):
    for i, f in enumerate(frames(4), start=1):
        cv2.imwrite(str(tmp_path / f"img{i:03d}.png"), f)
    boxes = tmp_path / "b.txt"
    assert main(["video", str(tmp_path / "img%03d.png"), "--boxes", str(boxes), "--no-progress"]) == 0
    assert main(["bench", str(tmp_path / "img%03d.png"), "--frames", "2", "--repeat", "1", "--no-oncoming"]) == 0
    stdout, err = _err_lines(capsys)
    assert "4 frames in" in stdout and not err
    assert read_predictions(boxes).frames.max(initial=0) <= 4


# ------------------------------------------------------------------------------------------
# named pipes: a stream, read once


def _feed_fifo(fifo, data: bytes):
    import threading

    def feed():
        with open(fifo, "wb") as fh:
            fh.write(data)

    t = threading.Thread(target=feed, daemon=True)
    t.start()
    return t


def test_named_pipe_is_live_and_offline_refused_at_once(tmp_path, capsys):
    import os
    clip = write_video(tmp_path / "c.avi", 8, ("-c:v", "mjpeg", "-q:v", "4"), w=480, h=270)
    fifo = tmp_path / "pipe.avi"
    os.mkfifo(fifo)
    t = _feed_fifo(fifo, clip.read_bytes())
    # was: the offline pass reopened the pipe and waited for ever, deaf to SIGINT and SIGTERM
    assert main(["video", str(fifo), "--offline", "--boxes", str(tmp_path / "b.txt"), "--no-progress"]) == 2
    assert "--offline needs a video file, not a live source" in capsys.readouterr().err
    t.join(timeout=30)
    assert not t.is_alive() and not (tmp_path / "b.txt").exists()
    t = _feed_fifo(fifo, clip.read_bytes())
    assert main(["video", str(fifo), "--boxes", str(tmp_path / "b.txt"), "--no-progress", "--no-refine"]) == 0
    t.join(timeout=30)
    assert "8 frames" in capsys.readouterr().out


def test_named_pipe_nobody_writes_to_is_bounded_and_a_stop_ends_it(tmp_path, monkeypatch):
    import os
    import signal
    import threading

    import fastdet.io.reader as reader_mod
    from fastdet import signals
    from fastdet.errors import DataError

    fifo = tmp_path / "pipe.mp4"
    os.mkfifo(fifo)
    monkeypatch.setattr(reader_mod, "OPEN_TIMEOUT_S", 1.0)
    with pytest.raises(DataError, match="did not open within 1 s"):
        FrameReader(fifo)
    monkeypatch.setattr(reader_mod, "OPEN_TIMEOUT_S", 300.0)
    with signals.handled():
        timer = threading.Timer(0.5, os.kill, (os.getpid(), signal.SIGTERM))
        timer.start()
        with pytest.raises(signals.Stopped):
            FrameReader(fifo)
        timer.join()
    # the helper threads left blocked in OpenCV's open hold OpenCV's FFmpeg lock: a writer
    # that opens and closes the pipe lets them go before any other test opens a video
    import time
    end = time.monotonic() + 60
    while any(t.name == "fastdet-open" for t in threading.enumerate()) and time.monotonic() < end:
        try:
            os.close(os.open(fifo, os.O_WRONLY | os.O_NONBLOCK))
        except OSError:
            pass
        time.sleep(0.05)
    assert not any(t.name == "fastdet-open" for t in threading.enumerate())


@pytest.mark.slow
def test_an_http_source_that_never_answers_ends_in_one_line(tmp_path):
    """``video http://HOST:PORT/c.mp4`` where the server accepts and never answers: the 30 s line
    and exit 2 (before: the helper thread still inside OpenCV's open woke as the interpreter shut
    down: "terminate called without an active exception", exit 134)."""
    import os
    import socket
    import subprocess
    import sys

    # the bound is 30 s; the child waits 3 s (a sitecustomize sets the module's bound before the
    # command runs), the same path and exit in a tenth of the time
    site = tmp_path / "site"
    site.mkdir()
    (site / "sitecustomize.py").write_text("import fastdet.io.reader as r\nr.OPEN_TIMEOUT_S = 3.0\n")
    out = tmp_path / "out"
    out.mkdir()
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(site), os.environ.get("PYTHONPATH", "")]))
    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen(8)
    try:
        url = f"http://127.0.0.1:{srv.getsockname()[1]}/c.mp4"
        p = subprocess.run([sys.executable, "-m", "fastdet", "video", url, "--boxes", str(out / "b.txt")],
                           capture_output=True, text=True, timeout=120, env=env)
    finally:
        srv.close()
    assert p.returncode == 2, (p.returncode, p.stderr)
    assert p.stderr.strip().splitlines() == [f"fastdet video: error: {url}: the source did not open within 3 s "
                                             "(a pipe nobody writes to, a stream that does not answer?)"], p.stderr
    assert list(out.iterdir()) == []
