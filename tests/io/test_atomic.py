"""fastdet.io.atomic: outputs appear under their final name only when complete."""
from __future__ import annotations

import os
from pathlib import Path

import pytest

from fastdet.errors import DataError
from fastdet.io.atomic import atomic_path, check_output_path, commit, partial_name, write_bytes


def test_partial_name_keeps_the_folder_and_extension():
    assert partial_name("/a/b/out.mp4") == Path("/a/b/.out.partial.mp4")
    assert partial_name("boxes.txt") == Path(".boxes.partial.txt")
    assert partial_name(Path("x/model")) == Path("x/.model.partial")


def test_atomic_path_renames_on_success(tmp_path):
    out = tmp_path / "o.txt"
    with atomic_path(out) as tmp:
        assert tmp == partial_name(out)
        tmp.write_text("hello")
        assert not out.exists()  # nothing under the final name while writing
    assert out.read_text() == "hello"
    assert sorted(tmp_path.iterdir()) == [out]
    assert out.stat().st_mode & 0o777 == 0o644


def test_atomic_path_replaces_an_existing_file_only_when_done(tmp_path):
    out = tmp_path / "o.txt"
    out.write_text("old")
    with pytest.raises(RuntimeError):
        with atomic_path(out) as tmp:
            tmp.write_text("new, half")
            raise RuntimeError("stop")
    assert out.read_text() == "old" and sorted(tmp_path.iterdir()) == [out]
    with atomic_path(out) as tmp:
        tmp.write_text("new")
    assert out.read_text() == "new"


@pytest.mark.parametrize("exc", [RuntimeError("bug"), KeyboardInterrupt(), DataError("bad input")])
def test_atomic_path_leaves_no_file_on_an_exception(tmp_path, exc):
    out = tmp_path / "o.bin"
    with pytest.raises(type(exc)):
        with atomic_path(out) as tmp:
            tmp.write_bytes(b"partial")
            raise exc
    assert list(tmp_path.iterdir()) == []


def test_oserror_while_writing_becomes_a_data_error_naming_the_final_path(tmp_path):
    out = tmp_path / "o.bin"
    with pytest.raises(DataError) as info:
        with atomic_path(out) as tmp:
            tmp.write_bytes(b"partial")
            raise OSError(28, "No space left on device")
    msg = str(info.value)
    assert str(out) in msg and "partial" not in msg and "No space left on device" in msg
    assert "\n" not in msg
    assert list(tmp_path.iterdir()) == []


def test_nothing_written_is_an_error(tmp_path):
    out = tmp_path / "o.bin"
    with pytest.raises(DataError, match="nothing was written"):
        with atomic_path(out):
            pass
    assert list(tmp_path.iterdir()) == []


def test_write_bytes(tmp_path):
    out = tmp_path / "m.npz"
    assert write_bytes(out, b"\x00\x01") == out
    assert out.read_bytes() == b"\x00\x01" and sorted(tmp_path.iterdir()) == [out]
    with pytest.raises(DataError, match="does-not-exist"):
        write_bytes(tmp_path / "does-not-exist" / "m.npz", b"x")  # the folder is missing: OSError on open


def test_commit_failure_removes_the_temporary_file(tmp_path):
    tmp = tmp_path / ".o.partial.txt"
    tmp.write_text("x")
    target = tmp_path / "folder"
    target.mkdir()
    (target / "keep").write_text("y")  # a non-empty folder cannot be replaced by a file
    with pytest.raises(DataError, match=str(target)):
        commit(tmp, target)
    assert not tmp.exists() and (target / "keep").exists()
    ok = tmp_path / ".p.partial.txt"
    ok.write_text("z")
    assert commit(ok, tmp_path / "p.txt", mode=None) == tmp_path / "p.txt"


def test_check_output_path(tmp_path):
    inp = tmp_path / "in.mp4"
    inp.write_bytes(b"v")
    check_output_path(tmp_path / "out.mp4", "video", inp)  # fine: nothing raised, nothing made
    assert sorted(tmp_path.iterdir()) == [inp]
    with pytest.raises(DataError, match="does not exist"):
        check_output_path(tmp_path / "nowhere" / "o.mp4", "video")
    with pytest.raises(DataError, match="is a folder"):
        check_output_path(tmp_path, "video")
    with pytest.raises(DataError, match="overwrite the input"):
        check_output_path(inp, "video", inp)
    link = tmp_path / "link.mp4"
    link.symlink_to(inp)
    with pytest.raises(DataError, match="overwrite the input"):
        check_output_path(link, "video", inp)
    if os.geteuid() != 0:  # root ignores permissions
        ro = tmp_path / "ro"
        ro.mkdir()
        ro.chmod(0o500)
        try:
            with pytest.raises(DataError, match="not writable"):
                check_output_path(ro / "o.mp4", "video")
        finally:
            ro.chmod(0o700)
