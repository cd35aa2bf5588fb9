#!/usr/bin/env bash
# A main job's map split into areas, end to end (docs/areas.md): areas -> train every area (MPI
# ranks, resumable) -> export each -> bundle with its pose and walk calibrations -> eval of the
# bundle's modes beside the single model.
#   jobs/areas.sh OUT_DIR [AREAS_DIR]
# OUT_DIR is a main-job folder (jobs/pipeline.sh, jobs/tum.sh, jobs/7scenes.sh) holding map.h5 and
# vocab.lbv; its model.lbm, when there, is evaluated on the same frames in the same run. AREAS_DIR
# (default OUT_DIR/areas) gets areas.txt, train/area-ID, bundle/area-ID.lbm, bundle/bundle.txt and
# eval.json. Stages whose output exists are kept, so the same command continues after a failure or
# a stop. LBOOST points at the lboost binary (default: build/train/lboost); LMB_RANKS sets the
# training ranks (default 2); LMB_AREAS_ARGS, LMB_TRAIN_ARGS, LMB_EXPORT_ARGS and LMB_EVAL_ARGS
# replace the stages' flags (defaults below).
set -euo pipefail
[ $# -ge 1 ] || { sed -n '2,12p' "$0"; exit 2; }
out=$1
areas_dir=${2:-$out/areas}
here=$(cd "$(dirname "$0")/.." && pwd)
lboost=${LBOOST:-$here/build/train/lboost}
ranks=${LMB_RANKS:-2}
for f in map.h5 vocab.lbv; do
  [ -f "$out/$f" ] || { echo "areas: $out/$f: no such file (run the main job into $out first)" >&2; exit 2; }
done
read -r -a areas_args <<< "${LMB_AREAS_ARGS:---max-classes 7500 --prior-noise 5}"
read -r -a train_args <<< "${LMB_TRAIN_ARGS:---rounds 300 --threads 1}"
read -r -a export_args <<< "${LMB_EXPORT_ARGS:---max-exemplars 4}"
read -r -a eval_args <<< "${LMB_EVAL_ARGS:---prior-noise 5 --track 1 --track-prior-noise 5}"
export LBOOST=$lboost
# OpenMPI refuses root without these, and more ranks than cores without oversubscription.
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_rmaps_base_oversubscribe=1
export OMPI_MCA_btl_vader_single_copy_mechanism=none

stage() { printf '\n== %s\n' "$*"; }
mkdir -p "$areas_dir/bundle"
if [ ! -f "$areas_dir/areas.txt" ]; then
  stage "areas: the map split into areas (lboost areas ${areas_args[*]})"
  "$lboost" areas --map "$out/map.h5" --out "$areas_dir/areas.txt" "${areas_args[@]}"
fi
num_areas=$(awk '$1 == "areas" { print $2; exit }' "$areas_dir/areas.txt")

stage "train: $num_areas areas on $ranks ranks (${train_args[*]})"
bash "$here/jobs/train_areas.sh" "$ranks" "$areas_dir/areas.txt" "$areas_dir/train" \
  --map "$out/map.h5" --vocab "$out/vocab.lbv" "${train_args[@]}"

stage "export: every area's model (${export_args[*]})"
for id in $(seq 0 $((num_areas - 1))); do
  model=$areas_dir/bundle/area-$id.lbm
  [ -f "$model" ] && continue
  "$lboost" export --run "$areas_dir/train/area-$id" --map "$out/map.h5" --vocab "$out/vocab.lbv" \
    --out "$model" "${export_args[@]}" > "$areas_dir/bundle/area-$id.export.log" 2>&1 ||
    { echo "areas: export of area $id failed: $(tail -3 "$areas_dir/bundle/area-$id.export.log")" >&2; exit 1; }
  echo "export: area $id -> $model"
done

if [ ! -f "$areas_dir/bundle/bundle.txt" ]; then
  stage "bundle: the index, its pose and walk calibrations on the map's held-out frames"
  "$lboost" bundle --areas "$areas_dir/areas.txt" --models "$areas_dir/bundle" --map "$out/map.h5"
fi

single=()
[ -f "$out/model.lbm" ] && single=(--model "$out/model.lbm")
stage "eval: the bundle's modes (${eval_args[*]})${single:+ beside the single model}"
"$lboost" eval --bundle "$areas_dir/bundle/bundle.txt" --map "$out/map.h5" "${single[@]}" \
  --report "$areas_dir/eval.json" "${eval_args[@]}"
