"""The tracking picture of docs/tracking.md: one frame of a clip with each vehicle's id and trail.

    python -m tools.studies.tracking_picture [--video ../shared/data/videos/test_small1.mp4]
        [--frame 86] [--crop 0,360,1100,520] [--out docs/tracking.jpg]

Runs the default video pipeline (tracker on) up to ``--frame`` (1-based), draws that
frame's tracked boxes with their trails as ``fastdet video -o`` does, crops it
(``x1,y1,x2,y2``) and writes a JPEG (under a temporary name, then renamed).
"""
from __future__ import annotations

import argparse
import os

import cv2

from fastdet.data import data_dir
from fastdet.io import draw
from fastdet.io.atomic import write_bytes
from fastdet.video import iter_video_detections


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--video", default=os.path.join(data_dir(), "videos", "test_small1.mp4"))
    p.add_argument("--frame", type=int, default=86)
    p.add_argument("--crop", default="0,360,1100,520", help="x1,y1,x2,y2 of the picture kept")
    p.add_argument("--out", default="docs/tracking.jpg")
    args = p.parse_args()
    x1, y1, x2, y2 = (int(v) for v in args.crop.split(","))
    trails = draw.Trails()
    cap = cv2.VideoCapture(args.video)
    try:
        for fno, dets in iter_video_detections(args.video, frames=args.frame, progress=False):
            ok, frame = cap.read()
            if not ok:
                raise SystemExit(f"{args.video}: frame {fno} does not decode")
            trails.update(dets)
        draw.draw_tracks(frame, dets, trails)
    finally:
        cap.release()
    ok, buf = cv2.imencode(".jpg", frame[y1:y2, x1:x2], [cv2.IMWRITE_JPEG_QUALITY, 85])
    write_bytes(args.out, buf.tobytes())
    print(f"wrote {args.out}: frame {args.frame}, ids {dets.ids.tolist()}")


if __name__ == "__main__":
    main()
