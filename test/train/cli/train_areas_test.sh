#!/usr/bin/env bash
# jobs/train_areas.sh on the tiny rendered world (docs/areas.md): every area trains into its own
# run folder with a progress line each; a failed area does not stop the others and is rerun alone;
# a stopped job (SIGTERM) exits 75 and the same command resumes it, giving the model of an
# uninterrupted run byte for byte; finished areas are skipped.
#   train_areas_test.sh LBOOST TINY_WORLD_DIR WORK_DIR
set -uo pipefail
lboost=$1
tiny=$2
work=$3
here=$(cd "$(dirname "$0")/../../.." && pwd)
export LBOOST=$lboost
rm -rf "$work"
mkdir -p "$work"
fail() {
  echo "train_areas_test: FAIL: $*" >&2
  exit 1
}
"$lboost" vocab --words 16 --max-descriptors 20000 --images "$tiny/collection/images" --seed 7 \
  --out "$work/vocab.lbv" > /dev/null || fail "vocab"
"$lboost" areas --map "$tiny/map.h5" --out "$work/areas.txt" --min-observations 3 --max-classes 400 --overlap 0.2 \
  > "$work/areas.log" || fail "areas: $(cat "$work/areas.log")"
num_areas=$(awk '$1 == "areas" { print $2; exit }' "$work/areas.txt")
[ "$num_areas" -ge 3 ] || fail "expected >= 3 areas, got $num_areas"
args=(--map "$tiny/map.h5" --vocab "$work/vocab.lbv" --rounds 6 --dims-per-round 64 --checkpoint-interval 2)

# 1. Areas 0 and 2, with area 2's run folder blocked by a file: area 0 trains, area 2 fails, the
#    script says so and exits 1.
mkdir -p "$work/out"
touch "$work/out/area-2"
AREAS="0 2" bash "$here/jobs/train_areas.sh" 1 "$work/areas.txt" "$work/out" "${args[@]}" > "$work/run1.log" 2>&1
status=$?
[ "$status" -eq 1 ] || fail "run 1: status $status, expected 1: $(tail -5 "$work/run1.log")"
grep -q "train_areas: area 0 (1/2): trained in .* s -> .*area-0/model.bin; 1 left, ETA" "$work/run1.log" ||
  fail "run 1: no progress line for area 0: $(cat "$work/run1.log")"
grep -q "train_areas: area 2 (2/2): FAILED with status 1" "$work/run1.log" || fail "run 1: area 2 not reported"
grep -q "train_areas: 1 of 2 areas failed: 2" "$work/run1.log" || fail "run 1: no summary of the failure"
[ -f "$work/out/area-0/model.bin" ] || fail "run 1: no model for area 0"

# 2. The failed area alone, once unblocked; then the finished ones are skipped.
rm "$work/out/area-2"
AREAS=2 bash "$here/jobs/train_areas.sh" 1 "$work/areas.txt" "$work/out" "${args[@]}" > "$work/run2.log" 2>&1 ||
  fail "run 2: $(tail -5 "$work/run2.log")"
[ -f "$work/out/area-2/model.bin" ] || fail "run 2: no model for area 2"
AREAS="0 2" bash "$here/jobs/train_areas.sh" 1 "$work/areas.txt" "$work/out" "${args[@]}" > "$work/run3.log" 2>&1 ||
  fail "run 3: $(tail -5 "$work/run3.log")"
[ "$(grep -c "already trained" "$work/run3.log")" -eq 2 ] || fail "run 3: finished areas not skipped: $(cat "$work/run3.log")"

# 3. Area 1 stopped by SIGTERM while it trains (2 ranks), then resumed by the same command: its
#    model equals an uninterrupted one-process run's.
long=(--map "$tiny/map.h5" --vocab "$work/vocab.lbv" --rounds 400 --dims-per-round 64 --checkpoint-interval 50)
"$lboost" train "${long[@]}" --area "$work/areas.txt:1" --out "$work/reference" > "$work/reference.log" 2>&1 ||
  fail "reference run: $(tail -3 "$work/reference.log")"
AREAS=1 bash "$here/jobs/train_areas.sh" 2 "$work/areas.txt" "$work/stopped" "${long[@]}" > "$work/run4.log" 2>&1 &
pid=$!
for _ in $(seq 600); do
  [ -f "$work/stopped/area-1/metrics.jsonl" ] && [ "$(wc -l < "$work/stopped/area-1/metrics.jsonl")" -ge 3 ] && break
  sleep 0.1
done
kill -TERM "$pid"
wait "$pid"
status=$?
[ "$status" -eq 75 ] || fail "run 4: status $status after SIGTERM, expected 75: $(tail -5 "$work/run4.log")"
grep -q "area 1 checkpointed and stopped" "$work/run4.log" || fail "run 4: no stop line: $(tail -5 "$work/run4.log")"
[ ! -f "$work/stopped/area-1/done" ] || fail "run 4: a stopped area is marked done"
AREAS=1 bash "$here/jobs/train_areas.sh" 2 "$work/areas.txt" "$work/stopped" "${long[@]}" > "$work/run5.log" 2>&1 ||
  fail "run 5: $(tail -5 "$work/run5.log")"
grep -q "resumed from" "$work/run5.log" || fail "run 5 did not resume: $(head -20 "$work/run5.log")"
cmp -s "$work/stopped/area-1/model.bin" "$work/reference/model.bin" ||
  fail "the stopped and resumed area's model differs from the uninterrupted run's"
echo "train_areas_test: OK"
rm -rf "$work"
