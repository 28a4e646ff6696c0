"""The videos of a batch: INPUT arguments expanded to video files, and a unique output name each.

An INPUT is

- a video file (any name: OpenCV decides later whether it reads it);
- a folder, searched recursively for files with a video extension (:data:`VIDEO_EXTENSIONS`,
  hidden files and folders skipped);
- a glob pattern (``'clips/**/*.mp4'``, quoted so that fastdet expands it, recursively);
- a list file: a text file with a ``.txt`` / ``.lst`` / ``.list`` extension, one path
  per line (relative paths are relative to the list file's folder; blank lines and lines
  starting with ``#`` are skipped; a line may itself be a folder or a glob).

Videos are kept in the order given (the videos of a folder or a glob sorted by path), each
file once. An
INPUT that does not exist or matches nothing raises :class:`~fastdet.errors.DataError`
before anything runs.

A batch never reads what it writes: with ``writes`` (:func:`batch_writes`), a file the batch
writes or could write (``NAME.annotated.mp4`` and the other outputs in the output folder,
whatever the options) found in a folder or by a glob is left out, and one named as an INPUT
(or in a list file) is refused.
"""
from __future__ import annotations

import glob
import os
import re
import zlib
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path

from ..errors import DataError
from ..io.files import not_found

VIDEO_EXTENSIONS = frozenset({".mp4", ".avi", ".mov", ".mkv", ".m4v", ".mpg", ".mpeg", ".wmv", ".webm",
                              ".ts", ".mts", ".m2ts", ".flv", ".3gp", ".h264", ".h265", ".hevc"})
LIST_EXTENSIONS = frozenset({".txt", ".lst", ".list"})
_GLOB_CHARS = re.compile(r"[*?\[]")
_UNSAFE = re.compile(r"[^A-Za-z0-9._+-]+")


def is_video_name(path: str | os.PathLike) -> bool:
    """True when the file name has a video extension."""
    return Path(path).suffix.lower() in VIDEO_EXTENSIONS


Writes = Callable[[Path], bool]


def batch_writes(out_dir: str | os.PathLike, suffixes: Iterable[str],
                 names: Iterable[str | os.PathLike] = ()) -> Writes:
    """A test ``writes(path)``: True for a file a batch into ``out_dir`` writes or could write
    -- one in ``out_dir`` whose name ends with one of ``suffixes``, or one of ``names``
    (the manifest, the table). Real paths are compared."""
    out = os.path.realpath(out_dir)
    ends = tuple(suffixes)
    exact = {os.path.realpath(n) for n in names}

    def writes(path: Path) -> bool:
        real = os.path.realpath(path)
        return real in exact or (os.path.dirname(real) == out and os.path.basename(real).endswith(ends))

    return writes


def _never(path: Path) -> bool:
    return False


def _folder_videos(folder: Path, writes: Writes = _never) -> list[Path]:
    found: list[Path] = []
    for root, dirs, files in os.walk(folder):
        dirs[:] = sorted(d for d in dirs if not d.startswith("."))
        found.extend(p for p in (Path(root) / f for f in files if not f.startswith(".") and is_video_name(f))
                     if p.is_file() and not writes(p))  # not a pipe or a device named like a video
    return sorted(found, key=lambda p: p.relative_to(folder).parts)


def _expand_one(arg: str, base: Path | None, depth: int, writes: Writes = _never) -> list[Path]:
    where = f"{arg} (listed in {base})" if base is not None else arg
    p = Path(arg).expanduser()
    if base is not None and not p.is_absolute():
        p = base / p
    if p.is_dir():
        return _folder_videos(p, writes)
    if p.is_file():
        if writes(p):
            raise DataError(f"{where}: is a file this batch writes (an output in --out); it cannot be an input")
        if p.suffix.lower() in LIST_EXTENSIONS:
            if depth > 0:
                raise DataError(f"{where}: a list file inside a list file is not supported")
            return _read_list(p, writes)
        return [p]
    if _GLOB_CHARS.search(arg):
        hits = sorted(Path(h) for h in glob.glob(str(p), recursive=True))
        videos: list[Path] = []
        for h in hits:
            if h.is_dir():
                videos.extend(_folder_videos(h, writes))
            elif h.is_file() and is_video_name(h) and not writes(h):
                videos.append(h)
        if not videos:
            raise DataError(f"{where}: the pattern matches no video")
        return videos
    if p.exists():
        raise DataError(f"{where}: not a file or folder")
    raise not_found(p, f"{where}: file not found")


