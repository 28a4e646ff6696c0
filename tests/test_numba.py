"""The first run speaks (issue 14, item 4): one notice before the kernels compile, the whole
wall time beside the fps, and a Numba cache that stays valid when the package is installed
where it cannot write (Numba then falls back to a user cache folder).

The read-only install is a real read-only bind mount of a copy of the package, made in a
user + mount namespace (``unshare -rm``): as root, file permissions alone would not stop
writes. One cold compile: marked slow.
"""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import cv2
import pytest

import fastdet
from tests.media import frames


def _unshare_works() -> bool:
    if shutil.which("unshare") is None:
        return False
    r = subprocess.run(["unshare", "-rm", "true"], capture_output=True, check=False)
    return r.returncode == 0


@pytest.mark.slow
@pytest.mark.skipif(not _unshare_works(), reason="needs user + mount namespaces (unshare -rm) for a read-only mount")
def test_read_only_install_caches_in_the_user_folder(tmp_path):
    site = tmp_path / "site"
    shutil.copytree(Path(fastdet.__file__).parent, site / "fastdet", copy_function=shutil.copy2,
                    ignore=shutil.ignore_patterns("__pycache__"))
    img = tmp_path / "in.jpg"
    cv2.imwrite(str(img), next(frames(1, 640, 360)))
    cache = tmp_path / "cache"
    # run the copy, not the checkout an editable install points at (its finder comes first)
    launcher = tmp_path / "launch.py"
    launcher.write_text(
        "import runpy, sys\n"
        "sys.meta_path[:] = [f for f in sys.meta_path if 'editable' not in getattr(f, '__module__', '')]\n"
        "import fastdet\n"
        f"assert fastdet.__file__.startswith({str(site)!r}), fastdet.__file__\n"
        "sys.argv[0] = 'fastdet'\n"
        "runpy.run_module('fastdet', run_name='__main__')\n")
    script = (f"mount --bind {site} {site} && mount -o remount,bind,ro {site} {site} && "
              f"touch {site}/fastdet/probe 2>/dev/null && echo WRITABLE; "
              f"for i in 1 2; do PYTHONPATH={site} PYTHONDONTWRITEBYTECODE=1 XDG_CACHE_HOME={cache} "
              f"{sys.executable} {launcher} image {img} -o {tmp_path}/out$i.jpg; echo rc=$?; done")
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    r = subprocess.run(["unshare", "-rm", "sh", "-c", script], capture_output=True, text=True, timeout=600,
                       env=env, check=False)
    out, err = r.stdout, r.stderr
    assert "WRITABLE" not in out, "the mount is not read-only"
    assert out.count("rc=0") == 2, out + err
    # first run: one notice, then the kernels land in the user cache folder ...
    assert err.count("compiling the detection kernels") == 1, err
    assert err.splitlines()[0].startswith("fastdet image: compiling"), err
    assert list(cache.rglob("*.nbi")) and list(cache.rglob("*.nbc"))
    assert not list((site / "fastdet").rglob("*.nbi"))
    # ... and the second run loads them: no notice (it is printed only for kernels not cached)
    assert (tmp_path / "out1.jpg").exists() and (tmp_path / "out2.jpg").exists()


def test_summary_reports_the_whole_wall_time(tmp_path):
    """``video`` prints the frame loop's fps and the whole run's wall time (start-up,
    loading and on a first run compiling included), which is the larger."""
    from tests.media import write_video

    clip = write_video(tmp_path / "c.mp4", 5)
    r = subprocess.run([sys.executable, "-m", "fastdet", "video", str(clip), "--boxes", str(tmp_path / "b.txt"),
                        "--no-progress"], capture_output=True, text=True, timeout=300, check=False)
    assert r.returncode == 0, r.stderr
    import re

    m = re.search(r"5 frames in ([\d.]+) s, [\d.]+ fps \(([\d.]+) s in all, start-up included\)", r.stdout)
    assert m, r.stdout
    assert float(m.group(2)) >= float(m.group(1))
