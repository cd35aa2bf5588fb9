#!/usr/bin/env bash
# A real video end to end: a 7-Scenes-style recording -> collection -> map -> vocab -> train ->
# export -> localize -> eval (docs/your_own_images.md "Video with poses: 7-Scenes and 12-Scenes").
#   jobs/7scenes.sh DATA_DIR OUT_DIR    e.g. jobs/7scenes.sh ../shared/data/7scenes_redkitchen out/7scenes_redkitchen
# DATA_DIR holds the frames (rgb/frame-NNNNNN.color.jpg with pose/frame-NNNNNN.pose.txt, or the
# frames with their poses beside them), camera-intrinsics.txt and gravity-direction.txt (read in
# place, never copied). The split is the recording's first half for the map and its second half,
# another part of the path, as queries: LMB_7SCENES_MAP (default 0-499) and LMB_7SCENES_QUERY
# (default 500-999), frame numbers or sequence folders as `lboost import 7scenes` takes them, every
# LMB_7SCENES_STRIDE-th frame of each (default 1, all: about 20 min on 2 cores; 3 takes a third).
# LMB_7SCENES_IMPORT_ARGS adds import flags, e.g. "--focal 525" for the camera, "--gravity-up 0 -1
# 0" without a gravity-direction.txt. The vocabulary is trained on unrelated images: a rendered
# world (seed 1001), as in jobs/pipeline.sh, so no image of the recording shapes the visual words.
# Stages whose output exists are kept; delete OUT_DIR to start over. LBOOST points at the lboost
# binary (default: build/train/lboost); LMB_TRAIN_ARGS (default --rounds 600 --top-k 1000),
# LMB_LOCALIZE_ARGS, LMB_EVAL_ARGS as in jobs/pipeline.sh; LMB_MAP_ARGS adds `lboost map` flags,
# e.g. "--refine-focal on" (the shipped 585 px focal length fits these frames badly: the map's
# focal check says so and refines it, docs/real_data.md "Wrong intrinsics"). The map stage also writes
# OUT_DIR/map_report.json. report.json carries the 7-Scenes
# figures beside the 20 cm / 5 deg ones: pose_recall_5cm_5deg and the median errors over all query
# frames (docs/report.md).
set -euo pipefail
data=${1:?usage: jobs/7scenes.sh DATA_DIR OUT_DIR}
out=${2:?usage: jobs/7scenes.sh DATA_DIR OUT_DIR}
here=$(cd "$(dirname "$0")/.." && pwd)
lboost=${LBOOST:-$here/build/train/lboost}
threads=${LMB_THREADS:-$(nproc)}
map_frames=${LMB_7SCENES_MAP:-0-499}
query_frames=${LMB_7SCENES_QUERY:-500-999}
stride=${LMB_7SCENES_STRIDE:-1}
[ -d "$data" ] || { echo "jobs/7scenes.sh: $data is not a folder" >&2; exit 1; }
data=$(cd "$data" && pwd)
mkdir -p "$out"

stage() { printf '\n== %s\n' "$*"; }
seconds() { date +%s.%N; }
t0=$(seconds)

if [ ! -d "$out/collection/sparse" ]; then
  stage "import: map frames $map_frames, query frames $query_frames, stride $stride"
  # shellcheck disable=SC2086
  "$lboost" import 7scenes --data "$data" --out "$out/collection" --map-frames "$map_frames" \
    --query-frames "$query_frames" --stride "$stride" ${LMB_7SCENES_IMPORT_ARGS:-}
fi
if [ ! -f "$out/map.h5" ]; then
  [ -f "$out/collection/gravity.txt" ] || {
    echo "jobs/7scenes.sh: $out/collection has no gravity.txt (no gravity-direction.txt in $data): set" \
      "LMB_7SCENES_IMPORT_ARGS=\"--gravity-up X Y Z\" and delete $out/collection" >&2
    exit 1
  }
  # A room: depths beyond 6 m are outside it; the poses are in metres.
  stage "map: detection, guided matching, triangulation (gravity.txt per image)"
  # shellcheck disable=SC2086
  "$lboost" map --collection "$out/collection" --out "$out/map.h5" --gravity "$out/collection/gravity.txt" \
    --max-depth 6 --threads "$threads" --report "$out/map_report.json" ${LMB_MAP_ARGS:-}
fi
default_train_args="--rounds 600 --top-k 1000"
# shellcheck source=jobs/model_stages.sh
source "$here/jobs/model_stages.sh"
model_stages
printf '\n7scenes job done in %.0f s; outputs in %s\n' "$(echo "$(seconds) - $t0" | bc)" "$out"
