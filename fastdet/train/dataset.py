"""Training crops: loading folders of 64x64 PNGs and splitting them without leaks.

Layout (``../shared/data``): ``vehicles/<folder>/...png`` are positives,
``non-vehicles/<folder>/...png`` negatives, at any depth. Within a folder, files sorted by
the number in their name are in time order (GTI images are consecutive video frames), so
the *sequence* split cuts every folder into contiguous blocks instead of shuffling frames
of the same car to both sides.
"""
from __future__ import annotations

import re
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from ..errors import DataError
from ..io.files import check_input, not_found

_NUM = re.compile(r"(\d+)")


def _sort_key(path: Path) -> tuple:
    nums = _NUM.findall(path.stem)
    return (int(nums[-1]) if nums else -1, path.name)


@dataclass(frozen=True)
class CropSet:
    """images: ``(N, 64, 64, 3) uint8`` BGR; labels: ``(N,) int64`` (1 vehicle, 0 not);
    groups: ``(N,)`` folder of each crop (relative to the data folder); order: ``(N,)``
    position of the crop in its folder's time order."""

    images: np.ndarray
    labels: np.ndarray
    groups: np.ndarray
    order: np.ndarray

    def __len__(self) -> int:
        return len(self.labels)

    def subset(self, idx: np.ndarray) -> "CropSet":
        return CropSet(self.images[idx], self.labels[idx], self.groups[idx], self.order[idx])

    @staticmethod
    def concat(a: "CropSet", b: "CropSet") -> "CropSet":
        return CropSet(np.concatenate([a.images, b.images]), np.concatenate([a.labels, b.labels]),
                       np.concatenate([a.groups, b.groups]), np.concatenate([a.order, b.order]))


def find_pngs(folder: Path) -> dict[Path, list[Path]]:
    """PNG files under ``folder`` (any depth), grouped by their parent folder, each group in
    time order (by the last number in the file name)."""
    groups: dict[Path, list[Path]] = {}
    for p in folder.rglob("*.png"):
        groups.setdefault(p.parent, []).append(p)
    return {k: sorted(v, key=_sort_key) for k, v in sorted(groups.items())}


def _read(path: Path, size: int | None) -> np.ndarray:
    check_input(path, "training crop")  # a FIFO would block the reader thread for ever
    img = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if img is None:
        raise DataError(f"{path}: not a readable image")
    if size is not None and img.shape[:2] != (size, size):
        img = cv2.resize(img, (size, size), interpolation=cv2.INTER_AREA)
    return img


def thinned(count: int, n: int | None) -> np.ndarray:
    """Positions ``(min(n, count),) int64`` kept of a folder of ``count`` crops in time order
    when at most ``n`` are wanted: evenly spread from the first to the last (``n`` ``None`` or
    0: all)."""
    if not n or n >= count:
        return np.arange(count, dtype=np.int64)
    return np.linspace(0, count - 1, n).astype(np.int64)


def load_folder(folder: Path, label: int, root: Path | None = None, size: int | None = 64,
                progress: bool = False, max_per_folder: int | None = None) -> CropSet:
    """All PNGs under ``folder`` with one label; crops not ``size``x``size`` are resized
    (``size=None``: kept as they are, and they must then all have the same shape).
    ``max_per_folder``: only the crops :func:`thinned` keeps of each folder are read (their
    ``order`` is still their position among all of the folder's crops)."""
    folder = Path(folder)
    if not folder.is_dir():
        raise not_found(folder, f"folder {folder} not found")
    groups = find_pngs(folder)
    if not any(groups.values()):
        raise DataError(f"no .png files under {folder}")
    paths, names, order = [], [], []
    for g, ps in groups.items():
        rel = str(g.relative_to(root)) if root is not None else str(g)
        keep = thinned(len(ps), max_per_folder)
        paths += [ps[k] for k in keep]
        names += [rel] * len(keep)
        order += keep.tolist()
    with ThreadPoolExecutor(max_workers=4) as pool:
        it = pool.map(lambda p: _read(p, size), paths, chunksize=64)
        if progress:
            from tqdm import tqdm

            it = tqdm(it, total=len(paths), desc=f"reading {folder.name}", unit="img", leave=False)
        imgs = list(it)
    shapes = {im.shape for im in imgs}
    if len(shapes) > 1:
        raise DataError(f"images under {folder} have different sizes {sorted(shapes)}")
    images = np.stack(imgs)
    return CropSet(images, np.full(len(paths), label, np.int64), np.array(names), np.array(order, np.int64))


