"""Image files: read strictly (:func:`read_image`), written atomically (:func:`write_image`).

OpenCV decodes a truncated JPEG without an error -- libjpeg prints "Premature end of JPEG
file" on stderr and fills the missing rows with grey -- so :func:`check_image` looks at the
file itself: a JPEG's last scan must be followed by its end-of-image marker (``FF D9``;
entropy-coded data can never contain it, so a file cut short has none). A truncated PNG
already fails to decode. ``cv2.imwrite`` returns ``False`` both for an extension it does
not know and for a failed write (a full disk): :func:`write_image` tells the two apart.
"""
from __future__ import annotations

import os
from pathlib import Path

import cv2
import numpy as np

from ..console import quiet_native_stderr
from ..errors import DataError, WriteError
from .atomic import atomic_path
from .files import check_input, read_input_bytes

#: the largest image file read (a 16-bit 8K PNG is under 200 MB)
MAX_IMAGE_BYTES = 512 * 2**20

_SOI, _SOS, _EOI = b"\xff\xd8", b"\xff\xda", b"\xff\xd9"


def jpeg_complete(data: bytes) -> bool:
    """``data`` (a JPEG file's bytes) ends its last scan with the end-of-image marker;
    ``True`` for data that is not a JPEG."""
    if not data.startswith(_SOI):
        return True
    last_scan = data.rfind(_SOS)
    return last_scan >= 0 and data.find(_EOI, last_scan + 2) >= 0


def check_image(path: str | os.PathLike) -> None:
    """``DataError`` when the image file ``path`` is a JPEG cut short (see the module
    docstring)."""
    name = os.fspath(path)
    data = read_input_bytes(name, "image", MAX_IMAGE_BYTES)
    if not jpeg_complete(data):
        raise DataError(f"{name}: the JPEG file is cut short (truncated or damaged): "
                        f"part of the picture is missing")


def read_image(path: str | os.PathLike) -> np.ndarray:
    """The image at ``path`` as ``(H, W, 3) uint8`` BGR; ``DataError`` for a missing file, a
    folder, a file OpenCV cannot decode, or a truncated JPEG."""
    name = os.fspath(path)
    if os.path.isdir(name):
        raise DataError(f"{name}: is a folder, not an image")
    st = check_input(name, "image")  # a FIFO or a device: refused before OpenCV opens it
    if st.st_size > MAX_IMAGE_BYTES:
        raise DataError(f"{name}: is {st.st_size // 2**20} MB, larger than an image may be "
                        f"({MAX_IMAGE_BYTES // 2**20} MB)")
    with quiet_native_stderr():  # libpng / libjpeg complaints: we say it in one line
        frame = cv2.imread(name, cv2.IMREAD_COLOR)
    if frame is None:
        raise DataError(f"{name}: not an image OpenCV can read (damaged, empty or another format)")
    check_image(name)
    return frame


def write_image(path: str | os.PathLike, img: np.ndarray) -> Path:
    """``cv2.imwrite`` to ``.NAME.partial.EXT``, then rename to ``path``; ``DataError`` (and
    nothing under either name) when the extension is not an image format OpenCV writes or
    the write failed (a full disk)."""
    path = Path(path)
    if not cv2.haveImageWriter(str(path)):
        raise DataError(f"{path}: cannot write an image there (extension {path.suffix or '(none)'!r} "
                        f"not supported? use .jpg or .png)")
    with atomic_path(path) as tmp:
        try:
            with quiet_native_stderr():
                ok = cv2.imwrite(str(tmp), img)
        except cv2.error:
            ok = False
        if not ok or not _readable(tmp):
            tmp.unlink(missing_ok=True)
            raise WriteError(f"{path}: writing the image failed (disk full or a file-size limit?)")
    return path


def _readable(path: Path) -> bool:
    """The written file decodes, and is not a JPEG cut short."""
    try:
        data = path.read_bytes()
    except OSError:
        return False
    if not data or not jpeg_complete(data):
        return False
    with quiet_native_stderr():
        return cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED) is not None
