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
    assert not out.exists()
