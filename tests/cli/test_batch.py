"""fastdet/cli/batch.py: the command's arguments refused in one line before any work (an output
named as an input, a scheduler address that is not one, bad options). Whole batches:
tests/batch/test_job.py."""
from __future__ import annotations

from pathlib import Path

import pytest

pytest.importorskip("distributed")

from fastdet.cli.main import main


@pytest.fixture
def clips(tmp_path: Path) -> Path:
    """A folder with a file named as a video (the arguments are refused before it is read)."""
    d = tmp_path / "clips"
    d.mkdir()
    (d / "road.mp4").write_bytes(b"v")
    return d


def test_cli_refuses_an_output_as_input_before_any_work(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    d = tmp_path / "d"
    d.mkdir()
    (d / "a.mp4").write_bytes(b"v")
    (d / "a.annotated.mp4").write_bytes(b"keep")
    assert main(["batch", str(d / "a.mp4"), str(d / "a.annotated.mp4"), "--out", str(d), "--video"]) == 2
    assert "a.annotated.mp4: is a file this batch writes" in capsys.readouterr().err
    assert (d / "a.annotated.mp4").read_bytes() == b"keep" and sorted(p.name for p in d.iterdir()) == [
        "a.annotated.mp4", "a.mp4"]


@pytest.mark.parametrize("address", ["not a url", "tcp://", "tcp://host-without-port", "http//x:1"])
def test_scheduler_address_that_is_not_one(tmp_path: Path, capsys: pytest.CaptureFixture, address: str) -> None:
    (tmp_path / "a.mp4").write_bytes(b"v")
    assert main(["batch", str(tmp_path / "a.mp4"), "--out", str(tmp_path / "o"), "--scheduler", address]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "is not a scheduler address" in err
    assert not (tmp_path / "o").exists()


def test_batch_bad_arguments_one_line(tmp_path: Path, clips: Path, capsys: pytest.CaptureFixture) -> None:
    for args, msg in (([tmp_path / "nope"], "file not found"),
                      ([clips, "--table", tmp_path / "t.xlsx"], ".parquet or .csv"),
                      ([clips, "--model", tmp_path / "m.npz"], "model file not found"),
                      ([clips, "--workers", "2", "--scheduler", "tcp://127.0.0.1:1"], "--workers")):
        assert main(["batch", *map(str, args), "--out", str(tmp_path / "o")]) == 2, args
        err = capsys.readouterr().err
        assert len(err.strip().splitlines()) == 1 and msg in err, (args, err)
    assert not (tmp_path / "o").exists()
