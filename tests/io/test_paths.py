"""fastdet.io.paths: a command's inputs and outputs checked together before any work."""
from __future__ import annotations

import os
from pathlib import Path

import pytest

from fastdet.errors import DataError
from fastdet.io.paths import bundled_models, check_output, check_paths


def test_distinct_files_pass_and_nothing_is_made(tmp_path):
    inp = tmp_path / "in.mp4"
    inp.write_bytes(b"v")
    check_paths([("INPUT", inp), ("--model", None)], [("-o", tmp_path / "o.mp4", "video"),
                                                      ("--boxes", tmp_path / "b.txt", "box"), ("--json", None, "JSON")])
    assert sorted(tmp_path.iterdir()) == [inp]


def test_output_that_is_an_input(tmp_path, monkeypatch):
    gt, pred = tmp_path / "g.txt", tmp_path / "p.txt"
    gt.write_text("1,1,1,1,5,5")
    pred.write_text("")
    for out, label in ((gt, "--gt"), (pred, "--pred")):
        with pytest.raises(DataError, match=f"--plot {out}: would overwrite the input {label} {out}"):
            check_paths([("--gt", gt), ("--pred", pred)], [("--plot", out, "PNG")])
    # the same file under another name: a relative path, a symlink, a hard link, '..'
    monkeypatch.chdir(tmp_path)
    link = tmp_path / "link.txt"
    link.symlink_to(gt)
    hard = tmp_path / "hard.txt"
    os.link(gt, hard)
    (tmp_path / "sub").mkdir()
    for alias in ("g.txt", str(link), str(hard), str(tmp_path / "sub" / ".." / "g.txt")):
        with pytest.raises(DataError, match="would overwrite the input --gt"):
            check_paths([("--gt", gt)], [("--plot", alias, "PNG")])


def test_two_outputs_that_are_one_file(tmp_path):
    a = tmp_path / "x.mp4"
    with pytest.raises(DataError, match="-o .*x.mp4 and --summary .*x.mp4 are one file"):
        check_paths([], [("-o", a, "video"), ("--summary", str(tmp_path / "." / "x.mp4"), "summary")])
    a.write_bytes(b"old")
    link = tmp_path / "l.mp4"
    link.symlink_to(a)
    with pytest.raises(DataError, match="are one file"):
        check_paths([], [("-o", a, "video"), ("--boxes", link, "box")])


def test_bundled_models_are_inputs(tmp_path):
    models = bundled_models()
    assert any(str(p).endswith("default.npz") for _, p in models)
    _, default = next(m for m in models if str(m[1]).endswith("default.npz"))
    with pytest.raises(DataError, match="would overwrite the input the bundled model"):
        check_paths(models, [("--boxes", default, "box")], into_package=True)
    with pytest.raises(DataError, match="inside the installed fastdet package"):  # without the flag, first
        check_paths(models, [("--boxes", default, "box")])


def test_live_sources_and_missing_inputs_take_no_part(tmp_path):
    check_paths([("INPUT", "rtsp://cam/1"), ("INPUT", "0"), ("INPUT", str(tmp_path / "img%04d.jpg")),
                 ("--gt", tmp_path / "missing.txt")], [("-o", tmp_path / "o.mp4", "video")])


def test_output_locations(tmp_path):
    with pytest.raises(DataError, match="does not exist"):
        check_output(tmp_path / "nowhere" / "o.mp4", "video")
    with pytest.raises(DataError, match="-o .*: is a folder, expected an image file name"):
        check_output(tmp_path, "image", "-o")
    if os.geteuid() != 0:  # root ignores permissions
        ro = tmp_path / "ro"
        ro.mkdir()
        ro.chmod(0o500)
        try:
            with pytest.raises(DataError, match="not writable"):
                check_output(ro / "o.mp4", "video")
        finally:
            ro.chmod(0o700)


def test_output_that_is_a_device_or_a_pipe(tmp_path):
    fifo = tmp_path / "p.txt"
    os.mkfifo(fifo)
    with pytest.raises(DataError, match="is not a regular file"):
        check_output(fifo, "box")
    with pytest.raises(DataError, match="is not a regular file"):
        check_output("/dev/null", "box")  # a rename onto it would replace the device with a file
    assert os.path.exists("/dev/null") and not os.path.isfile("/dev/null")


def test_output_name_too_long_for_its_temporary_name(tmp_path):
    check_output(tmp_path / ("a" * 200 + ".txt"), "box")
    with pytest.raises(DataError, match="file name is too long"):
        check_output(tmp_path / ("a" * 240 + ".txt"), "box")


