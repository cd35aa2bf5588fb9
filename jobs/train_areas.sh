#!/usr/bin/env bash
# Trains every area of an areas file (lboost areas; docs/areas.md) one after the other, each as its
# own resumable run OUT_DIR/area-ID on RANKS MPI ranks (jobs/train_local.sh: requeue and resume).
#   jobs/train_areas.sh RANKS AREAS_FILE OUT_DIR LBOOST_TRAIN_ARGS...
#   e.g. jobs/train_areas.sh 2 out/paper/areas.txt out/paper/areas --map out/paper/map.h5 \
#          --vocab out/paper/vocab.lbv --rounds 2000
# An area whose run finished with the same arguments (OUT_DIR/area-ID/done) is skipped, so the
# same command continues an interrupted job. A failed area does not stop the others: the script
# ends with status 1 naming them; AREAS="3 7" trains only those ids (rerun a failed area alone).
# Prints one progress line per area with the overall ETA (mean time of the areas trained so far).
# SIGTERM / SIGUSR1 / SIGINT: the running area checkpoints and the script exits 75; rerun it.
# LBOOST, MPIEXEC: as for jobs/train_local.sh.
set -uo pipefail
[ $# -ge 3 ] || { sed -n '2,13p' "$0"; exit 2; }
ranks=$1
areas_file=$2
out_dir=$3
shift 3
here=$(cd "$(dirname "$0")/.." && pwd)
[ -f "$areas_file" ] || { echo "train_areas: $areas_file: no such file (make it with lboost areas)" >&2; exit 2; }
num_areas=$(awk '$1 == "areas" { print $2; exit }' "$areas_file")
[[ "$num_areas" =~ ^[0-9]+$ ]] && [ "$num_areas" -ge 1 ] ||
  { echo "train_areas: $areas_file: no 'areas N' line (not an areas file of lboost areas)" >&2; exit 2; }
mkdir -p "$out_dir" || exit 2
ids=${AREAS:-$(seq 0 $((num_areas - 1)))}
for id in $ids; do
  [[ "$id" =~ ^[0-9]+$ ]] && [ "$id" -lt "$num_areas" ] ||
    { echo "train_areas: AREAS: '$id' is not an area id of $areas_file (0..$((num_areas - 1)))" >&2; exit 2; }
done
total=$(echo $ids | wc -w)

child=
stop=0
on_signal() {
  stop=1
  [ -n "$child" ] && kill -TERM "$child" 2> /dev/null  # train_local.sh asks its ranks to checkpoint
}
trap on_signal TERM INT USR1

start=$(date +%s)
trained=0
trained_seconds=0
done_count=0
failed=()
for id in $ids; do
  run_dir=$out_dir/area-$id
  signature="$areas_file:$id $*"
  if [ -f "$run_dir/done" ] && [ "$(cat "$run_dir/done")" = "$signature" ]; then
    done_count=$((done_count + 1))
    echo "train_areas: area $id ($done_count/$total): already trained ($run_dir), skipped"
    continue
  fi
  t0=$(date +%s)
  bash "$here/jobs/train_local.sh" "$ranks" "$@" --area "$areas_file:$id" --out "$run_dir" \
    > >(sed -u "s/^/[area $id] /") 2>&1 &
  child=$!
  status=0
  wait "$child" || status=$?
  while kill -0 "$child" 2> /dev/null; do
    status=0
    wait "$child" || status=$?
  done
  child=
  seconds=$(($(date +%s) - t0))
  if [ "$status" -eq 75 ] || [ "$stop" -eq 1 ]; then
    echo "train_areas: area $id checkpointed and stopped; rerun the same command to continue"
    exit 75
  fi
  done_count=$((done_count + 1))
  if [ "$status" -ne 0 ]; then
    failed+=("$id")
    echo "train_areas: area $id ($done_count/$total): FAILED with status $status after ${seconds} s (rerun alone: AREAS=$id)"
    continue
  fi
  printf '%s\n' "$signature" > "$run_dir/done"
  trained=$((trained + 1))
  trained_seconds=$((trained_seconds + seconds))
  left=$((total - done_count))
  eta=$((trained_seconds * left / trained))
  echo "train_areas: area $id ($done_count/$total): trained in ${seconds} s -> $run_dir/model.bin;" \
       "$left left, ETA $((eta / 60)) min $((eta % 60)) s (elapsed $(($(date +%s) - start)) s)"
done
if [ ${#failed[@]} -gt 0 ]; then
  echo "train_areas: ${#failed[@]} of $total areas failed: ${failed[*]} (rerun them: AREAS=\"${failed[*]}\")"
  exit 1
fi
echo "train_areas: all $total areas trained under $out_dir in $(($(date +%s) - start)) s"
