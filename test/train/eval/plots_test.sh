#!/bin/sh
# Runs jobs/plots.py on a small fake report and metrics.jsonl and checks that every PNG is written
# (the pose-recall sweep plot included).
#   plots_test.sh PLOTS_PY SOURCE_DIR OUT_DIR        (exit 77 = skipped: no matplotlib)
set -eu
plots=$1
out=$3
py=/usr/bin/python3
if ! "$py" -c "import matplotlib" 2>/dev/null; then
  echo "SKIP: $py has no matplotlib (Debian: python3-matplotlib)"
  exit 77
fi
rm -rf "$out"
mkdir -p "$out/run" "$out/plots"
"$py" - "$out" <<'PY'
import json, math, sys
out = sys.argv[1]
def method(p1, mrr, slope, auc_scale, ms):
    fppi = [0.0] + [(1 - p1) * n * slope for n in range(1, 21)]
    miss = [1.0] + [max(0.02, (1 - p1) * math.exp(-0.25 * (n - 1))) for n in range(1, 21)]
    recall = [0.0] + [0.03 * i * auc_scale for i in range(1, 25)]
    precision = [1.0] + [1.0 - 0.012 * i / auc_scale for i in range(1, 25)]
    frames = 40
    return {
        "precision_at_1": p1, "mrr": mrr,
        "miss_rate_at_fppi": {"0.1": 1.0, "1": miss[3], "10": miss[-1]},
        "pose_recall_20cm_5deg": recall[-1], "pose_auc": 0.6 * auc_scale,
        "median_position_error_m": 0.05, "median_rotation_error_deg": 0.8,
        "mean_inlier_ratio": 0.3 + 0.2 * p1, "match_ms_per_frame": ms, "total_ms_per_frame": ms * 1.3,
        "miss_rate_curve": {"n": list(range(21)), "fppi": fppi, "miss_rate": miss},
        "pose_pr_curve": {"threshold": list(range(25, 0, -1)), "recall": recall, "precision": precision},
        "pose_recall_sweep": {"ransac_iterations": [50, 100, 500], "seeds": [0, 1, 2, 3, 4],
                              "mean": [0.3 * auc_scale, 0.4 * auc_scale, 0.5 * auc_scale],
                              "min": [0.25 * auc_scale, 0.35 * auc_scale, 0.48 * auc_scale],
                              "max": [0.35 * auc_scale, 0.45 * auc_scale, 0.52 * auc_scale]},
        "per_frame": {"match_ms": [ms * (0.8 + 0.01 * i) for i in range(frames)],
                      "total_ms": [ms * 1.3] * frames,
                      "inlier_ratio": [min(1.0, 0.2 + 0.2 * p1 + 0.005 * i) for i in range(frames)],
                      "position_error_m": [0.05] * (frames - 1) + [None]},
    }
report = {"dataset": {"map_frames": 200, "query_frames": 40, "landmarks": 1000, "query_keypoints": 20000,
                      "query_keypoints_with_truth": 9000},
          "methods": {"landmarkboost": method(0.86, 0.91, 0.5, 1.2, 6.0),
                      "landmarkboost_invfile": method(0.85, 0.90, 0.55, 1.15, 3.0),
                      "bruteforce_hamming": method(0.81, 0.83, 0.9, 1.0, 40.0),
                      "hamming_ratio": method(0.81, 0.83, 0.9, 1.1, 41.0),
                      "projected_kdtree": method(0.66, 0.72, 1.3, 0.7, 2.0)}}
# Equal seeds whose mean exceeds their max by a rounding step (0.1 + 0.2 > 0.3), as real reports give.
report["methods"]["projected_kdtree"]["pose_recall_sweep"].update(
    {"mean": [0.1 + 0.2] * 3, "min": [0.3] * 3, "max": [0.3] * 3})
json.dump(report, open(out + "/report.json", "w"), indent=1)
with open(out + "/run/metrics.jsonl", "w") as f:
    for r in range(300):
        f.write(json.dumps({"round": r, "cost": 5e5 * math.exp(-r / 80.0) + 2e4,
                            "validation_p1": (0.8 * (1 - math.exp(-r / 60.0))) if r % 25 == 24 else None,
                            "sharing_size": int(300 * math.exp(-r / 100.0)) + (r * 7919) % 40,
                            "seconds": 0.3}) + "\n")
    f.write(json.dumps({"round": 299, "cost": 2.1e4, "validation_p1": -1, "sharing_size": 20, "seconds": 0.3}) + "\n")
    f.write('{"round": 300, "cost"')  # a torn last line, as a preempted run leaves
PY
"$py" "$plots" --report "$out/report.json" --run "$out/run" --out "$out/plots"
for f in miss_rate_fppi pose_pr runtime_inlier pose_recall_iterations training sharing_size; do
  png="$out/plots/$f.png"
  test -s "$png" || { echo "FAIL: $png missing"; exit 1; }
  # PNG signature and a plausible size (an empty figure is ~5 KB).
  "$py" -c "import sys; d=open(sys.argv[1],'rb').read(); sys.exit(0 if d[:8]==b'\x89PNG\r\n\x1a\n' and len(d)>10000 else 1)" "$png" \
    || { echo "FAIL: $png is not a plausible PNG"; exit 1; }
done
# A report without 'methods' must fail with a message naming the file.
echo '{"dataset": {}}' > "$out/bad.json"
if "$py" "$plots" --report "$out/bad.json" --out "$out/plots_bad" 2>"$out/bad.err"; then
  echo "FAIL: a report without methods was accepted"; exit 1
fi
grep -q "bad.json" "$out/bad.err" || { echo "FAIL: error does not name the file"; cat "$out/bad.err"; exit 1; }
echo "OK: 6 plots in $out/plots"
