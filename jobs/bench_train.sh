#!/usr/bin/env bash
# Training speed on a real map, every figure against a baseline measured in the same run:
#   jobs/bench_train.sh MAP VOCAB OUT [ROUNDS=200] [TOP_K=7500]
# Runs `lboost train` ROUNDS rounds (|F_m| 500, checkpoints only at the end) three times:
#   columns  1 rank,  [boost] blocked_screening = false (one column pass per candidate dim)
#   blocked  1 rank,  the default class-major screening, 8 dims a pass
#   blocked  2 ranks (mpirun -n 2, feature-parallel)
# and prints, per run, CPU-s and wall s per round (rounds only: features and checkpoints apart),
# peak memory and features per rank, bytes sent per round, validation P@1, and model.bin's CRC;
# then the speed-ups. The 2-rank model must equal the 1-rank one (the script fails otherwise).
# LBOOST: the lboost binary (default build/train/lboost); LMB_BENCH_RUNS: a subset of
# "columns blocked blocked2" (default all three).
set -euo pipefail
[ $# -ge 3 ] || { sed -n '2,12p' "$0"; exit 2; }
map=$1 vocab=$2 out=$3 rounds=${4:-200} top_k=${5:-7500}
here=$(cd "$(dirname "$0")/.." && pwd)
lboost=${LBOOST:-$here/build/train/lboost}
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_rmaps_base_oversubscribe=1
export OMPI_MCA_btl_vader_single_copy_mechanism=none
mkdir -p "$out"
printf '[boost]\nblocked_screening = false\n' > "$out/columns.toml"
printf '[boost]\nblocked_screening = true\n' > "$out/blocked.toml"

run() {  # name ranks config
  local name=$1 ranks=$2 config=$3
  rm -rf "${out:?}/$name"
  local cmd=("$lboost" train)
  [ "$ranks" -gt 1 ] && cmd=(mpirun -n "$ranks" "$lboost" train)
  echo "bench_train: $name: ${cmd[*]} ($(date +%T), load $(cut -d' ' -f1 /proc/loadavg))"
  "${cmd[@]}" --map "$map" --vocab "$vocab" --out "$out/$name" --config "$out/$config" \
    --rounds "$rounds" --top-k "$top_k" --dims-per-round 500 --threads 2 --checkpoint-interval 0 --checkpoint-minutes 0 \
    > "$out/$name.log" 2>&1 || { tail -5 "$out/$name.log"; exit 1; }
}
for name in ${LMB_BENCH_RUNS:-columns blocked blocked2}; do
  case $name in
    columns) run columns 1 columns.toml ;;
    blocked) run blocked 1 blocked.toml ;;
    blocked2) run blocked2 2 blocked.toml ;;
    *) echo "bench_train: unknown run '$name'" >&2; exit 2 ;;
  esac
done

/usr/bin/env python3 - "$out" <<'EOF'
import json, os, sys, zlib
out = sys.argv[1]
rows = {}
for name in ("columns", "blocked", "blocked2"):
    path = os.path.join(out, name, "summary.json")
    if not os.path.exists(path):
        continue
    s = json.load(open(path))
    s["crc"] = zlib.crc32(open(os.path.join(out, name, "model.bin"), "rb").read())
    rows[name] = s
first = next(iter(rows.values()), None)
if first:
    print(f"machine: {first.get('machine', 'unknown')}")
print(f"| run | ranks | CPU-s / round (slowest rank) | wall s / round | features / rank | peak RSS / rank "
      f"| bytes sent / round (all ranks) | validation P@1 | model CRC-32 |")
print("|---|---|---|---|---|---|---|---|---|")
for name, s in rows.items():
    print(f"| {name} | {s['ranks']} | {s['cpu_seconds_per_round_max_rank']:.3f} | {s['seconds_per_round']:.3f} "
          f"| {s['feature_mb_rank0']:,.0f} MB | {s['peak_rss_mb_max_rank']:,.0f} MB "
          f"| {s['bytes_sent_per_round_all_ranks']:,.0f} | {s['validation_p1']:.4f} | {s['crc']} |")
def ratio(a, b, key):
    if a in rows and b in rows:
        print(f"{b} vs {a}: {rows[a][key] / rows[b][key]:.2f}x ({key})")
ratio("columns", "blocked", "cpu_seconds_per_round_max_rank")
ratio("blocked", "blocked2", "cpu_seconds_per_round_max_rank")
ratio("blocked", "blocked2", "seconds_per_round")
if "blocked" in rows and "blocked2" in rows:
    r = rows["blocked2"]
    print(f"extrapolated to 2,000 rounds on 2 ranks: {2000 * r['seconds_per_round'] / 60:.1f} min wall "
          f"({2000 * r['cpu_seconds_per_round_max_rank'] / 60:.1f} min of the slowest rank's CPU)")
    if rows["blocked"]["crc"] != r["crc"]:
        sys.exit("bench_train: the 2-rank model differs from the 1-rank model")
if "columns" in rows and "blocked" in rows and rows["columns"]["crc"] != rows["blocked"]["crc"]:
    sys.exit("bench_train: the blocked screening's model differs from the column passes' model")
json.dump(rows, open(os.path.join(out, "bench_train.json"), "w"), indent=2)
EOF
