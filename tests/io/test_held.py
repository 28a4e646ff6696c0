"""fastdet.io.held: a file's frames decoded once and held (in memory, or spilled to a raw file)
read again by FrameReader exactly as the file's own reader gives them -- numbers, damaged
frames skipped, the end, a decoding error -- and the spill file removed on every way out."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from fastdet.errors import DataError, WriteError
from fastdet.io.held import HeldFrames
from fastdet.io.hold import hold_frames
from fastdet.io.reader import FrameReader
from tests.media import damage, leftovers, write_video


@pytest.fixture(scope="module")
def damaged(tmp_path_factory) -> Path:
    """30 frames of 160x120, frames 13-14 (1-based) damaged: the reader skips them."""
    d = tmp_path_factory.mktemp("held")
    return damage(write_video(d / "clip.mp4", 30, w=160, h=120), d / "damaged.mp4", [12, 13])


def _read(source, start=0, frames=None) -> tuple[list[tuple[int, np.ndarray]], list[tuple[int, int]]]:
    with FrameReader(source, start, frames, notify=lambda _n: None) as r:
        got = [(fno, f) for fno, f, _ in r]
        return got, r.skipped


def _same(a, b) -> None:
    assert [n for n, _ in a] == [n for n, _ in b]
    for (n, x), (_, y) in zip(a, b):
        assert x.dtype == y.dtype == np.uint8 and np.array_equal(x, y), n


@pytest.mark.parametrize("spill", [False, True])
def test_held_frames_read_as_the_file_reads(damaged, tmp_path, spill):
    held = hold_frames(damaged, 4, max_bytes=0 if spill else None, spill_dir=tmp_path, notify=lambda _n: None)
    try:
        assert (held.spill is not None) == spill and held.ended and held.numbers[0] == 5
        assert isinstance(held.frames, np.memmap) == spill
        for start, frames in ((4, None), (4, 6), (8, 10), (10, 3), (10, None)):
            want, want_skipped = _read(damaged, start, frames)
            got, got_skipped = _read(held, start, frames)
            _same(got, want)
            assert got_skipped == want_skipped, (start, frames)
        assert _read(held, 8, 10)[1] == [(13, 14)]  # the damaged frames, as the file's reader says
        with FrameReader(held, 4, notify=lambda _n: None) as r:
            assert r.fps == 25.0 and r.kind == "file" and r.held is held and r.path == str(damaged)
            ahead = r.peek(3)
            frames_out = [f for _, f, _ in r]
            assert all(np.array_equal(a, b) for a, b in zip(ahead, frames_out[:3]))
            frames_out[0][:] = 0  # a copy: the held frame is untouched
        assert held.frames[0].any()
        with pytest.raises(ValueError, match="not frame 3"):
            FrameReader(held, 2)
        with pytest.raises(DataError, match="past the end"):
            FrameReader(held, 40)
    finally:
        held.close()
    assert not leftovers(tmp_path) and held.spill is None


def test_frames_not_held_and_a_decoding_error(damaged):
    # read up to a frame limit: frames past it are not held (never silently cut short)
    held = hold_frames(damaged, 0, 5, notify=lambda _n: None)
    assert not held.ended and len(held) == 5
    assert len(_read(held, 0, 5)[0]) == 5
    with pytest.raises(ValueError, match="after 5 are not held"):
        _read(held, 2)
    # an error the reading met is raised after the frames before it, every time
    f = np.zeros((8, 8, 3), np.uint8)
    err = HeldFrames("x.mp4", 25.0, 10, 0, np.array([1, 2]), [f, f], np.zeros(2), True, "x.mp4: frame 3 is ...")
    for _ in range(2):
        with FrameReader(err) as r:
            seen = []
            with pytest.raises(DataError, match="frame 3 is"):
                for fno, _, _ in r:
                    seen.append(fno)
            assert seen == [1, 2]


def test_a_spill_that_cannot_be_written_is_one_line_and_leaves_nothing(damaged, tmp_path):
    not_a_folder = tmp_path / "file"
    not_a_folder.write_text("")
    with pytest.raises(WriteError, match=r"cannot hold the frames of .*damaged.mp4 there") as e:
        hold_frames(damaged, 0, max_bytes=0, spill_dir=not_a_folder)
    assert "\n" not in str(e.value)
    with pytest.raises(ValueError, match="spill_dir"):
        hold_frames(damaged, 0, max_bytes=0)

    class Full:
        """A file object whose writes fail after the first frame, as on a full disk."""

        def __init__(self, path, mode):
            self.fh, self.n = open(path, mode), 0  # noqa: SIM115

        def write(self, b):
            self.n += 1
            if self.n > 1:
                raise OSError(28, "No space left on device")
            return self.fh.write(b)

        def flush(self):
            self.fh.flush()

        def close(self):
            self.fh.close()

    import fastdet.io.hold as held_mod

    held_mod.open = Full  # type: ignore[attr-defined]
    try:
        with pytest.raises(WriteError, match="No space left on device"):
            hold_frames(damaged, 0, max_bytes=0, spill_dir=tmp_path)
    finally:
        del held_mod.open  # type: ignore[attr-defined]
    assert not leftovers(tmp_path)


def test_a_stop_while_holding_removes_the_spill(damaged, tmp_path):
    def stop(_note):
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):  # the reader's note of the damage comes midway
        hold_frames(damaged, 0, max_bytes=0, spill_dir=tmp_path, notify=stop)
    assert not leftovers(tmp_path)
