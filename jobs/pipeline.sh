#!/usr/bin/env bash
# The main job: world -> map -> vocab -> train -> export -> localize for one world preset.
#   jobs/pipeline.sh [PRESET] [OUT_DIR]
# Stages whose output exists are kept (rerun after a failure continues where it stopped); delete
# OUT_DIR to start over. LBOOST points at the lboost binary (default: build/train/lboost).
set -euo pipefail
preset=${1:-default}
out=${2:-out/$preset}
here=$(cd "$(dirname "$0")/.." && pwd)
lboost=${LBOOST:-$here/build/train/lboost}
threads=${LMB_THREADS:-$(nproc)}
mkdir -p "$out"

stage() { printf '\n== %s\n' "$*"; }
seconds() { date +%s.%N; }
t0=$(seconds)

if [ ! -d "$out/world" ]; then
  stage "world: rendering the '$preset' world"
  "$lboost" world --preset "$preset" --seed 1 --out "$out/world" --threads "$threads"
fi
if [ ! -d "$out/vocab_world" ]; then
  # The vocabulary is trained on images that are not the map's: another seed of the world.
  stage "vocab images: an unrelated world (seed 1001)"
  "$lboost" world --preset tiny --seed 1001 --out "$out/vocab_world" --threads "$threads"
fi
if [ ! -f "$out/map.h5" ]; then
  stage "map: detection, guided matching, triangulation"
  "$lboost" map --collection "$out/world" --out "$out/map.h5" --threads "$threads"
fi
if [ ! -f "$out/vocab.lbv" ]; then
  stage "vocab: 16 binary words by k-majority"
  "$lboost" vocab --images "$out/vocab_world/images" --out "$out/vocab.lbv" --words 16 --seed 7
fi
stage "inspect: the map and its descriptor aliasing"
"$lboost" inspect "$out/map.h5" --threads "$threads" | tee "$out/inspect.txt"

if [ ! -f "$out/run/model.bin" ]; then
  stage "train: shared-stump classifier"
  "$lboost" train --map "$out/map.h5" --vocab "$out/vocab.lbv" --out "$out/run" \
    --threads "$threads" ${LMB_TRAIN_ARGS:---rounds 300}
fi
if [ ! -f "$out/model.lbm" ]; then
  stage "export: model.lbm"
  "$lboost" export --run "$out/run" --map "$out/map.h5" --vocab "$out/vocab.lbv" --out "$out/model.lbm"
fi
stage "localize: the query frames"
# Until the classifier's background margin is calibrated (see README "Status"), the main job keeps
# every keypoint's best class and lets RANSAC sort the matches with the best margins.
"$lboost" localize --model "$out/model.lbm" --map "$out/map.h5" --out "$out/poses.json" \
  --threads "$threads" ${LMB_LOCALIZE_ARGS:---min-margin=-1e300 --max-correspondences 100 --ransac-iterations 2000}

printf '\nmain job done in %.0f s; outputs in %s\n' "$(echo "$(seconds) - $t0" | bc)" "$out"
