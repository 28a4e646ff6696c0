#!/usr/bin/env bash
# The bundled oncoming-traffic model (fastdet/models/oncoming.npz), from scratch (~4 minutes).
#
# A wide-window model (64x24 windows, rows 12..36 of the 64x64 crops) for cars half hidden
# behind the median barrier. It uses no frame of the annotated clips:
# - positives: the vehicle crops' rows 12..36, plus the three oncoming cars that
#   tools/test_images.gt.txt marks in the six test images (hand-annotated for fastdet),
#   40 jittered crops each (tools/scripts/gt_crops.py);
# - negatives: the non-vehicle crops' row bands, sub-windows of them at the wide search's
#   small scales (tools/scripts/zoom_negatives.py), and two rounds of hard negatives mined on the
#   left half of the test images outside every annotated box.
# Usage (from the repository root): bash tools/scripts/oncoming_model.sh [WORK_DIR] [OUT.npz] [MAIN.npz]
# MAIN.npz: the main model the mining rounds search beside the wide one (default: the bundled
# fastdet/models/default.npz; tools/scripts/rebuild_models.py passes the one it just built).
# ONCOMING_TRAIN_ARGS (environment): extra options of every `fastdet train` here, e.g.
# "--reencode 0.5" (they replace nothing: a later --C wins over the one below). Not
# --classifier: mine-negatives searches the wide model beside the bundled main model, and
# refuses one whose kind of score differs ("train both with the same --classifier").
# ONCOMING_ZOOM_ARGS (environment): extra options of zoom_negatives, e.g. "--limit 50" (the
# smoke test runs the whole script on a few crops that way).
# ONCOMING_MINE_ARGS (environment): extra options of both mine-negatives rounds, e.g.
# "--frames 2" (the smoke test mines the first two test images only: fewer hard negatives to fit).
set -euo pipefail
D=${FASTDET_DATA:-../shared/data}
W=${1:-/tmp/fastdet-oncoming}
OUT=${2:-fastdet/models/oncoming.npz}
MAIN=()
if [ -n "${3:-}" ]; then MAIN=(--model "$3"); fi
rm -rf "$W"
mkdir -p "$W"
T="--window-rows 12 36 --orientations 9 --C 0.01 --split sequence --no-progress ${ONCOMING_TRAIN_ARGS:-}"
IMG="$D/test_images/test%d.jpg"
G=tools/test_images.gt.txt
mine() {  # model out-dir
  python -m fastdet mine-negatives "$IMG" --gt "$G" --out "$2" --part wide --wide-model "$1" "${MAIN[@]}" \
    --threshold -0.5 --x-range 0 660 --y-range 380 520 --no-progress ${ONCOMING_MINE_ARGS:-}
}
negatives() {  # NEG: --negatives DIR for each DIR given that holds crops (a mining round may find none)
  NEG=()
  for d in "$@"; do
    if compgen -G "$d/*.png" > /dev/null; then NEG+=(--negatives "$d"); fi
  done
}
python -m tools.scripts.gt_crops "$IMG" "$G" "$W/pos" --height 24 --jitter 40
python -m tools.scripts.zoom_negatives "$W/zoom" ${ONCOMING_ZOOM_ARGS:-}
python -m fastdet train $T --positives "$W/pos" --out "$W/w0.npz"
mine "$W/w0.npz" "$W/neg0"
negatives "$W/neg0"
python -m fastdet train $T --positives "$W/pos" "${NEG[@]}" --out "$W/w1.npz"
mine "$W/w1.npz" "$W/neg1"
negatives "$W/neg0" "$W/neg1" "$W/zoom"
# OUT is the bundled model by default: train writes into the package only when told to
python -m fastdet train $T --positives "$W/pos" "${NEG[@]}" --out "$OUT" --into-package