def load_crops(data: Path, size: int = 64, progress: bool = False, max_per_folder: int | None = None) -> CropSet:
    """``data/vehicles`` (label 1) and ``data/non-vehicles`` (label 0); ``max_per_folder``:
    of each folder only the crops :func:`thinned` keeps (the others are not read)."""
    data = Path(data)
    for sub in ("vehicles", "non-vehicles"):
        if not (data / sub).is_dir():
            raise DataError(f"{data} has no '{sub}' folder (expected {data}/vehicles and {data}/non-vehicles)")
    pos = load_folder(data / "vehicles", 1, data, size, progress, max_per_folder)
    neg = load_folder(data / "non-vehicles", 0, data, size, progress, max_per_folder)
    return CropSet.concat(pos, neg)


def random_split(labels: np.ndarray, seed: int, test_size: float = 0.2) -> tuple[np.ndarray, np.ndarray]:
    """Stratified random split: ``(train_idx, test_idx)``."""
    from sklearn.model_selection import train_test_split

    idx = np.arange(len(labels))
    tr, te = train_test_split(idx, test_size=test_size, random_state=seed, stratify=labels)
    return np.sort(tr), np.sort(te)


#: crops of each class the random split needs: a fifth of each is held out, so 5 give the
#: test part one and the training part four
MIN_RANDOM_SPLIT = 5


def check_splits(labels: np.ndarray, groups: np.ndarray, order: np.ndarray, split: str, seed: int) -> None:
    """:class:`DataError` (one line saying what each split needs) when a split ``train`` will
    make (``'random'``, ``'sequence'``, ``'both'``; ``'none'``: the final fit) would leave a
    class out of its training or its test part: scikit-learn would fail with a traceback
    (1 + 1 or 2 + 2 crops, or ``--split sequence`` with too few crops in the folders)."""
    n_pos, n_neg = int((labels == 1).sum()), int((labels == 0).sum())
    got = f"got {n_pos} vehicle and {n_neg} non-vehicle crops"
    if min(n_pos, n_neg) < 1:
        raise DataError(f"training needs vehicle and non-vehicle crops, {got}")
    names = {"both": ("random", "sequence"), "none": ()}.get(split, (split,))
    if "random" in names and min(n_pos, n_neg) < MIN_RANDOM_SPLIT:
        raise DataError(f"the random split holds out a fifth of each class: it needs at least {MIN_RANDOM_SPLIT} "
                        f"crops of each, {got} (--split none trains without a held-out test)")
    if "sequence" in names:
        tr, te = sequence_split(groups, order, seed)
        parts = {"training": labels[tr], "test": labels[te]}
        short = [f"its {part} part has no {'vehicle' if c else 'non-vehicle'} crop"
                 for part, y in parts.items() for c in (1, 0) if not (y == c).any()]
        if short:
            raise DataError(f"the sequence split cuts every folder into 5 blocks in time order and holds out one "
                            f"block of each: {short[0]} ({got} in {len(np.unique(groups))} folder(s); each class "
                            f"needs a folder of at least 5 crops, or use --split random / none)")


def sequence_split(groups: np.ndarray, order: np.ndarray, seed: int,
                   n_blocks: int = 5) -> tuple[np.ndarray, np.ndarray]:
    """Leak-free split: each folder, in time order, is cut into ``n_blocks`` contiguous
    blocks and block ``seed % n_blocks`` of every folder is the test part."""
    test = np.zeros(len(groups), bool)
    k = seed % n_blocks
    for g in np.unique(groups):
        members = np.flatnonzero(groups == g)
        members = members[np.argsort(order[members], kind="stable")]
        blocks = np.array_split(members, n_blocks)
        test[blocks[k]] = True
    return np.flatnonzero(~test), np.flatnonzero(test)
