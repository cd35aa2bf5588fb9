#!/usr/bin/env bash
# The evaluation of a finished main-job output dir: `lboost eval` (LandmarkBoost and the baselines on
# the map's query frames) and the plots.
#   jobs/eval.sh OUT_DIR [extra lboost eval flags...]
# Reads OUT_DIR/{model.lbm,map.h5,vocab.lbv,run/} (the vocabulary exports a cross-fitted run's fold
# models for the pose calibration); writes OUT_DIR/report.json (fields: docs/report.md),
# OUT_DIR/report_keypoints.json (each query keypoint's rank of its true landmark, per method),
# OUT_DIR/results.txt (the results table) and OUT_DIR/plots/*.png (jobs/plots.py).
# LBOOST points at the lboost binary (default: build/train/lboost); plots need /usr/bin/python3
# with matplotlib (skipped with a message otherwise).
set -euo pipefail
out=${1:?usage: jobs/eval.sh OUT_DIR [lboost eval flags...]}
shift
here=$(cd "$(dirname "$0")/.." && pwd)
lboost=${LBOOST:-$here/build/train/lboost}
for f in model.lbm map.h5 vocab.lbv run/metrics.jsonl; do
  [ -e "$out/$f" ] || { echo "jobs/eval.sh: $out/$f missing (run jobs/pipeline.sh first)" >&2; exit 1; }
done
"$lboost" eval --model "$out/model.lbm" --map "$out/map.h5" --run "$out/run" --vocab "$out/vocab.lbv" \
  --report "$out/report.json" --keypoint-ranks "$out/report_keypoints.json" "$@" | tee "$out/results.txt"
if /usr/bin/python3 -c "import matplotlib" 2>/dev/null; then
  /usr/bin/python3 "$here/jobs/plots.py" --report "$out/report.json" --run "$out/run" --out "$out/plots"
else
  echo "jobs/eval.sh: /usr/bin/python3 has no matplotlib (Debian: python3-matplotlib); plots skipped" >&2
fi
