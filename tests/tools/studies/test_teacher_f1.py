"""tools/studies/teacher_f1.py: the teacher's boxes on a clip's keyframes, scored as the label
command's files of every frame score on those keyframes."""
from __future__ import annotations

import numpy as np
import pytest

from fastdet.detections import Detections
from fastdet.eval import evaluate
from fastdet.eval.clips import annotated_clips
from fastdet.labels.teacher import read_teacher_clip
from fastdet.teacher.label import label_video, write_teacher_files

pytest.importorskip("onnxruntime")


def test_keyframes_only_score_as_every_frame_labelled(data, yolox_nano, tmp_path):
    from fastdet.teacher import TeacherDetector
    from tools.studies.teacher_f1 import teacher_rows

    clip = {c.name: c for c in annotated_clips(data)}["boston_street"]  # 40 frames, 8 keyframes
    keys = clip.keyframes()
    assert keys is not None and 0 < len(keys) < 40
    detector = TeacherDetector(yolox_nano, size=640)
    got = teacher_rows(clip, detector, [0.3, 0.5], tmp_path / "study")
    # the slow, obvious twin: `fastdet label --every 1` over the whole clip, scored on the keyframes
    (tmp_path / "every").mkdir()
    boxes_path, _ = write_teacher_files(tmp_path / "every", clip.name, label_video(clip.video, detector, every=1))
    for m in (0.3, 0.5):
        pics = read_teacher_clip(boxes_path, min_score=m, video=clip.video)
        preds = Detections.concat([Detections(p.targets.astype(np.int32), np.ones(len(p.targets), np.float32),
                                              frames=np.full(len(p.targets), p.frame, np.int64))
                                   for p in pics if len(p.targets)])
        want = evaluate(clip.gt(), preds, keyframes=keys)
        assert (got[m].tp, got[m].fp, got[m].fn) == (want.tp, want.fp, want.fn)
        assert want.tp > 0
    # a stricter score keeps fewer targets: the thresholds are applied
    assert got[0.5].tp + got[0.5].fp < got[0.3].tp + got[0.3].fp