def _read_list(path: Path, writes: Writes = _never) -> list[Path]:
    try:
        text = path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError:
        raise DataError(f"{path}: a list file must be UTF-8 text, one path per line") from None
    except OSError as exc:
        raise DataError(f"{path}: cannot read ({exc.strerror or exc})") from None
    videos: list[Path] = []
    for line in text.splitlines():
        line = line.strip()
        if line and not line.startswith("#"):
            videos.extend(_expand_one(line, path.parent, 1, writes))
    return videos


def expand_inputs(inputs: Sequence[str], writes: Writes = _never) -> list[Path]:
    """The video files named by ``inputs`` (see the module docstring): absolute paths, in
    order, each file once; files that ``writes`` says the batch writes are left out of
    folders and globs and refused when named. :class:`DataError` for an input that names
    nothing, or when there is no video at all."""
    seen: set[str] = set()
    videos: list[Path] = []
    for arg in inputs:
        for v in _expand_one(arg, None, 0, writes):
            v = Path(os.path.abspath(v))
            key = os.path.realpath(v)
            if key not in seen:
                seen.add(key)
                videos.append(v)
    if not videos:
        raise DataError(f"no video found in {', '.join(inputs)} (extensions: "
                        f"{', '.join(sorted(VIDEO_EXTENSIONS))})")
    return videos


def _safe(part: str) -> str:
    return _UNSAFE.sub("_", part).strip("._") or "video"


def output_names(videos: Iterable[Path], max_len: int | None = None) -> list[str]:
    """One output name per video (no extension; used as ``NAME.boxes.txt`` etc.), unique
    within the batch and independent of the order of the videos.

    The name is the file's stem; videos sharing a stem get as many parent folder names as
    it takes to tell them apart (``day1_clip``, ``day2_clip``), and the extension too when
    that is what differs (``clip_mp4``, ``clip_avi``). Characters other than letters,
    digits and ``._+-`` become ``_``. A name longer than ``max_len`` characters (the output
    folder's longest file name less the longest suffix: a 245-character video name) is cut
    and ends in a checksum of the video's path (``LONG_PREFIX_1a2b3c4d``), so every output
    name fits the file system.
    """
    videos = [Path(v) for v in videos]
    names = [_safe(v.stem) for v in videos]
    for _ in range(64):  # each round adds a folder to every clashing name; paths end
        groups: dict[str, list[int]] = {}
        for i, n in enumerate(names):
            groups.setdefault(n.lower(), []).append(i)
        clashes = [idx for idx in groups.values() if len(idx) > 1]
        if not clashes:
            return [_fit(n, v, max_len) for n, v in zip(names, videos)]
        for idx in clashes:
            for i in idx:
                names[i] = _longer_name(videos[i], names[i])
    raise DataError("cannot give the videos unique output names")  # pragma: no cover - paths end


def _fit(name: str, video: Path, max_len: int | None) -> str:
    """``name`` cut to ``max_len`` characters (ASCII: one byte each), a checksum of the video's
    path at its end keeping it unique; as it is when it fits."""
    if max_len is None or len(name) <= max_len:
        return name
    tag = f"_{zlib.crc32(os.fsencode(video)):08x}"
    return name[: max(1, max_len - len(tag))] + tag


def _longer_name(video: Path, current: str) -> str:
    """The next longer candidate name of ``video`` after ``current``."""
    parts = [_safe(p) for p in video.parent.parts if p not in ("/", "")]
    stem = _safe(video.stem)
    for k in range(1, len(parts) + 1):
        cand = "_".join(parts[-k:] + [stem])
        if len(cand) > len(current):
            return cand
    ext = _safe(video.suffix.lstrip(".")) if video.suffix else "noext"
    with_ext = "_".join(parts + [stem, ext])
    if len(with_ext) > len(current):
        return with_ext
    return f"{current}_{zlib.crc32(os.fsencode(video)):08x}"
