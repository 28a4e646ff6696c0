"""Every command: no output over an input, no two outputs in one file, a failed run keeps no
output, wrong paths named for what they are -- all before any work (fastdet.io.paths)."""
from __future__ import annotations

import hashlib
import shutil
from pathlib import Path

import cv2
import pytest

from fastdet.cli.main import main
from fastdet.io.atomic import partial_name
from fastdet.model import DEFAULT_MODEL_PATH, ONCOMING_MODEL_PATH
from tests.media import frames, leftovers, write_video


def _digest(p: Path) -> str:
    return hashlib.sha256(p.read_bytes()).hexdigest()


@pytest.fixture(scope="module")
def clip(tmp_path_factory) -> Path:
    """6 colour frames of 480x270 (big enough for the real search)."""
    return write_video(tmp_path_factory.mktemp("clip") / "c.mp4", 6, w=480, h=270)


@pytest.fixture
def box_files(tmp_path: Path) -> tuple[Path, Path]:
    gt, pred = tmp_path / "g.txt", tmp_path / "p.txt"
    gt.write_text("1,1,10,10,40,30,1,1,1\n2,1,12,10,40,30,1,1,1\n")
    pred.write_text("1,1,10,10,40,30,0.9,-1,-1,-1\n")
    return gt, pred


@pytest.mark.parametrize("onto", ["gt", "pred"])
def test_eval_plot_onto_an_input_is_refused(box_files, capsys, onto):
    gt, pred = box_files
    before = {p: _digest(p) for p in box_files}
    target = gt if onto == "gt" else pred
    assert main(["eval", "--gt", str(gt), "--pred", str(pred), "--plot", str(target)]) == 2
    err = capsys.readouterr().err
    assert f"would overwrite the input --{onto}" in err and err.count("\n") == 1
    assert {p: _digest(p) for p in box_files} == before


def test_eval_plot_checked_before_the_clip_runs(box_files, clip, capsys, monkeypatch, tmp_path):
    import fastdet.cli.eval as ev

    def never(*a, **kw):
        raise AssertionError("the clip ran before the outputs were checked")

    monkeypatch.setattr(ev, "iter_video_detections", never)
    gt, _ = box_files
    before = _digest(clip)
    assert main(["eval", "--gt", str(gt), "--video", str(clip), "--plot", str(clip)]) == 2
    assert "would overwrite the input --video" in capsys.readouterr().err and _digest(clip) == before
    assert main(["eval", "--gt", str(gt), "--video", str(clip), "--plot", str(tmp_path / "none" / "p.png")]) == 2
    assert "does not exist" in capsys.readouterr().err


def test_video_outputs_onto_model_files_are_refused(clip, tmp_path, capsys):
    m, w = tmp_path / "m.npz", tmp_path / "w.npz"
    shutil.copy(DEFAULT_MODEL_PATH, m)
    shutil.copy(ONCOMING_MODEL_PATH, w)
    before = {p: _digest(p) for p in (m, w)}
    assert main(["video", str(clip), "--model", str(m), "--boxes", str(m), "--no-progress"]) == 2
    assert "--boxes" in capsys.readouterr().err
    assert main(["video", str(clip), "--oncoming-model", str(w), "--boxes", str(tmp_path / "b.txt"),
                 "--summary", str(w), "--no-progress"]) == 2
    assert "would overwrite the input --oncoming-model" in capsys.readouterr().err
    assert main(["video", str(clip), "--boxes", str(DEFAULT_MODEL_PATH), "--no-progress"]) == 2
    assert "is inside the installed fastdet package" in capsys.readouterr().err  # (and an input)
    assert {p: _digest(p) for p in (m, w)} == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.npz", "w.npz"]


def test_video_whose_summary_cannot_be_written_keeps_no_output(clip, tmp_path, capsys):
    out, boxes, summary = tmp_path / "o.mp4", tmp_path / "b.txt", tmp_path / "s.json"
    partial_name(summary).mkdir()  # the summary's temporary file cannot be made (as on a full disk)
    assert main(["video", str(clip), "-o", str(out), "--boxes", str(boxes), "--summary", str(summary),
                 "--no-progress", "--no-refine"]) == 2
    assert "s.json: cannot write" in capsys.readouterr().err
    partial_name(summary).rmdir()
    assert sorted(tmp_path.iterdir()) == []  # neither o.mp4 nor b.txt: a failed run keeps none of its outputs


def test_video_outputs_all_appear_together(clip, tmp_path, capsys):
    out, boxes, summary = tmp_path / "o.mp4", tmp_path / "b.txt", tmp_path / "s.json"
    assert main(["video", str(clip), "-o", str(out), "--boxes", str(boxes), "--summary", str(summary),
                 "--no-progress", "--no-refine"]) == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["b.txt", "o.mp4", "s.json"] and not leftovers(tmp_path)


def test_image_output_that_is_a_folder(tmp_path, capsys, test_images):
    """``-o`` an existing folder: the annotated picture goes into it under its own name."""
    assert main(["image", str(test_images[0]), "-o", str(tmp_path), "--no-progress"]) == 0
    assert [p.name for p in tmp_path.iterdir()] == [test_images[0].name]


def test_train_data_that_is_a_file(clip, tmp_path, capsys):
    assert main(["train", "--data", str(clip), "--out", str(tmp_path / "m.npz")]) == 2
    assert f"--data {clip}: is a file" in capsys.readouterr().err