def test_outputs_inside_the_package_are_refused(tmp_path):
    """Issue 33, item 5: nothing is written into the installed package unless asked for
    (``--into-package``); a symlink into it is followed."""
    import fastdet
    from fastdet.io.paths import PACKAGE_DIR, check_output_folder, check_outside_package

    assert PACKAGE_DIR == Path(fastdet.__file__).resolve().parent
    inside = PACKAGE_DIR / "models" / "default.npz"
    link = tmp_path / "pkg"
    link.symlink_to(PACKAGE_DIR / "models")
    for out in (inside, PACKAGE_DIR / "new.txt", link / "x.npz", tmp_path / os.path.relpath(inside, tmp_path)):
        with pytest.raises(DataError, match="inside the installed fastdet package") as e:
            check_output(out, "model", "--out")
        assert str(e.value).startswith(f"--out {out}: ")
        with pytest.raises(DataError, match="inside the installed fastdet package"):
            check_paths([], [("--boxes", out, "box")])
        check_outside_package(out, "--out", into_package=True)  # told to
    for folder in (PACKAGE_DIR, PACKAGE_DIR / "models" / "hard", link / "hard"):
        with pytest.raises(DataError, match="inside the installed fastdet package"):
            check_output_folder(folder, "--out")
    check_output(tmp_path / "m.npz", "model", "--out")  # elsewhere: as before
    check_output_folder(tmp_path / "new" / "hard", "--out")
    sibling = PACKAGE_DIR.parent / (PACKAGE_DIR.name + "-other") / "m.npz"  # a name that only starts alike
    check_outside_package(sibling, "--out")


def _images(folder, names):
    import cv2
    import numpy as np

    for n in names:
        cv2.imwrite(str(folder / n), np.full((8, 8, 3), 90, np.uint8))


def test_an_output_onto_a_frame_of_an_input_image_sequence(tmp_path, monkeypatch):
    """Issue 34 (1): ``video 'seq2/img%04d.jpg' --boxes seq2/img0003.jpg`` wrote box text over
    frame 3 of the sequence it read."""
    seq = tmp_path / "seq2"
    seq.mkdir()
    _images(seq, [f"img{i:04d}.jpg" for i in (1, 2, 3)])
    pattern = str(seq / "img%04d.jpg")
    monkeypatch.chdir(tmp_path)
    for out in (seq / "img0003.jpg", "seq2/img0003.jpg", "./seq2/../seq2/img0002.jpg", seq / "img0099.jpg",
                seq / "img12345.jpg"):
        with pytest.raises(DataError, match="is a frame of the input image sequence INPUT"):
            check_paths([("INPUT", pattern)], [("--boxes", out, "box")])
    link = tmp_path / "link.jpg"
    link.symlink_to(seq / "img0001.jpg")
    with pytest.raises(DataError, match="is a frame of the input image sequence"):
        check_paths([("INPUT", pattern)], [("--boxes", link, "box")])
    for out in (seq / "img003.jpg", seq / "img0003.txt", tmp_path / "img0003.jpg"):  # not frames of it
        check_paths([("INPUT", pattern)], [("--boxes", out, "box")])
    assert sorted(p.name for p in seq.iterdir()) == ["img0001.jpg", "img0002.jpg", "img0003.jpg"]


def test_a_file_literally_named_like_a_sequence_is_that_file(tmp_path, monkeypatch):
    """``a%d.mp4`` beside ``a1.mp4``: OpenCV (FFmpeg) opens the literal file, so the check must
    treat it as the input file (it took it for a sequence and let ``-o 'a%d.mp4'`` replace it)."""
    from fastdet.io.reader import source_kind

    monkeypatch.chdir(tmp_path)
    Path("a%d.mp4").write_bytes(b"the input")
    Path("a1.mp4").write_bytes(b"another")
    assert source_kind("a%d.mp4") == "file"
    with pytest.raises(DataError, match="would overwrite the input INPUT a%d.mp4"):
        check_paths([("INPUT", "a%d.mp4")], [("-o", "a%d.mp4", "video")])
    check_paths([("INPUT", "a%d.mp4")], [("-o", "a1.mp4", "video")])  # not read: OpenCV reads the literal file
    _images(tmp_path, ["img1.png"])
    assert source_kind("img%d.png") == "sequence"  # an image extension: FFmpeg's pattern


def test_video_refuses_boxes_over_a_frame_of_its_sequence(tmp_path, capsys):
    from fastdet.cli.main import main

    seq = tmp_path / "seq2"
    seq.mkdir()
    _images(seq, [f"img{i:04d}.jpg" for i in (1, 2, 3)])
    before = (seq / "img0003.jpg").read_bytes()
    rc = main(["video", str(seq / "img%04d.jpg"), "--boxes", str(seq / "img0003.jpg")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "is a frame of the input image sequence" in err[0], err
    assert (seq / "img0003.jpg").read_bytes() == before
