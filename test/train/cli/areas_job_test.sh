#!/usr/bin/env bash
# jobs/areas.sh on the tiny rendered world (docs/areas.md): a main-job folder split into areas,
# every area trained, exported and bundled with its calibrations, and the bundle's modes evaluated
# beside the single model; the same command again keeps every stage's output (nothing retrained,
# re-exported or re-indexed) and evaluates again; a folder without a vocabulary is refused with one
# line.
#   areas_job_test.sh LBOOST TINY_WORLD_DIR WORK_DIR
set -uo pipefail
lboost=$1
tiny=$2
work=$3
here=$(cd "$(dirname "$0")/../../.." && pwd)
export LBOOST=$lboost LMB_RANKS=1
rm -rf "$work"
mkdir -p "$work/out"
fail() {
  echo "areas_job_test: FAIL: $*" >&2
  exit 1
}
ln -s "$tiny/map.h5" "$work/out/map.h5"
"$lboost" vocab --words 16 --max-descriptors 20000 --images "$tiny/collection/images" --seed 7 \
  --out "$work/out/vocab.lbv" > /dev/null || fail "vocab"

# A folder without its vocabulary: one line, status 2, nothing made.
mkdir -p "$work/bare"
ln -s "$tiny/map.h5" "$work/bare/map.h5"
bash "$here/jobs/areas.sh" "$work/bare" > "$work/bare.log" 2>&1
status=$?
[ "$status" -eq 2 ] || fail "a folder without vocab.lbv: status $status, expected 2"
grep -q "areas: $work/bare/vocab.lbv: no such file" "$work/bare.log" || fail "no refusal line: $(cat "$work/bare.log")"
[ ! -e "$work/bare/areas" ] || fail "a refused job made $work/bare/areas"

# The main job's single model: a few rounds on the same map and vocabulary, evaluated beside the bundle.
export LMB_AREAS_ARGS="--min-observations 3 --overlap 0.2 --max-classes 400"
export LMB_TRAIN_ARGS="--rounds 6 --dims-per-round 64"
export LMB_EVAL_ARGS="--prior-noise 5 --track 1 --ransac-sweep-seeds 1"
"$lboost" train --map "$work/out/map.h5" --vocab "$work/out/vocab.lbv" --out "$work/single" --rounds 6 \
  --dims-per-round 64 --top-k 200 > "$work/single.log" 2>&1 || fail "single model: $(tail -3 "$work/single.log")"
"$lboost" export --run "$work/single" --map "$work/out/map.h5" --vocab "$work/out/vocab.lbv" \
  --out "$work/out/model.lbm" > "$work/single_export.log" 2>&1 || fail "export: $(tail -3 "$work/single_export.log")"

bash "$here/jobs/areas.sh" "$work/out" > "$work/run1.log" 2>&1 || fail "run 1: $(tail -20 "$work/run1.log")"
a=$work/out/areas
num_areas=$(awk '$1 == "areas" { print $2; exit }' "$a/areas.txt")
[ "$num_areas" -ge 3 ] || fail "expected >= 3 areas, got $num_areas"
for id in $(seq 0 $((num_areas - 1))); do
  [ -f "$a/train/area-$id/done" ] || fail "area $id not trained"
  [ -f "$a/bundle/area-$id.lbm" ] || fail "area $id not exported"
done
grep -q "^walk_calibration " "$a/bundle/bundle.txt" || fail "the bundle has no walk calibration: $(cat "$a/bundle/bundle.txt")"
python3 - "$a/eval.json" "$num_areas" << 'EOF' || fail "eval.json: see above"
import json, sys
report = json.load(open(sys.argv[1]))
names = [m["mode"] for m in report["modes"]]
assert names == ["prior 5 m", "tracking 1 m", "single model"], names
assert len(report["areas"]) == int(sys.argv[2]), len(report["areas"])
assert "walk" in report["modes"][1], report["modes"][1].keys()
EOF

# The same command again: every stage's output kept, the eval run again.
cp "$a/bundle/bundle.txt" "$work/bundle_before.txt"
touch -d '2000-01-01' "$a/bundle/area-0.lbm" "$a/bundle/bundle.txt"
bash "$here/jobs/areas.sh" "$work/out" > "$work/run2.log" 2>&1 || fail "run 2: $(tail -20 "$work/run2.log")"
[ "$(grep -c "already trained" "$work/run2.log")" -eq "$num_areas" ] || fail "run 2 retrained: $(cat "$work/run2.log")"
! grep -q "^export: area" "$work/run2.log" || fail "run 2 re-exported: $(cat "$work/run2.log")"
! grep -q "^== bundle" "$work/run2.log" || fail "run 2 re-indexed: $(cat "$work/run2.log")"
for f in area-0.lbm bundle.txt; do
  [ "$(date -r "$a/bundle/$f" +%Y)" = 2000 ] || fail "run 2 rewrote $f"
done
cmp -s "$a/bundle/bundle.txt" "$work/bundle_before.txt" || fail "run 2 changed bundle.txt"
grep -q "^== eval" "$work/run2.log" || fail "run 2 did not evaluate"
echo "areas_job_test: OK"
rm -rf "$work"
