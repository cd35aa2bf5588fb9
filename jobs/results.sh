#!/usr/bin/env bash
# The results tables of the documentation, measured on the build at hand: runs each data set's job,
# prints its table and writes it to docs/results/.
#   jobs/results.sh [--out DIR] [--tum TUM_DIR] [--kitchen KITCHEN_DIR] [--paper] [--no-write]
#   jobs/results.sh --tables-only
# Always the `default` rendered world (jobs/pipeline.sh default DIR/default, the main job: minutes
# on 2 cores); with --tum the TUM RGB-D fr1_rpy sequence (jobs/tum.sh TUM_DIR DIR/tum_rpy);
# with --kitchen a 7-Scenes recording such as redkitchen (jobs/7scenes.sh KITCHEN_DIR DIR/kitchen);
# with --paper the `paper` world at the paper's scale (7,500 classes, 2,000 rounds: hours on 2
# cores). DIR defaults to out/results; a job keeps the stages whose output exists there (delete
# DIR/NAME to start that data set over).
# For each data set NAME it writes docs/results/NAME.md (the command, then one row per method:
# jobs/results_table.py), docs/results/NAME/report.json (the report, its paths as OUT/..., DATA/...)
# and docs/results/NAME/*.png (jobs/plots.py), and puts the table into docs/evaluation.md between
# its <!-- results:NAME --> markers; then docs/results/summary.md, the README's table (a row per data
# set whose report docs/results/ holds), also put into README.md between <!-- results:summary -->
# markers. --no-write prints the tables only. --tables-only runs no job: it rewrites every table
# (docs/results/NAME.md, docs/evaluation.md, the README) from the reports docs/results/ holds.
# LBOOST, LMB_THREADS, LMB_RANKS and the jobs' other variables pass through to the jobs.
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
usage="usage: jobs/results.sh [--out DIR] [--tum TUM_DIR] [--kitchen KITCHEN_DIR] [--paper] [--no-write] | --tables-only"
out=out/results
tum=""
kitchen=""
paper=0
write=1
tables_only=0
while [ $# -gt 0 ]; do
  case "$1" in
    --out) out=${2:?$usage}; shift 2 ;;
    --tum) tum=${2:?$usage}; shift 2 ;;
    --kitchen) kitchen=${2:?$usage}; shift 2 ;;
    --paper) paper=1; shift ;;
    --no-write) write=0; shift ;;
    --tables-only) tables_only=1; shift ;;
    -h|--help) echo "$usage"; exit 0 ;;
    *) echo "jobs/results.sh: unknown argument '$1'" >&2; echo "$usage" >&2; exit 1 ;;
  esac
done
for d in "$tum" "$kitchen"; do
  [ -z "$d" ] || [ -d "$d" ] || { echo "jobs/results.sh: $d is not a folder" >&2; exit 1; }
done
if [ "$tables_only" = 0 ]; then
  mkdir -p "$out"
  out=$(cd "$out" && pwd)
fi
table=(python3 "$here/jobs/results_table.py")
docs=$here/docs/results
summary_rows=()
declare -A titles=(
  [default]="\`default\` rendered world, unseen query session"
  [tum_rpy]="TUM RGB-D fr1_rpy, real"
  [kitchen]="7-Scenes redkitchen, real"
  [paper]="\`paper\` rendered world, 7,500 classes")
declare -A commands=(
  [default]="jobs/pipeline.sh default OUT"
  [tum_rpy]="jobs/tum.sh TUM_FR1_RPY OUT"
  [kitchen]="jobs/7scenes.sh REDKITCHEN OUT"
  [paper]='LMB_TRAIN_ARGS="--rounds 2000 --top-k 7500" jobs/pipeline.sh paper OUT')

# write_tables NAME: docs/results/NAME.md and its section of docs/evaluation.md, from the report
# docs/results/NAME/report.json.
write_tables() {
  local name=$1
  local title=${titles[$name]} command=${commands[$name]} flags=()
  [ "$name" = kitchen ] && flags=(--seven-scenes)
  local rows
  rows=$("${table[@]}" table "$docs/$name/report.json" "${flags[@]}")
  {
    printf '# Results: %s\n\n' "$title"
    printf 'Command: `%s`; table by `jobs/results.sh` (jobs/results_table.py). ' "$command"
    printf 'The report, its paths as OUT/... (and DATA/... for the data set): [%s/report.json](%s/report.json); ' "$name" "$name"
    printf 'plots: %s/*.png. Every field: [report.md](../report.md).\n\n' "$name"
    printf '%s\n' "$rows"
  } > "$docs/$name.md"
  local section
  section=$(mktemp)
  printf 'Command: `%s` ([%s.md](results/%s.md), with the report and plots).\n\n%s\n' \
    "$command" "$name" "$name" "$rows" > "$section"
  "${table[@]}" splice "$here/docs/evaluation.md" --name "$name" --text "$section"
  rm -f "$section"
  echo "jobs/results.sh: wrote docs/results/$name.md"
}

