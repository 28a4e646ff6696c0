"""Picture sizes without decoding the pictures: :func:`image_size` reads a JPEG's frame header
(``SOFn``) or a PNG's ``IHDR`` chunk (a few hundred bytes), :func:`video_size` asks the
video's container. A label reader needs the size to turn normalised boxes into pixels and to
clip boxes; decoding every picture of a set for it would cost seconds per hundred pictures.
"""
from __future__ import annotations

import os
import struct
from pathlib import Path
from typing import BinaryIO

import cv2

from ..console import quiet_native_stderr, quiet_opencv
from ..errors import DataError

_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
#: JPEG start-of-frame markers that carry the picture's size (every SOFn but DHT C4, JPG C8, DAC CC)
_SOF = {0xC0, 0xC1, 0xC2, 0xC3, 0xC5, 0xC6, 0xC7, 0xC9, 0xCA, 0xCB, 0xCD, 0xCE, 0xCF}
#: markers without a length field (TEM, RSTn, SOI, EOI)
_NO_LENGTH = {0x01, *range(0xD0, 0xDA)}


def _jpeg_size(fh: BinaryIO) -> tuple[int, int] | None:
    """``(width, height)`` from the first SOFn segment of the JPEG ``fh`` (positioned after
    its SOI marker); None when the file ends or is damaged before one."""
    while True:
        b = fh.read(1)
        while b and b != b"\xff":  # stray bytes between segments: skip
            b = fh.read(1)
        while b == b"\xff":  # fill bytes
            b = fh.read(1)
        if not b:
            return None
        marker = b[0]
        if marker in _NO_LENGTH:
            continue
        if marker == 0xDA:  # start of scan before any frame header: damaged
            return None
        head = fh.read(2)
        if len(head) < 2:
            return None
        (length,) = struct.unpack(">H", head)
        if length < 2:
            return None
        if marker in _SOF:
            body = fh.read(5)
            if len(body) < 5:
                return None
            height, width = struct.unpack(">HH", body[1:5])
            return width, height
        fh.seek(length - 2, os.SEEK_CUR)


def header_size(path: str | os.PathLike[str]) -> tuple[int, int] | None:
    """``(width, height)`` in pixels from a JPEG or PNG file's header, or None when the file
    is neither (or its header is damaged). Reads only the header: no pixel is decoded."""
    with open(path, "rb") as fh:
        start = fh.read(8)
        if start.startswith(b"\xff\xd8"):
            fh.seek(2)
            return _jpeg_size(fh)
        if start == _PNG_SIGNATURE:
            chunk = fh.read(16)  # length, b"IHDR", width, height
            if len(chunk) == 16 and chunk[4:8] == b"IHDR":
                width, height = struct.unpack(">II", chunk[8:16])
                return width, height
    return None


def image_size(path: str | os.PathLike[str]) -> tuple[int, int]:
    """``(width, height)`` of the image at ``path`` in pixels: from the header for JPEG and
    PNG (:func:`header_size`), by decoding with OpenCV for any other format (or a header it
    could not read). :class:`DataError` (naming the file) for a missing file, a folder, or a
    file that is no image."""
    name = os.fspath(path)
    p = Path(name)
    if not p.is_file():
        raise DataError(f"{name}: " + ("is a folder, not an image" if p.is_dir() else "image file not found"))
    try:
        size = header_size(p)
    except OSError as exc:
        raise DataError(f"{name}: cannot read ({exc.strerror or exc})") from None
    if size is not None and size[0] > 0 and size[1] > 0:
        return size
    with quiet_native_stderr():
        img = cv2.imread(name, cv2.IMREAD_UNCHANGED)
    if img is None:
        raise DataError(f"{name}: not an image OpenCV can read (damaged, empty or another format)")
    return int(img.shape[1]), int(img.shape[0])


def video_size(path: str | os.PathLike[str]) -> tuple[int, int]:
    """``(width, height)`` of the video at ``path`` in pixels, from its container (no frame
    is decoded). :class:`DataError` for a missing file or one OpenCV cannot open as a video."""
    name = os.fspath(path)
    p = Path(name)
    if not p.is_file():
        raise DataError(f"{name}: " + ("is a folder, not a video" if p.is_dir() else "video file not found"))
    quiet_opencv()
    cap = cv2.VideoCapture(name)
    try:
        ok = cap.isOpened()
        w = int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)) if ok else 0
        h = int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT)) if ok else 0
    finally:
        cap.release()
    if w <= 0 or h <= 0:
        raise DataError(f"{name}: not a video OpenCV can open (damaged, empty or another format)")
    return w, h


#: file name endings of pictures a label reader pairs with label files (lower case)
IMAGE_SUFFIXES = (".jpg", ".jpeg", ".png", ".bmp", ".webp", ".tif", ".tiff")
