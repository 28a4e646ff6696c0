"""``mine-negatives``: options checked for their domain; a failed run keeps none of its crops."""
from __future__ import annotations

import pytest

import fastdet.cli.mine as mine_cmd
from fastdet.cli.main import main
from fastdet.errors import WriteError


@pytest.mark.parametrize("opts, msg", [
    (["--x-range", "0", "600", "--margin", "-100", "--gt", "GT"], "--margin must be >= 0"),
    (["--x-range", "700", "300"], "--x-range A B needs 0 <= A < B"),
    (["--y-range", "-5", "300"], "--y-range A B needs 0 <= A < B"),
    (["--x-range", "0", "600", "--threshold", "nan"], "--threshold must be a finite number"),
    (["--x-range", "0", "600", "--threshold", "inf"], "--threshold must be a finite number"),
    (["--x-range", "0", "600", "--prefix", "../../x"], "--prefix must be a plain file name part"),
    (["--x-range", "0", "600", "--prefix", "a/b"], "--prefix must be a plain file name part"),
    (["--x-range", "0", "600", "--prefix", ".."], "--prefix must be a plain file name part"),
])
def test_options_out_of_their_domain(tmp_path, capsys, test_images, opts, msg):
    gt = tmp_path / "gt.txt"
    gt.write_text("1,1,10,10,40,30\n")
    opts = [str(gt) if o == "GT" else o for o in opts]
    out = tmp_path / "crops"
    assert main(["mine-negatives", str(test_images[0]), "--out", str(out), *opts, "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert msg in err and len(err.strip().splitlines()) == 1
    assert not out.exists() and not (tmp_path.parent / "x").exists()


def test_a_failed_run_removes_the_crops_it_wrote(tmp_path, capsys, test_images, monkeypatch):
    out = tmp_path / "crops"
    out.mkdir()
    earlier = out / "keep.png"
    earlier.write_bytes(b"an earlier run's crop")
    real = mine_cmd.write_image
    calls = []

    def fills_up(path, crop):
        calls.append(path)
        if len(calls) > 3:
            raise WriteError(f"{path}: writing the image failed (disk full)")
        return real(path, crop)

    monkeypatch.setattr(mine_cmd, "write_image", fills_up)
    assert main(["mine-negatives", str(test_images[0]), "--out", str(out), "--x-range", "0", "1280",
                 "--threshold", "-100", "--no-progress"]) == 2
    assert "the crops this run wrote before it were removed" in capsys.readouterr().err
    assert len(calls) == 4 and sorted(p.name for p in out.iterdir()) == ["keep.png"]


def test_a_url_is_a_source_and_a_symlink_loop_says_so(tmp_path, capsys):
    """issue 34, item 19: ``http://`` given to ``mine-negatives`` said "http:/...: file not found"
    (the argument was a Path, which folds ``//``); a symlink loop said "file not found"."""
    out = tmp_path / "neg"
    assert main(["mine-negatives", "http://127.0.0.1:1/clip.mp4", "--out", str(out), "--x-range", "0", "100",
                 "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "http:/127" not in err and "file not found" not in err and "http://127.0.0.1:1/clip.mp4" in err, err
    (tmp_path / "a.mp4").symlink_to(tmp_path / "b.mp4")
    (tmp_path / "b.mp4").symlink_to(tmp_path / "a.mp4")
    assert main(["mine-negatives", str(tmp_path / "a.mp4"), "--out", str(out), "--x-range", "0", "100",
                 "--no-progress"]) == 2
    assert "symlink loop" in capsys.readouterr().err


def test_windows_sharing_x1_y1_and_width_get_their_own_files(tmp_path, capsys, test_images, monkeypatch):
    """Issue 34 (4): "mined 1090 windows" but 1074 files (windows with the same x1, y1 and
    width shared a name); the same box twice is one crop, counted once."""
    import numpy as np

    crop = np.zeros((64, 64, 3), np.uint8)
    boxes = [(0, 0, 64, 64), (0, 0, 64, 80), (0, 0, 64, 64), (8, 0, 72, 64)]
    monkeypatch.setattr(mine_cmd, "hard_negatives",
                        lambda *a, **k: [(np.array(b), crop + i) for i, b in enumerate(boxes)])
    out = tmp_path / "crops"
    assert main(["mine-negatives", str(test_images[0]), "--out", str(out), "--x-range", "0", "1280",
                 "--no-progress"]) == 0
    said = capsys.readouterr().out
    files = sorted(p.name for p in out.iterdir())
    assert "mined 3 false-positive windows" in said and len(files) == 3, (said, files)


@pytest.mark.parametrize("long_video", [True, False])
def test_names_too_long_for_the_file_system_are_one_line(tmp_path, capsys, test_images, long_video):
    """Issue 34 (16): a 240-character video name or --prefix was an ``OSError: File name too
    long`` traceback, with an empty --out folder left."""
    import shutil

    video = test_images[0]
    opts = []
    if long_video:
        video = tmp_path / f"{'v' * 240}.jpg"
        shutil.copy(test_images[0], video)
    else:
        opts = ["--prefix", "p" * 240]
    out = tmp_path / "crops"
    rc = main(["mine-negatives", str(video), "--out", str(out), "--x-range", "0", "1280", *opts, "--no-progress"])
    err = capsys.readouterr().err
    assert rc == 2 and len(err.strip().splitlines()) == 1 and "give a shorter --prefix" in err, err
    assert not out.exists()
