"""fastdet.detect.checks: a frame, a horizon the search cannot use is refused in one line."""
from __future__ import annotations

import pytest

from fastdet.cli.main import main
from fastdet.detect.checks import check_frame_size, check_horizon
from fastdet.errors import DataError
from fastdet.video import make_detector


@pytest.fixture(scope="module")
def det():
    return make_detector()  # the main and the oncoming model


@pytest.mark.parametrize("shape", [(1, 1000), (1, 1), (2, 1000), (1000, 1)])
def test_thin_frames_get_the_message_not_a_traceback(det, shape):
    with pytest.raises(DataError, match=f"frames of {shape[1]}x{shape[0]} are too small"):
        check_frame_size(det, shape, "x")


def test_horizon_without_room_for_a_band(det):
    with pytest.raises(DataError, match=r"--horizon must be a fraction of the frame height in \[0, 1\)"):
        check_horizon(det, (720, 1280), 1.0, "x")
    with pytest.raises(DataError, match=r"--horizon 0.99 leaves no room .* between 0 and 0\.\d+ of the height"):
        check_horizon(det, (720, 1280), 0.99, "x")
    for ok in (0.0, 0.3, 0.585, 0.7, "auto", None):
        check_horizon(det, (720, 1280), ok, "x")


@pytest.mark.parametrize("h", ["1", "0.99"])
def test_video_horizon_one_line(tmp_path, capsys, h):
    from tests.media import write_video
    clip = write_video(tmp_path / "c.mp4", 3, w=480, h=270)
    assert main(["video", str(clip), "--boxes", str(tmp_path / "b.txt"), "--horizon", h, "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "--horizon" in err and len(err.strip().splitlines()) == 1 and not (tmp_path / "b.txt").exists()
