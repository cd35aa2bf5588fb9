#!/usr/bin/env bash
# The visual-word sweep (the paper's Table II): context-only classifiers (F_m drawn from the
# context dims only, [boost] candidate_dims = regions x words: no descriptor bits) for 4 ... 128
# visual words, precision@1 and MRR of the map's query keypoints (`lboost eval --methods
# landmarkboost`).
#   jobs/vocab_sweep.sh [OUT_DIR] [SWEEP_DIR]
# OUT_DIR: a main-job output (default out/default: map.h5 and vocab_world/ of jobs/pipeline.sh);
# SWEEP_DIR (default OUT_DIR/vocab_sweep): per word count w<N>/{vocab.lbv,config.toml,run/,
# model.lbm,report.json}, then table.md (jobs/vocab_table.py). Settings from the environment:
# WORDS (default "4 8 16 32 64 128"), TOP_K (1000: the classes of the main job's model, the map's
# best landmarks), ROUNDS (1000, as the main job), REGIONS (1000), DIMS_PER_ROUND (500),
# LMB_THREADS (nproc), AUGMENT (0: augmented copies of every training sample, [augment] copies; the
# noise is measured on the map). Word counts whose report exists are kept; delete SWEEP_DIR to start over.
set -euo pipefail
out=${1:-out/default}
sweep=${2:-$out/vocab_sweep}
here=$(cd "$(dirname "$0")/.." && pwd)
lboost=${LBOOST:-$here/build/train/lboost}
threads=${LMB_THREADS:-$(nproc)}
words_list=${WORDS:-4 8 16 32 64 128}
top_k=${TOP_K:-1000}
rounds=${ROUNDS:-1000}
regions=${REGIONS:-1000}
dims_per_round=${DIMS_PER_ROUND:-500}
augment=${AUGMENT:-0}
for f in map.h5 vocab_world/images; do
  [ -e "$out/$f" ] || { echo "jobs/vocab_sweep.sh: $out/$f missing (run jobs/pipeline.sh first)" >&2; exit 1; }
done
mkdir -p "$sweep"
t0=$(date +%s)
for w in $words_list; do
  d=$sweep/w$w
  [ -f "$d/report.json" ] && continue
  mkdir -p "$d"
  printf '\n== %d visual words\n' "$w"
  "$lboost" vocab --images "$out/vocab_world/images" --out "$d/vocab.lbv" --words "$w" --seed 7
  cat > "$d/config.toml" <<TOML
[boost]
num_rounds = $rounds
dims_per_round = $dims_per_round
candidate_dims = $((regions * w))
[regions]
num_regions = $regions
[training_set]
top_k_landmarks = $top_k
TOML
  if [ "$augment" -gt 0 ]; then
    printf '[augment]\ncopies = %d\n' "$augment" >> "$d/config.toml"
  fi
  rm -rf "$d/run"
  "$lboost" train --map "$out/map.h5" --vocab "$d/vocab.lbv" --out "$d/run" --config "$d/config.toml" \
    --threads "$threads"
  # --fusion off: the descriptor-distance term would bring the descriptor back in.
  "$lboost" export --run "$d/run" --map "$out/map.h5" --vocab "$d/vocab.lbv" --out "$d/model.lbm" --fusion off
  "$lboost" eval --model "$d/model.lbm" --map "$out/map.h5" --run "$d/run" --vocab "$d/vocab.lbv" --methods landmarkboost \
    --report "$d/report.json"
done
/usr/bin/python3 "$here/jobs/vocab_table.py" "$sweep" | tee "$sweep/table.md"
echo "vocab sweep done in $(( $(date +%s) - t0 )) s: $sweep/table.md"
