#!/usr/bin/env bash
# Speed of two builds in the same run: `lboost-bench infer` of each, alternating (the order flips
# every round, so that drift on a shared machine weighs on both), then the median of every timing
# and the ratio old / new (> 1: the new build is faster). A binary without an `infer` subcommand is
# run as `BINARY bench infer` (an lboost that holds the benchmarks).
#   scripts/bench_ab.sh OLD_BENCH NEW_BENCH OUT_DIR [ROUNDS] [-- infer arguments]
# Default arguments: --synthetic-paper --frames 10 --repeats 3 --no-popcount --train-descriptors 2000.
# Example, the code before a commit against after it:
#   git worktree add ../old <commit>^ && (cd ../old && ./scripts/build.sh)
#   scripts/bench_ab.sh ../old/build/tools/bench/lboost-bench build/tools/bench/lboost-bench bench_ab 3
set -euo pipefail
if [ $# -lt 3 ]; then
  sed -n '2,10p' "$0" | sed 's/^# \{0,1\}//' >&2
  exit 2
fi
old=$1 new=$2 out=$3
shift 3
rounds=3
if [ $# -gt 0 ] && [ "$1" != "--" ]; then rounds=$1; shift; fi
[ $# -gt 0 ] && [ "$1" = "--" ] && shift
args=("$@")
[ ${#args[@]} -eq 0 ] && args=(--synthetic-paper --frames 10 --repeats 3 --no-popcount --train-descriptors 2000)
for b in "$old" "$new"; do
  [ -x "$b" ] || { echo "bench_ab: $b is not an executable" >&2; exit 2; }
done
# The infer benchmark's command line of binary $1.
infer_command() {
  if "$1" infer --help > /dev/null 2>&1; then echo infer; else echo bench infer; fi
}
read -r -a old_cmd <<< "$(infer_command "$old")"
read -r -a new_cmd <<< "$(infer_command "$new")"
mkdir -p "$out"
for i in $(seq 1 "$rounds"); do
  order="old new"
  [ $((i % 2)) = 0 ] && order="new old"
  for which in $order; do
    bin=$old cmd=("${old_cmd[@]}")
    [ "$which" = new ] && bin=$new cmd=("${new_cmd[@]}")
    echo "bench_ab: round $i of $rounds, $which ($bin ${cmd[*]})"
    "$bin" "${cmd[@]}" "${args[@]}" --json "$out/$which-$i.json" > "$out/$which-$i.txt"
  done
done
python3 - "$out" <<'PY' | tee "$out/summary.txt"
import glob, json, statistics, sys
out = sys.argv[1]
def timings(d, prefix=""):
    flat = {}
    for k, v in d.items():
        if isinstance(v, dict):
            flat.update(timings(v, prefix + k + "."))
        elif isinstance(v, (int, float)) and "ms" in prefix + k:
            flat[prefix + k] = v
    return flat
runs = {w: [timings(json.load(open(f))) for f in sorted(glob.glob(f"{out}/{w}-*.json"))] for w in ("old", "new")}
keys = sorted(set(runs["old"][0]) & set(runs["new"][0]))
print(f"{'median ms of %d runs' % len(runs['old']):48s} {'old':>9s} {'new':>9s}  old/new")
for k in keys:
    old, new = (statistics.median(r[k] for r in runs[w]) for w in ("old", "new"))
    print(f"{k:48s} {old:9.3f} {new:9.3f}  {old / new if new else float('nan'):6.2f}")
PY
