"""One bounded open for every input file (issue 34, items 8, 12, 19): a named pipe, a device,
a symlink loop, a huge or binary file are refused in one line before anything waits or is
read, by every reader that takes a file (box files, keyframes, pictures, training crops,
label files, models, the batch manifest)."""
from __future__ import annotations

import os
import threading
import time

import pytest

from fastdet.errors import DataError, ModelError
from fastdet.io.files import MAX_TEXT_BYTES, check_input, read_input_bytes, read_input_text


def _within(seconds, fn):
    """``fn()``'s exception (or result) when it ends within ``seconds``; fails otherwise (a
    reader that blocks on a FIFO: the daemon thread is left behind)."""
    out: dict = {}

    def run():
        try:
            out["value"] = fn()
        except BaseException as exc:  # noqa: BLE001 - handed to the test
            out["exc"] = exc
    t = threading.Thread(target=run, daemon=True)
    t.start()
    t.join(seconds)
    assert not t.is_alive(), f"still waiting after {seconds} s"
    return out.get("exc", out.get("value"))


@pytest.fixture
def fifo(tmp_path):
    p = tmp_path / "pipe.txt"
    os.mkfifo(p)
    return p


@pytest.fixture
def loop(tmp_path):
    a, b = tmp_path / "a.txt", tmp_path / "b.txt"
    a.symlink_to(b)
    b.symlink_to(a)
    return a


def test_check_input_names_what_is_wrong(tmp_path, fifo, loop):
    (tmp_path / "f.txt").write_text("1")
    assert check_input(tmp_path / "f.txt").st_size == 1
    for path, msg in ((tmp_path / "none.txt", "file not found"), (loop, "symlink loop"),
                      (fifo, r"named pipe \(FIFO\), not a regular file"), ("/dev/zero", "is a device"),
                      (tmp_path, "is a folder")):
        with pytest.raises(DataError, match=msg):
            check_input(path, "box file")


def test_text_reads_are_bounded_and_refuse_binary_early(tmp_path):
    big = tmp_path / "big.txt"
    with open(big, "wb") as fh:  # sparse: 3 GB on paper, nothing on disk
        fh.truncate(3 * 2**30)
    t0 = time.perf_counter()
    with pytest.raises(DataError, match=f"larger than a box file may be .{MAX_TEXT_BYTES // 2**20} MB"):
        read_input_text(big, "box file")
    assert time.perf_counter() - t0 < 1  # refused from its size, nothing read
    binary = tmp_path / "bin.txt"
    binary.write_bytes(b"1,2,3\n" + b"\0" * (MAX_TEXT_BYTES // 2))
    with pytest.raises(DataError, match="not a text file .binary data: a NUL byte at byte 6"):
        read_input_text(binary)
    with pytest.raises(DataError, match="larger than"):
        read_input_bytes(binary, limit=100)
    (tmp_path / "crlf.txt").write_bytes(b"\xef\xbb\xbf1\r\n2\r3\n")
    assert read_input_text(tmp_path / "crlf.txt") == "1\n2\n3\n"


def test_every_file_reader_refuses_a_fifo_at_once(tmp_path, fifo, loop):
    from fastdet.batch.manifest import Manifest
    from fastdet.io.images import read_image
    from fastdet.io.keyframes import read_keyframes
    from fastdet.io.motfiles import read_gt, read_predictions
    from fastdet.labels.imagesize import image_size
    from fastdet.labels.rules import read_text
    from fastdet.model import load_model
    from fastdet.train.dataset import load_folder

    (tmp_path / "crops").mkdir()
    os.mkfifo(tmp_path / "crops" / "c1.png")
    os.mkfifo(tmp_path / "manifest.jsonl")
    for fn in (lambda: read_gt(fifo), lambda: read_predictions(fifo), lambda: read_keyframes(fifo),
               lambda: read_image(fifo), lambda: image_size(fifo), lambda: read_text(fifo),
               lambda: load_folder(tmp_path / "crops", 1), lambda: Manifest(tmp_path / "manifest.jsonl")):
        exc = _within(5, fn)
        assert isinstance(exc, DataError) and "named pipe (FIFO)" in str(exc), exc
    exc = _within(5, lambda: load_model(fifo))
    assert isinstance(exc, ModelError) and "named pipe (FIFO)" in str(exc), exc
    for fn in (lambda: read_gt(loop), lambda: read_image(loop), lambda: load_model(loop), lambda: image_size(loop)):
        exc = _within(5, fn)
        assert isinstance(exc, (DataError, ModelError)) and "symlink loop" in str(exc), exc
    exc = _within(5, lambda: read_gt("/dev/zero"))
    assert isinstance(exc, DataError) and "is a device" in str(exc), exc


def test_every_input_found_missing_says_symlink_loop(tmp_path, loop):
    """A symlink loop given where a video, a folder, a teacher, a COCO file or a batch input is
    expected said "file not found" (``exists()`` is False for both; issue 34, item 19): every
    check that finds an input missing now says why (:func:`fastdet.io.files.not_found`)."""
    from fastdet.batch.inputs import expand_inputs
    from fastdet.io.files import not_found
    from fastdet.io.reader import FrameReader, check_source
    from fastdet.labels.coco import read_coco
    from fastdet.labels.imagesize import video_size
    from fastdet.teacher.yolox import TeacherDetector
    from fastdet.train.dataset import load_folder

    assert "file not found" in str(not_found(tmp_path / "none", "none: file not found"))
    assert "symlink loop" in str(not_found(loop, "file not found"))
    folder_loop = tmp_path / "d"
    folder_loop.symlink_to(folder_loop)
    for fn in (lambda: check_source(loop), lambda: FrameReader(loop), lambda: video_size(loop),
               lambda: read_coco(loop), lambda: load_folder(folder_loop, 1), lambda: TeacherDetector(loop),
               lambda: expand_inputs([str(loop)])):
        exc = _within(5, fn)
        assert isinstance(exc, (DataError, ModelError)) and "symlink loop" in str(exc), exc


def test_parse_json_fails_in_one_line_for_every_input():
    """Every JSON input (COCO files, JSON-lines boxes, the manifest, model metadata) parses through
    one function whose failures are a JsonError with a few words: 200,000 ``[`` was a
    RecursionError traceback, a 5,000-digit number a ValueError traceback (issue 34)."""
    from fastdet.io.files import JsonError, parse_json

    assert parse_json('{"a": [1, 2.5]}') == {"a": [1, 2.5]}
    for text, words in (("[" * 200_000, "nested too deeply"), ("9" * 5000, "a number too long"),
                        ('{"a": 1,}', "line 1: Expecting property name"), (b"\xff", "not UTF-8")):
        with pytest.raises(JsonError, match=words):
            parse_json(text)
