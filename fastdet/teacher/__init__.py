"""A teacher: a bigger CNN detector that labels frames for fastdet (issue 31).

:class:`TeacherDetector` runs a YOLOX-style ONNX model (:mod:`.yolox`) on one frame;
:func:`label_video` runs it on every N-th frame of a video and :func:`write_teacher_files`
writes what it saw as ``CLIP.teacher.txt`` + ``CLIP.frames`` (:mod:`.label`), the format of the
shared ``teacher/`` folder. onnxruntime is optional (``pip install 'fastdet[teacher]'``); it
is imported only when a detector is made.
"""
from .label import (
    FRAMES_SUFFIX,
    TEACHER_SUFFIX,
    clip_name,
    format_line,
    label_frames,
    label_video,
    teacher_paths,
    teacher_text,
    write_teacher_files,
)
from .yolox import TeacherBoxes, TeacherDetector

__all__ = ["FRAMES_SUFFIX", "TEACHER_SUFFIX", "TeacherBoxes", "TeacherDetector", "clip_name", "format_line",
           "label_frames", "label_video", "teacher_paths", "teacher_text", "write_teacher_files"]
