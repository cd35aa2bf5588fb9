#!/usr/bin/env bash
# A real sequence end to end: a TUM RGB-D sequence -> collection -> map -> vocab -> train -> export
# -> localize -> eval (docs/real_data.md "End to end").
#   jobs/tum.sh DATA_DIR OUT_DIR        e.g. jobs/tum.sh ../shared/data/tum_fr1_rpy out/tum_rpy
# DATA_DIR holds rgb.txt, rgb/, groundtruth.txt, accelerometer.txt (read in place, never copied).
# To keep it to a few minutes on 2 cores the sequence is thinned first: every LMB_TUM_STRIDE-th
# image of rgb.txt (default 3) is kept, then split LMB_TUM_SPLIT (default every:3: frames 0, 3, 6..
# of the thinned list map, the others are queries). OUT_DIR/seq is the thinned view of DATA_DIR
# (its own rgb.txt, links to the rest). The vocabulary is trained on unrelated images: a rendered
# world (seed 1001), as in jobs/pipeline.sh, so no image of the sequence shapes the visual words.
# Stages whose output exists are kept; delete OUT_DIR to start over. LBOOST points at the lboost
# binary (default: build/train/lboost); LMB_TRAIN_ARGS (default --rounds 600 --top-k 1000, about
# 3 min of training here), LMB_LOCALIZE_ARGS, LMB_EVAL_ARGS as in jobs/pipeline.sh; LMB_MAP_ARGS
# adds `lboost map` flags (e.g. "--refine-focal off"). The map stage also writes OUT_DIR/map_report.json.
set -euo pipefail
data=${1:?usage: jobs/tum.sh DATA_DIR OUT_DIR}
out=${2:?usage: jobs/tum.sh DATA_DIR OUT_DIR}
here=$(cd "$(dirname "$0")/.." && pwd)
lboost=${LBOOST:-$here/build/train/lboost}
threads=${LMB_THREADS:-$(nproc)}
stride=${LMB_TUM_STRIDE:-3}
split=${LMB_TUM_SPLIT:-every:3}
for f in rgb.txt groundtruth.txt accelerometer.txt rgb; do
  [ -e "$data/$f" ] || { echo "jobs/tum.sh: $data/$f missing (not a TUM RGB-D sequence folder)" >&2; exit 1; }
done
data=$(cd "$data" && pwd)
mkdir -p "$out"

stage() { printf '\n== %s\n' "$*"; }
seconds() { date +%s.%N; }
t0=$(seconds)

if [ ! -f "$out/seq/rgb.txt" ]; then
  stage "thin: every ${stride}-th image of $data/rgb.txt"
  mkdir -p "$out/seq"
  for f in groundtruth.txt accelerometer.txt rgb; do ln -sfn "$data/$f" "$out/seq/$f"; done
  awk -v s="$stride" '/^#/ { print; next } { if (n++ % s == 0) print }' "$data/rgb.txt" > "$out/seq/rgb.txt.tmp"
  mv "$out/seq/rgb.txt.tmp" "$out/seq/rgb.txt"
fi
if [ ! -d "$out/collection/sparse" ]; then
  stage "import: split $split, gravity from the accelerometer"
  "$lboost" import tum --data "$out/seq" --out "$out/collection" --split "$split" --gravity accelerometer
fi
if [ ! -f "$out/map.h5" ]; then
  # Depths beyond 6 m are outside this office; the mocap world is in metres.
  stage "map: detection, guided matching, triangulation (gravity.txt per image)"
  # shellcheck disable=SC2086
  "$lboost" map --collection "$out/collection" --out "$out/map.h5" --gravity "$out/collection/gravity.txt" \
    --max-depth 6 --threads "$threads" --report "$out/map_report.json" ${LMB_MAP_ARGS:-}
fi
default_train_args="--rounds 600 --top-k 1000"
# shellcheck source=jobs/model_stages.sh
source "$here/jobs/model_stages.sh"
model_stages
printf '\ntum job done in %.0f s; outputs in %s\n' "$(echo "$(seconds) - $t0" | bc)" "$out"