@pytest.mark.parametrize("opt", [["--orientations", "100000"], ["--spatial-size", "100000"],
                                 ["--hist-bins", "100000"]])
def test_train_feature_options_beyond_their_range(tmp_path, capsys, opt):
    assert main(["train", "--out", str(tmp_path / "m.npz"), *opt]) == 2
    assert f"{opt[0]} must be at most" in capsys.readouterr().err


def test_image_of_one_pixel_row(tmp_path, capsys):
    img = tmp_path / "thin.png"
    cv2.imwrite(str(img), (255 * __import__("numpy").random.default_rng(0).random((1, 1000, 3))).astype("uint8"))
    assert main(["image", str(img), "-o", str(tmp_path / "o.jpg")]) == 2
    assert "a 1000x1 picture is too small" in capsys.readouterr().err


@pytest.mark.slow
def test_two_runs_onto_the_same_outputs_never_share_a_temporary_file(tmp_path):
    """Two ``video`` runs writing the same files at once: each writes its own temporary files
    (pid + token), so both end well and the last rename wins whole -- no video cut short, no
    box file mixing two runs. The first run is paused (SIGSTOP) once its temporary files are
    there and goes on only when the second one has made its own beside them: the two write
    at the same time on any machine, however fast."""
    import os
    import signal
    import subprocess
    import time

    from tests.media import fastdet_cmd, partials_of

    n_frames = 30  # the SIGSTOP holds the first run: a short clip does
    clip = write_video(tmp_path / "c.mp4", n_frames, w=480, h=270)
    solo = tmp_path / "solo.txt"
    assert main(["video", str(clip), "--boxes", str(solo), "--no-progress"]) == 0
    out, boxes = tmp_path / "same.mp4", tmp_path / "same.txt"
    cmd = fastdet_cmd("video", clip, "-o", out, "--boxes", boxes, "--no-progress")

    def wait_for(n: int, p: subprocess.Popen) -> list[Path]:
        """The temporary files once each output has ``n`` (bounded: 300 s)."""
        deadline = time.monotonic() + 300
        while time.monotonic() < deadline:
            assert p.poll() is None, p.communicate()
            tmps = [partials_of(out), partials_of(boxes)]
            if all(len(t) == n for t in tmps):
                return [f for t in tmps for f in t]
            time.sleep(0.02)
        raise AssertionError(f"no {n} temporary files of each output after 300 s")

    procs = [subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)]
    try:
        mine = wait_for(1, procs[0])
        os.kill(procs[0].pid, signal.SIGSTOP)
        try:
            procs.append(subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True))
            both = wait_for(2, procs[1])
        finally:
            os.kill(procs[0].pid, signal.SIGCONT)
        assert set(mine) < set(both)  # the second run's temporary files are others than the first's
        for p in procs:
            _, err = p.communicate(timeout=300)
            assert p.returncode == 0, err
    finally:
        for p in procs:
            if p.poll() is None:
                p.kill()
                p.communicate()
    assert boxes.read_bytes() == solo.read_bytes()
    cap = cv2.VideoCapture(str(out))
    n = 0
    while cap.read()[0]:
        n += 1
    cap.release()
    assert n == n_frames and not leftovers(tmp_path)


def test_train_into_the_package_needs_its_flag(tmp_path, capsys):
    """``train --out fastdet/models/default.npz`` (the README's old command) is refused in one
    line before the data is loaded, the bundled model untouched; ``--into-package`` allows it."""
    before = _digest(DEFAULT_MODEL_PATH)
    assert main(["train", "--out", str(DEFAULT_MODEL_PATH), "--data", str(tmp_path / "none")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "is inside the installed fastdet package" in err[0] and "--into-package" in err[0], err
    assert _digest(DEFAULT_MODEL_PATH) == before
    # told to: the output passes, and the next check (the missing data folder) speaks
    assert main(["train", "--out", str(DEFAULT_MODEL_PATH), "--into-package", "--data", str(tmp_path / "none")]) == 2
    err = capsys.readouterr().err
    assert "data folder" in err and "inside the installed" not in err, err
    assert _digest(DEFAULT_MODEL_PATH) == before


@pytest.mark.parametrize("command", ["video", "image", "eval", "mine-negatives", "batch"])
def test_other_commands_never_write_into_the_package(clip, box_files, tmp_path, capsys, command):
    from fastdet.io.paths import PACKAGE_DIR

    gt, pred = box_files
    img = tmp_path / "in.jpg"
    cv2.imwrite(str(img), next(frames(1, 480, 270)))
    inside = PACKAGE_DIR / "models"
    argv = {"video": ["video", str(clip), "--boxes", str(inside / "b.txt")],
            "image": ["image", str(img), "-o", str(inside / "o.jpg")],
            "eval": ["eval", "--gt", str(gt), "--pred", str(pred), "--plot", str(inside / "pr.png")],
            "mine-negatives": ["mine-negatives", str(clip), "--x-range", "0", "100", "--out", str(inside / "hard")],
            "batch": ["batch", str(clip), "--out", str(inside / "runs")]}[command]
    if command == "batch":
        pytest.importorskip("dask.distributed")
    before = sorted(p.name for p in PACKAGE_DIR.rglob("*") if "__pycache__" not in p.parts)
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "inside the installed fastdet package" in err[0], err
    assert sorted(p.name for p in PACKAGE_DIR.rglob("*") if "__pycache__" not in p.parts) == before
