"""Labelling adapt's footage on a Dask cluster (``adapt --workers``): the same label files as
labelling it here."""
from __future__ import annotations

from pathlib import Path

import pytest

pytest.importorskip("distributed")
pytest.importorskip("onnxruntime")

from fastdet.cli import adapt as adapt_cli  # noqa: E402
from fastdet.cli.main import build_parser  # noqa: E402
from fastdet.config.adapt import AdaptConfig  # noqa: E402
from fastdet.teacher.label import teacher_paths  # noqa: E402
from fastdet.teacher.yolox import TeacherDetector  # noqa: E402
from fastdet.train import adapt  # noqa: E402


@pytest.mark.slow
def test_the_cluster_writes_the_labels_the_teacher_gives_here(data: Path, yolox_nano: Path, tmp_path: Path):
    """test_video (one video, 6 planned frames) labelled by a local cluster of one worker through
    adapt's own option handling, and by the teacher in this process: the same files, byte for
    byte; a second run finds them and labels nothing."""
    video = data / "videos" / "test_video.mp4"
    footage = adapt.plan_footage([str(video)], AdaptConfig(every=10, max_frames=4))
    args = build_parser().parse_args(["adapt", str(video), "--teacher", str(yolox_nano), "-o",
                                      str(tmp_path / "cam.npz"), "--workers", "1"])
    make = adapt_cli._cluster_labelling(args)
    assert make is not None
    detector = TeacherDetector(yolox_nano, threads=1)
    here, _ = adapt.label_clips(footage, detector, tmp_path / "here", progress=False, log=lambda s: None)
    there, n = adapt.label_clips(footage, detector, tmp_path / "there", progress=False, log=lambda s: None,
                                 labeller=make(detector.config.min_score))
    clip = footage.clips[0]
    assert n == len(footage.planned(clip)) >= 4
    for a, b in zip(teacher_paths(tmp_path / "here", clip.key), teacher_paths(tmp_path / "there", clip.key)):
        assert a.read_bytes() == b.read_bytes() and a.stat().st_size > 0
    again, n2 = adapt.label_clips(footage, detector, tmp_path / "there", progress=False, log=lambda s: None,
                                  labeller=make(detector.config.min_score))
    assert n2 == 0 and again == there