# measure NAME SEVEN_SCENES DATA JOB...: runs the job into $out/NAME, prints its table and writes
# it; commands[NAME] is how the documentation names the job (placeholders, no machine paths).
measure() {
  local name=$1 seven=$2 data=$3
  shift 3
  local title=${titles[$name]} command=${commands[$name]}
  local dir=$out/$name
  printf '\n=== %s: %s\n' "$name" "$command"
  "$@" "$dir"
  local flags=()
  [ "$seven" = 1 ] && flags=(--seven-scenes)
  printf '\n%s\n' "$("${table[@]}" table "$dir/report.json" "${flags[@]}")"
  summary_rows+=("$("${table[@]}" summary "$dir/report.json" --name "$title" --command "$command")")
  [ "$write" = 1 ] || return 0
  mkdir -p "$docs/$name"
  local replace=(--replace "$dir=OUT" --replace "$(cd "$dir" && pwd -P)=OUT" --replace "$here/=" --replace "$here=.")
  [ -z "$data" ] || replace+=(--replace "$(cd "$data" && pwd)=DATA")
  "${table[@]}" sanitize "$dir/report.json" --out "$docs/$name/report.json" "${replace[@]}"
  rm -f "$docs/$name"/*.png
  if compgen -G "$dir/plots/*.png" > /dev/null; then cp "$dir"/plots/*.png "$docs/$name/"; fi
  write_tables "$name"
}

if [ "$tables_only" = 1 ]; then
  for name in default tum_rpy kitchen paper; do
    [ ! -f "$docs/$name/report.json" ] || write_tables "$name"
  done
else
  measure default 0 "" "$here/jobs/pipeline.sh" default
fi
if [ "$tables_only" = 0 ] && [ -n "$tum" ]; then
  measure tum_rpy 0 "$tum" "$here/jobs/tum.sh" "$tum"
fi
if [ "$tables_only" = 0 ] && [ -n "$kitchen" ]; then
  measure kitchen 1 "$kitchen" "$here/jobs/7scenes.sh" "$kitchen"
fi
if [ "$tables_only" = 0 ] && [ "$paper" = 1 ]; then
  measure paper 0 "" env "LMB_TRAIN_ARGS=${LMB_TRAIN_ARGS:---rounds 2000 --top-k 7500}" "$here/jobs/pipeline.sh" paper
fi

# The README table: with --no-write this call's data sets; else every data set whose report is in
# docs/results/ (this call's and those of earlier calls), in a fixed order.
if [ "$write" = 0 ]; then
  printf '\n=== the README table\n'
  "${table[@]}" summary-header
  printf '%s\n' "${summary_rows[@]}"
  exit 0
fi
rows=()
links=()
for name in default tum_rpy kitchen paper; do
  [ -f "$docs/$name/report.json" ] || continue
  rows+=("$("${table[@]}" summary "$docs/$name/report.json" --name "${titles[$name]}" --command "${commands[$name]}")")
  links+=("[$name.md]($name.md)")
done
summary=$("${table[@]}" summary-header; printf '%s\n' "${rows[@]}")
printf '\n=== the README table\n%s\n' "$summary"
{
  printf '# Results of the build at hand\n\n'
  printf 'Written by `jobs/results.sh` from the reports in docs/results/. P@1 over the query keypoints '
  printf 'whose landmark is a model class; pose recall within 20 cm / 5 deg, the mean over 5 RANSAC seeds at '
  printf '500 iterations; reported poses: those the calibrated confidence reports localized; tracked as a '
  printf 'walk: the frames reported right (and their precision) with each query session localized frame after '
  printf 'frame (docs/walks.md), the mean over the seeds; CPU time of '
  printf 'matching and pose, one thread. Per data set: %s.\n\n%s\n' "${links[*]}" "$summary"
} > "$docs/summary.md"
section=$(mktemp)
printf '%s\n' "$summary" > "$section"
"${table[@]}" splice "$here/README.md" --name summary --text "$section"
rm -f "$section"
echo "jobs/results.sh: wrote docs/results/summary.md"
