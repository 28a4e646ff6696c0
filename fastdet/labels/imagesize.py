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
from ..io.files import check_input, not_found

_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
#: JPEG start-of-frame markers that carry the picture's size (every SOFn but DHT C4, JPG C8, DAC CC)
_SOF = {0xC0, 0xC1, 0xC2, 0xC3, 0xC5, 0xC6, 0xC7, 0xC9, 0xCA, 0xCB, 0xCD, 0xCE, 0xCF}
#: markers without a length field (TEM, RSTn, SOI, EOI)
_NO_LENGTH = {0x01, *range(0xD0, 0xDA)}


def exif_orientation(app1: bytes) -> int:
    """The EXIF orientation tag (1 to 8; 1 = as stored) of an APP1 segment's payload, 1 when
    it has none (or is no EXIF)."""
    if not app1.startswith(b"Exif\x00\x00") or len(app1) < 14:
        return 1
    tiff = app1[6:]
    order = {b"II": "<", b"MM": ">"}.get(tiff[:2])
    if order is None:
        return 1
    try:
        (ifd,) = struct.unpack(order + "I", tiff[4:8])
        (count,) = struct.unpack(order + "H", tiff[ifd:ifd + 2])
        for k in range(count):
            at = ifd + 2 + 12 * k
            tag, _kind, _n = struct.unpack(order + "HHI", tiff[at:at + 8])
            if tag == 0x0112:
                (value,) = struct.unpack(order + "H", tiff[at + 8:at + 10])
                return int(value)
    except struct.error:
        return 1
    return 1


def _jpeg_size(fh: BinaryIO) -> tuple[int, int, int] | None:
    """``(width, height, EXIF orientation)`` from the segments of the JPEG ``fh`` (positioned
    after its SOI marker) up to the first SOFn; None when the file ends or is damaged before."""
    orientation = 1
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
            return width, height, orientation
        if marker == 0xE1 and orientation in (0, 1):
            orientation = exif_orientation(fh.read(length - 2))
        else:
            fh.seek(length - 2, os.SEEK_CUR)


def header_size(path: str | os.PathLike[str]) -> tuple[int, int] | None:
    """``(width, height)`` in pixels from a JPEG or PNG file's header, or None when the file
    is neither (or its header is damaged). Reads only the header: no pixel is decoded.
    A JPEG whose EXIF orientation says to turn it is a :class:`DataError`: OpenCV decodes it
    turned, and whether a labelling tool drew the boxes on the stored or the turned picture
    cannot be told."""
    with open(path, "rb") as fh:
        start = fh.read(8)
        if start.startswith(b"\xff\xd8"):
            fh.seek(2)
            got = _jpeg_size(fh)
            if got is not None and 2 <= got[2] <= 8:  # 0 and other values: invalid, read as 1
                raise DataError(f"{os.fspath(path)}: the JPEG says to turn it (EXIF orientation {got[2]}): "
                                f"are its labels for the picture as stored or as turned? Save it turned "
                                f"(without the orientation tag) and label that")
            return None if got is None else got[:2]
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
    if p.is_dir():
        raise DataError(f"{name}: is a folder, not an image")
    if not p.exists() and not p.is_symlink():
        raise DataError(f"{name}: image file not found")
    check_input(p, "image")  # a FIFO or a device: refused before it is opened
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
        if p.is_dir():
            raise DataError(f"{name}: is a folder, not a video")
        raise not_found(p, f"{name}: video file not found")
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
