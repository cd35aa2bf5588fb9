#!/usr/bin/env bash
# The main job: world -> map -> vocab -> train (mpirun, 2 ranks) -> export -> localize -> eval for
# one world preset, ending with the results table.
#   jobs/pipeline.sh [PRESET] [OUT_DIR]
# Stages whose output exists are kept (rerun after a failure continues where it stopped); delete
# OUT_DIR to start over. LBOOST points at the lboost binary (default: build/train/lboost);
# LMB_RANKS sets the training ranks (default 2; 1 = one process without mpirun); LMB_WORLD_ARGS,
# LMB_TRAIN_ARGS, LMB_LOCALIZE_ARGS and LMB_EVAL_ARGS add or replace stage flags.
set -euo pipefail
preset=${1:-default}
out=${2:-out/$preset}
here=$(cd "$(dirname "$0")/.." && pwd)
lboost=${LBOOST:-$here/build/train/lboost}
threads=${LMB_THREADS:-$(nproc)}
ranks=${LMB_RANKS:-2}
if [ "$ranks" -gt 1 ]; then
  # OpenMPI refuses root without these, and more ranks than cores without oversubscription.
  export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_rmaps_base_oversubscribe=1
  export OMPI_MCA_btl_vader_single_copy_mechanism=none
  train_cmd=(mpirun -n "$ranks" "$lboost" train)
  train_threads=1  # per rank: each rank builds its own feature columns
else
  train_cmd=("$lboost" train)
fi
default_train_args="--rounds 1000 --top-k 1000"
mkdir -p "$out"

stage() { printf '\n== %s\n' "$*"; }
seconds() { date +%s.%N; }
t0=$(seconds)

if [ ! -d "$out/world" ]; then
  stage "world: rendering the '$preset' world"
  "$lboost" world --preset "$preset" --seed 1 --out "$out/world" --threads "$threads" ${LMB_WORLD_ARGS:-}
fi
if [ ! -f "$out/map.h5" ]; then
  stage "map: detection, guided matching, triangulation"
  "$lboost" map --collection "$out/world" --out "$out/map.h5" --threads "$threads"
fi
# shellcheck source=jobs/model_stages.sh
source "$here/jobs/model_stages.sh"
model_stages

stage "results ($out/report.json, plots in $out/plots)"
grep -v '^\[' "$out/results.txt"
printf '\nmain job done in %.0f s; outputs in %s\n' "$(echo "$(seconds) - $t0" | bc)" "$out"
