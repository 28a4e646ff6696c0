"""fastdet.io.atomic: outputs appear under their final name only when complete."""
from __future__ import annotations

import os
from pathlib import Path

import pytest

from fastdet.errors import DataError
from fastdet.io.atomic import OutputSet, atomic_path, commit, new_folders, partial_name, process_token, write_bytes


def test_partial_name_keeps_the_folder_and_extension():
    tok = process_token()
    assert tok.startswith(f"{os.getpid()}-") and len(tok.split("-")[1]) == 8
    assert partial_name("/a/b/out.mp4") == Path(f"/a/b/.out.partial.{tok}.mp4")
    assert partial_name("boxes.txt") == Path(f".boxes.partial.{tok}.txt")
    assert partial_name(Path("x/model")) == Path(f"x/.model.partial.{tok}")


def test_partial_names_differ_between_processes():
    import subprocess
    import sys
    code = "from fastdet.io.atomic import partial_name; print(partial_name('/o/x.mp4'))"
    names = {subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
             for _ in range(2)}
    names.add(str(partial_name("/o/x.mp4")) + "\n")
    assert len(names) == 3


def test_partial_name_is_new_in_a_forked_child():
    r, w = os.pipe()
    pid = os.fork()
    if pid == 0:  # the child
        os.write(w, str(partial_name("/o/x.mp4")).encode())
        os._exit(0)
    os.waitpid(pid, 0)
    child = os.read(r, 4096).decode()
    assert child != str(partial_name("/o/x.mp4")) and f".{pid}-" in child


def test_output_set_renames_all_or_none(tmp_path):
    outs = OutputSet()
    for name in ("a.txt", "b.txt"):
        tmp = partial_name(tmp_path / name)
        tmp.write_text(name)
        outs.add(tmp, tmp_path / name)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(p.name for p in (partial_name(tmp_path / "a.txt"),
                                                                                 partial_name(tmp_path / "b.txt")))
    assert outs.commit() == [tmp_path / "a.txt", tmp_path / "b.txt"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.txt", "b.txt"]
    # the second rename fails (a non-empty folder in the way): the first output goes too
    blocker = tmp_path / "d.txt"
    blocker.mkdir()
    (blocker / "keep").write_text("k")
    outs = OutputSet()
    for name in ("c.txt", "d.txt", "e.txt"):
        tmp = partial_name(tmp_path / name)
        tmp.write_text(name)
        outs.add(tmp, tmp_path / name)
    with pytest.raises(DataError, match="d.txt: cannot write"):
        outs.commit()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.txt", "b.txt", "d.txt"]
    outs = OutputSet()
    tmp = partial_name(tmp_path / "f.txt")
    tmp.write_text("f")
    outs.add(tmp, tmp_path / "f.txt")
    outs.discard()
    assert not tmp.exists() and not (tmp_path / "f.txt").exists()


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


def test_commit_follows_the_umask_for_a_new_file(tmp_path):
    """Issue 34 (7): outputs were chmod 0644 whatever the umask (world-readable under 077)."""
    old = os.umask(0o077)
    try:
        write_bytes(tmp_path / "new.txt", b"x")
    finally:
        os.umask(old)
    assert (tmp_path / "new.txt").stat().st_mode & 0o777 == 0o600


def test_commit_keeps_the_mode_of_the_file_it_replaces(tmp_path):
    out = tmp_path / "old.txt"
    out.write_bytes(b"old")
    out.chmod(0o640)
    write_bytes(out, b"new")
    assert out.read_bytes() == b"new" and out.stat().st_mode & 0o777 == 0o640
    out.chmod(0o604)
    tmp = partial_name(out)
    tmp.write_bytes(b"newer")
    tmp.chmod(0o600)  # a temporary file made with a private mode (mkstemp)
    commit(tmp, out)
    assert out.stat().st_mode & 0o777 == 0o604


def test_a_process_leaves_no_temporary_file_on_any_exit_path(tmp_path):
    """A temporary file the process did not rename or remove (an exit path whose clean-up was cut
    short: a second Ctrl-C, an exception out of a library) is removed when the process ends;
    what was renamed stays (issue 34, item 13: ``.o.partial.PID-TOKEN.mp4`` was left)."""
    import subprocess
    import sys
    code = ("import sys; from pathlib import Path\n"
            "from fastdet.io.atomic import commit, partial_name\n"
            "d = Path(sys.argv[1])\n"
            "partial_name(d / 'a.txt').write_text('half')\n"
            "done = partial_name(d / 'b.txt'); done.write_text('whole'); commit(done, d / 'b.txt')\n"
            "partial_name(d / 'never.txt')\n"  # a name handed out, no file made: nothing to do
            "raise RuntimeError('cut short')\n")
    p = subprocess.run([sys.executable, "-c", code, str(tmp_path)], capture_output=True, text=True, timeout=120)
    assert p.returncode == 1 and "cut short" in p.stderr
    assert sorted(x.name for x in tmp_path.iterdir()) == ["b.txt"]
    assert (tmp_path / "b.txt").read_text() == "whole"


def test_a_forked_child_leaves_its_parents_temporary_files(tmp_path):
    """The names a parent handed out are the parent's: a forked child (a worker) ending does not
    remove them."""
    from fastdet.io import atomic

    tmp = partial_name(tmp_path / "p.txt")
    tmp.write_text("parent's")
    pid = os.fork()
    if pid == 0:  # the child: its exit handlers run
        try:
            atomic.remove_partials()
        finally:
            os._exit(0)
    os.waitpid(pid, 0)
    assert tmp.read_text() == "parent's"
    atomic.remove_partials()
    assert not tmp.exists()


def test_new_folders_are_removed_when_the_block_fails_and_kept_when_it_succeeds(tmp_path):
    """A run that fails to start leaves no folder it made (issue 34: an empty ``batch --out``
    left by a failed connection); folders that existed, or hold anything, stay."""
    out = tmp_path / "a" / "b" / "c"
    with pytest.raises(RuntimeError):
        with new_folders(out) as made:
            assert made == [tmp_path / "a", tmp_path / "a" / "b", out] and out.is_dir()
            raise RuntimeError("the scheduler did not answer")
    assert list(tmp_path.iterdir()) == []
    (tmp_path / "a").mkdir()  # existed before: stays
    with pytest.raises(KeyboardInterrupt):
        with new_folders(out) as made:
            assert made == [tmp_path / "a" / "b", out]
            raise KeyboardInterrupt
    assert [p.name for p in tmp_path.rglob("*")] == ["a"]
    with pytest.raises(RuntimeError):
        with new_folders(out):
            (out / "manifest.jsonl").write_text("{}\n")  # something written: the folders stay
            raise RuntimeError
    assert (out / "manifest.jsonl").is_file()
    with new_folders(tmp_path / "d" / "e") as made:
        pass
    assert (tmp_path / "d" / "e").is_dir()
    with new_folders(tmp_path / "d" / "e") as made:
        assert made == []
    (tmp_path / "link").symlink_to(tmp_path / "nowhere")
    with pytest.raises(FileExistsError):
        with new_folders(tmp_path / "link"):
            pass
