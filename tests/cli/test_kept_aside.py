"""``adapt``'s kept-aside frames (``fastdet.cli.kept_aside``): each stretch read once (held_stretches):
in memory under ``AdaptConfig.hold_bytes``, the rest in raw files of the work folder, a clip
whose file cannot be written read from its video again (a note); nothing left behind, a stop
included."""
from __future__ import annotations

import pytest

from fastdet.cli.kept_aside import _source, held_stretches
from fastdet.config.adapt import AdaptConfig
from fastdet.train.adapt import plan_footage
from tests.media import leftovers, write_video

FRAME = 160 * 120 * 3


@pytest.fixture(scope="module")
def footage(tmp_path_factory):
    d = tmp_path_factory.mktemp("footage")
    videos = [str(write_video(d / f"{n}.mp4", 30, w=160, h=120)) for n in ("a", "b", "c")]
    fp = plan_footage(videos, AdaptConfig())
    assert [c.holdout_start for c in fp.clips] == [25, 25, 25]  # the last 6 frames of each kept aside
    return fp


def test_memory_then_files_then_the_video(footage, tmp_path, capsys):
    labelled = {"a": ["p"], "b": ["p"], "c": ["p"]}
    blocked = tmp_path / "blocked"
    blocked.write_text("")  # a spill folder inside a file: b's and c's frames cannot be written there
    config = AdaptConfig(hold_bytes=6 * FRAME)
    with held_stretches(footage, labelled, config, tmp_path / "op") as frames:
        a, b = frames["a"], frames["b"]
        assert a.spill is None and list(a.numbers) == list(range(25, 31)) and a.nbytes == 6 * FRAME
        assert b.spill is not None and b.spill.parent == tmp_path / "op" and len(b) == 6
        assert frames["c"].spill is not None and leftovers(tmp_path / "op") == sorted(
            [b.spill.name, frames["c"].spill.name])
        assert _source(footage.clips[1], frames) is b
    assert not leftovers(tmp_path / "op")
    with held_stretches(footage, labelled, AdaptConfig(hold_bytes=6 * FRAME), blocked / "op") as frames:
        assert set(frames) == {"a"} and _source(footage.clips[2], frames) == footage.clips[2].path
    out = capsys.readouterr().out
    assert out.count("note: ") == 2 and "cannot hold the frames of" in out
    assert "each run decodes c up to its kept-aside stretch instead" in out
    with held_stretches(footage, {"b": ["p"]}, AdaptConfig(hold_bytes=0), tmp_path / "op") as frames:
        assert set(frames) == {"b"} and frames["b"].spill is not None  # clips without labels: not read


def test_a_stop_removes_the_held_files(footage, tmp_path):
    with pytest.raises(KeyboardInterrupt):
        with held_stretches(footage, {"a": ["p"], "b": ["p"]}, AdaptConfig(hold_bytes=0), tmp_path) as frames:
            assert len(leftovers(tmp_path)) == 2 and all(f.spill is not None for f in frames.values())
            raise KeyboardInterrupt
    assert not leftovers(tmp_path)
