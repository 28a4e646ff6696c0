#!/usr/bin/env bash
# Compare main models on the figures of the augmentation study (issue 12 item 4, issue 14 item 9):
# for every MODEL.npz given, `fastdet eval --video` on test_small1 and test_video (F1 / AP /
# IDF1 / FP per frame), on test_small1 re-encoded with OpenCV's mp4v and MJPG writers and
# x264 CRF 18 (imageio-ffmpeg's binary; copies under $TMPDIR, never the repo), the same with
# --no-oncoming, and the camera-shift suite on variants original, cut_right12, cut_right25,
# mirror, x264, mp4v, mjpg (pooled rows; JSON per model in the work folder).
# Usage: bash tools/studies/augment_compare.sh WORK_DIR MODEL.npz [MODEL.npz ...]
set -euo pipefail
D=${FASTDET_DATA:-../shared/data}
W=$1; shift
mkdir -p "$W"
COPIES=$(mktemp -d "${TMPDIR:-/tmp}/fastdet_copies.XXXXXX")
trap 'rm -rf "$COPIES"' EXIT
python - "$D/videos/test_small1.mp4" "$COPIES" <<'PY'
import subprocess, sys
import cv2, imageio_ffmpeg
src, out = sys.argv[1], sys.argv[2]
cap = cv2.VideoCapture(src); frames = []
while True:
    ok, f = cap.read()
    if not ok:
        break
    frames.append(f)
h, w = frames[0].shape[:2]
for name, fourcc, ext in (("mp4v", "mp4v", "mp4"), ("mjpg", "MJPG", "avi")):
    wr = cv2.VideoWriter(f"{out}/test_small1.{name}.{ext}", cv2.VideoWriter_fourcc(*fourcc), 25, (w, h))
    for f in frames:
        wr.write(f)
    wr.release()
cmd = [imageio_ffmpeg.get_ffmpeg_exe(), "-loglevel", "error", "-y", "-f", "rawvideo", "-pix_fmt", "bgr24",
       "-s", f"{w}x{h}", "-r", "25", "-i", "-", "-c:v", "libx264", "-crf", "18", "-pix_fmt", "yuv420p",
       f"{out}/test_small1.x264.mp4"]
subprocess.run(cmd, input=b"".join(f.tobytes() for f in frames), check=True)
PY
one() {  # label gt video model [eval options]
  local label=$1 gt=$2 video=$3 model=$4; shift 4
  python -m fastdet eval --gt "$gt" --video "$video" --model "$model" --json "$@" | python -c "
import json, sys; r = json.load(sys.stdin)
print(f\"  $label F1 {r['f1']:.3f} AP {r['ap']:.3f} IDF1 {r['idf1']:.3f} FP/frame {r['fp_per_frame']:.3f}\")"
}
G=$D/annotations/test_small1.gt.txt
for M in "$@"; do
  name=$(basename "$M" .npz)
  echo "== $M"
  for extra in "" "--no-oncoming"; do
    [ -n "$extra" ] && echo "  -- main model only ($extra)"
    one test_small1 "$G" "$D/videos/test_small1.mp4" "$M" $extra
    one test_video "$D/annotations/test_video.gt.txt" "$D/videos/test_video.mp4" "$M" $extra
    one mp4v "$G" "$COPIES/test_small1.mp4v.mp4" "$M" $extra
    one mjpg "$G" "$COPIES/test_small1.mjpg.avi" "$M" $extra
    one x264 "$G" "$COPIES/test_small1.x264.mp4" "$M" $extra
  done
  python -m tools.studies.camera_shift --variants original,cut_right12,cut_right25,mirror,x264,mp4v,mjpg \
    --model "$M" --json "$W/camera_shift.$name.json" 2>/dev/null | grep -E "^\| (variant|[a-z0-9_]+ \| (test_small1|all)) "
done
