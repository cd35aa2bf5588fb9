#!/usr/bin/env bash
# Fault injection for distributed training: real `mpirun -n 2 lboost train` runs on the
# tiny rendered world, each hit by one fault, then checked and rerun:
#   scripts/fault_inject.sh [--seeds N | --seeds S1,S2,...] [--cases C1,C2,...] [--rounds N]
#                           [--work DIR] [--keep]
# --seeds 3 (default) runs seeds 1, 2, 3; a list runs those seeds. Each seed drives bash's RANDOM:
# which rank is hit, at which moment, how much space is left, so a failing case reruns exactly.
# Cases, per seed:
#   kill9        kill -9 of a random rank at a random moment (after a random number of rounds, plus
#                0-99 ms; "round 0" = during start-up, after 0-2 s)
#   kill9_ckpt   kill -9 of rank 0 (the writer) while it writes a checkpoint: the script polls for
#                its temporary file (checkpoints/.ckpt-*.tmp-PID) and kills as soon as it appears
#   disk_full    the checkpoint folder is a small tmpfs (`mount -t tmpfs`, works as root in this
#                container) that the script fills after a random checkpoint, leaving either a random
#                10-90% of one checkpoint free (the next write runs out in its datasets) or the
#                last checkpoint's size + 0-30 KB (it runs out at its very end, HDF5's final flush)
#   read_only    the checkpoint folder becomes read-only after a random checkpoint. chmod does not
#                stop root, so it is a read-only bind mount of the folder over itself (EROFS for
#                every user); unmounted for the rerun
#   sigterm      SIGTERM to a random rank as soon as training starts (rank 0 opened metrics.jsonl),
#                i.e. in the first round
#   sigterm_load SIGTERM to a random rank while the ranks still load the data and build features
#                (0-1.5 s after the rank installed its SIGTERM handler): the job must stop after
#                its first round with a checkpoint and exit 75 like any requeue, not die of the
#                signal
#   sigterm_mpirun  SIGTERM to the launcher the user started (jobs/train_local.sh, which runs
#                mpirun) in the first rounds: it must exit 75 with a checkpoint. A bare Open MPI 4
#                `mpirun` cannot do that on SIGTERM (it refuses to forward SIGTERM and tears the
#                job down: the ranks end within 1 s, mid-round); the signal that stops a bare
#                mpirun with a checkpoint is SIGUSR1, which it forwards: the case sends it to a
#                bare mpirun and checks exit 75 and the checkpoint, and the rerun resumes to the
#                reference model
# Each case checks: no hang (every command runs under `timeout`, LMB_FAULT_TIMEOUT s, default 300;
# exit 124 = hang), the expected exit status and message in the log, that every ckpt-*.h5 left
# reads back whole (`lboost inspect`, CRC-32 included), and that the rerun (same command, after the
# disk or folder is restored) resumes from the newest checkpoint and writes a model.bin identical
# (cmp) to the reference: an uninterrupted run of the same command. One line per case, then a
# table; exit status 1 if any case failed.
# The tiny world (`lboost world --preset tiny --seed 1` + `lboost map`, as the tests' tiny_world
# fixture; the vocabulary from its own images) is made once in WORK/tiny (about 1 min).
# Needs root (mount) and mpirun. LBOOST: the lboost binary (default ${LMB_BUILD_DIR:-build}/train/lboost,
# build it with scripts/build.sh); MPIEXEC: the launcher (default mpirun).
#
# Damaged inputs of the inference commands (no root, no MPI; 20-30 s with the defaults once the
# inputs exist):
#   scripts/fault_inject.sh --inputs [--seeds N | --seeds S1,S2,...] [--faults N] [--cases C1,...]
#                           [--work DIR] [--keep]
# Each case damages one input FAULTS times per seed (default 2): truncated at a random length, one
# byte XORed with a random value, or a burst of random bytes written over it (the seed and the fault
# number choose which and where), then runs what reads it:
#   model         model.lbm: `lboost localize --model` (must fail: the file has a CRC-32) and
#                 landmarkboost.load (must raise landmarkboost.Error)
#   bundle_index  bundle.txt beside the area models: `lboost localize --bundle --no-prior`, and
#                 landmarkboost.load, then each area's model
#   areas         the areas file: `lboost bundle --areas` and `lboost train --area FILE:0`
#   sessions      the collection's sessions.txt (without its comments): `lboost map`
#   report        report.json of `lboost eval`: landmarkboost.read_report
# Each command must end by itself (no hang: LMB_FAULT_TIMEOUT s, default 60 here; no signal) with
# exit 0 (a fault that left a valid input) or exit 1 and exactly one stderr line
# "lboost CMD: error: ..." naming the damaged input; a Python entry point returns or raises
# landmarkboost.Error naming the file, nothing else; the damaged file is byte for byte what it was
# before. The inputs (a model with its eval report, the map split into areas, one model per area
# and their bundle) are made once in WORK/tiny/inputs (about 1.5 min, with the tiny world when it
# is missing). The Python checks use the build's package (<build>/python, with the interpreter of
# its CMakeCache.txt, or PYTHON) and are skipped when it does not import.
set -uo pipefail
cd "$(dirname "$0")/.."
root=$(pwd)
seeds_arg=3
cases_arg=kill9,kill9_ckpt,disk_full,read_only,sigterm,sigterm_load,sigterm_mpirun
rounds=100
work=${TMPDIR:-/tmp}/lmb_fault_inject
keep_work=0
mode=training
cases_given=0
faults=2
while [ $# -gt 0 ]; do
  case "$1" in
    --seeds) seeds_arg=$2; shift 2 ;;
    --cases) cases_arg=$2; cases_given=1; shift 2 ;;
    --rounds) rounds=$2; shift 2 ;;
    --work) work=$2; shift 2 ;;
    --keep) keep_work=1; shift ;;
    --inputs) mode=inputs; shift ;;
    --faults) faults=$2; shift 2 ;;
    *) sed -n '2,/^set -uo/{/^#/p}' "$0"; exit 2 ;;
  esac
done
if [[ "$seeds_arg" == *,* ]]; then IFS=, read -r -a seeds <<< "$seeds_arg"; else seeds=($(seq 1 "$seeds_arg")); fi
lboost=${LBOOST:-$root/${LMB_BUILD_DIR:-build}/train/lboost}
mpiexec=${MPIEXEC:-mpirun}
limit=${LMB_FAULT_TIMEOUT:-300}
interval=10  # checkpoint interval (rounds)
[ -x "$lboost" ] || { echo "fault_inject: no lboost at $lboost (scripts/build.sh, or set LBOOST)" >&2; exit 2; }
# ---- --inputs: corrupted inputs of the inference commands -----------------------------------------
if [ "$mode" = inputs ]; then
  limit=${LMB_FAULT_TIMEOUT:-60}
  [ "$cases_given" -eq 1 ] || cases_arg=model,bundle_index,areas,sessions,report
  build_dir=$(dirname "$(dirname "$lboost")")
  python=$(sed -n 's/^Python3_EXECUTABLE:FILEPATH=//p' "$build_dir/CMakeCache.txt" 2> /dev/null)
  python=${PYTHON:-${python:-python3}}
  export PYTHONPATH="$build_dir/python${PYTHONPATH:+:$PYTHONPATH}" PYTHONDONTWRITEBYTECODE=1
  have_python=1
  "$python" -c "import landmarkboost" 2> /dev/null || have_python=0
  mkdir -p "$work"
  work=$(cd "$work" && pwd)
  trap '[ "$keep_work" -eq 1 ] || rm -rf "$work"/inputs-seed-*' EXIT
  trap 'exit 130' INT TERM

  # The fixture, made once in WORK/tiny (about 2 min; reused by later runs): the tiny world and its
  # map as in the training mode, a model with its run and eval report, the map split into areas, one
  # model per area and their bundle.
  tiny=$work/tiny
  fx=$tiny/inputs
  make_inputs() {
    local map=$tiny/map.h5 vocab=$tiny/vocab.lbv eligible id
    if [ ! -f "$map" ] || [ ! -f "$vocab" ]; then
      rm -rf "$tiny" && mkdir -p "$fx/bundle"
      "$lboost" world --preset tiny --seed 1 --out "$tiny/collection" || return 1
      "$lboost" map --collection "$tiny/collection" --out "$map" || return 1
      "$lboost" vocab --images "$tiny/collection/images" --out "$vocab" --words 16 --seed 7 || return 1
    fi
    "$lboost" train --map "$map" --vocab "$vocab" --out "$fx/run" --rounds 20 --dims-per-round 100 --threads 2 || return 1
    "$lboost" export --run "$fx/run" --map "$map" --vocab "$vocab" --out "$fx/model.lbm" || return 1
    "$lboost" eval --model "$fx/model.lbm" --map "$map" --run "$fx/run" --vocab "$vocab" --report "$fx/report.json" ||
      return 1
    # Areas of a third of the eligible landmarks each (as test/train/cli/areas_cli_test.cc).
    "$lboost" areas --map "$map" --out "$fx/one_area.txt" --min-observations 3 --max-classes 1000000 || return 1
    eligible=$(sed -n 's/^eligible //p' "$fx/one_area.txt")
    "$lboost" areas --map "$map" --out "$fx/areas.txt" --min-observations 3 --overlap 0.2 \
      --max-classes $(( eligible / 3 )) || return 1
    for id in $(sed -n 's/^area \([0-9]*\) .*/\1/p' "$fx/areas.txt"); do
      "$lboost" train --map "$map" --vocab "$vocab" --out "$fx/area-run-$id" --rounds 6 --dims-per-round 64 \
        --area "$fx/areas.txt:$id" || return 1
      "$lboost" export --run "$fx/area-run-$id" --map "$map" --vocab "$vocab" --out "$fx/bundle/area-$id.lbm" || return 1
    done
    "$lboost" bundle --areas "$fx/areas.txt" --models "$fx/bundle" || return 1
    touch "$fx/ready"
  }
  if [ ! -f "$fx/ready" ]; then
    echo "fault_inject: making the inference inputs in $fx"
    rm -rf "$fx" && mkdir -p "$fx/bundle"
    make_inputs > "$tiny/inputs.log" 2>&1 || { tail -20 "$tiny/inputs.log"; echo "fault_inject: the inputs fixture failed" >&2; exit 1; }
  fi
  # The collection's sessions without its comments, so that most faults hit the sessions (a
  # collection without the file has the sessions "map" and "query": lboost map --query-prefix).
  sessions_file=$fx/sessions.txt
  if [ -f "$tiny/collection/sessions.txt" ]; then
    grep -v '^#' "$tiny/collection/sessions.txt" > "$sessions_file"
  else
    printf 'map map\nquery query\n' > "$sessions_file"
  fi

  # corrupt SRC DST KIND: DST = SRC with one fault at a random offset: KIND 0 truncates it there, 1
  # XORs that byte with a random non-zero value, 2 overwrites a burst of 2-16 bytes with random ones.
  # $fault describes it. (RANDOM in this shell, never in a $(...) subshell: a seed replays exactly.)
  corrupt() {
    local src=$1 dst=$2 size at x old len i bytes=""
    size=$(stat -c %s "$src")
    cp "$src" "$dst"
    at=$(( (RANDOM * 32768 + RANDOM) % size ))
    case $3 in
      0) truncate -s "$at" "$dst"; fault="truncated to $at of $size bytes" ;;
      1)
        x=$(( 1 + RANDOM % 255 ))
        old=$(od -An -tu1 -j "$at" -N1 "$src" | tr -d ' ')
        printf '%b' "\\0$(printf '%03o' $(( old ^ x )))" | dd of="$dst" bs=1 seek="$at" conv=notrunc status=none
        fault="byte $at of $size XOR $x"
        ;;
      2)
        len=$(( 2 + RANDOM % 15 ))
        for (( i = 0; i < len; i++ )); do bytes+="\\0$(printf '%03o' $(( RANDOM % 256 )))"; done
        printf '%b' "$bytes" | dd of="$dst" bs=1 seek="$at" conv=notrunc status=none
        fault="$len random bytes at $at of $size"
        ;;
    esac
  }
  # run_lboost DIR NAME CMD ARGS...: runs `lboost CMD ARGS` under timeout (stdout, stderr in
  # DIR/NAME.out, .err); $st is its exit status.
  run_lboost() {
    local dir=$1 name=$2
    shift 2
    st=0
    timeout -k 5 "$limit" "$lboost" "$@" > "$dir/$name.out" 2> "$dir/$name.err" < /dev/null || st=$?
  }
  # expect_clean NAME CMD MUST_FAIL ERRFILE DIR: the run ended by itself, not by a signal, and either
  # exited 0 (a fault that left a valid input; not allowed when MUST_FAIL is 1) or exited 1 with
  # exactly one line "lboost CMD: error: ..." on stderr that names the damaged input (a path in
  # DIR, the case's folder). $outcome += what happened.
  expect_clean() {
    local name=$1 cmd=$2 must_fail=$3 err=$4 dir=$5
    if [ "$st" -eq 124 ] || [ "$st" -eq 137 ]; then
      problem="$problem; $name: hang (stopped after $limit s)"
    elif [ "$st" -gt 128 ]; then
      problem="$problem; $name: killed by signal $(( st - 128 ))"
    elif [ "$st" -eq 0 ]; then
      [ "$must_fail" -eq 1 ] && problem="$problem; $name: accepted the damaged input"
      outcome="$outcome; $name accepted"
    elif [ "$st" -eq 1 ]; then
      if [ "$(wc -l < "$err")" -ne 1 ] || ! grep -q "^lboost $cmd: error: " "$err"; then
        problem="$problem; $name: exit 1 without exactly one line 'lboost $cmd: error: ...' ($(head -c 300 "$err" | tr '\n' '|'))"
      elif ! grep -qF "$dir/" "$err"; then
        problem="$problem; $name: the error names no damaged input ($(head -c 300 "$err"))"
      fi
      outcome="$outcome; $name: $(cut -c1-110 "$err")"
    else
      problem="$problem; $name: exit $st"
    fi
  }
  # expect_python KIND FILE MUST_FAIL: landmarkboost's entry point for the file (load, or read_report)
  # returns or raises landmarkboost.Error naming the file; never another exception or a crash.
  py_check='
import sys
import landmarkboost as lb
kind, path = sys.argv[1], sys.argv[2]
try:
    if kind == "report":
        lb.read_report(path)
    else:
        loaded = lb.load(path)
        if isinstance(loaded, lb.AreaBundle):
            for i in range(loaded.num_areas):
                try:
                    loaded.model(i)
                except lb.Error:
                    pass
    print("accepted")
except lb.Error as e:
    if path not in str(e):
        sys.exit(f"landmarkboost.Error without the file name: {e}")
    print("error")
'
  expect_python() {
    [ "$have_python" -eq 1 ] || return 0
    local out pst=0
    out=$(timeout -k 5 "$limit" "$python" -c "$py_check" "$1" "$2" 2>&1) || pst=$?
    if [ "$pst" -eq 124 ] || [ "$pst" -eq 137 ]; then
      problem="$problem; python $1: hang"
    elif [ "$pst" -ne 0 ]; then
      problem="$problem; python $1: exit $pst: $(echo "$out" | tail -n 1 | cut -c1-200)"
    elif [ "$3" -eq 1 ] && [ "$out" != error ]; then
      problem="$problem; python $1: accepted the damaged input"
    else
      outcome="$outcome; python $out"
    fi
  }
  # unchanged FILE COPY: the damaged input is byte for byte its copy made before the commands ran.
  unchanged() { cmp -s "$1" "$2" || problem="$problem; $(basename "$1") changed by the commands"; }
  # models_dir DIR: DIR/models holds links to the bundle's area models (commands write beside them).
  models_dir() {
    local m
    mkdir -p "$1/models"
    for m in "$fx"/bundle/area-*.lbm; do ln -s "$m" "$1/models/$(basename "$m")"; done
  }

  input_model() {
    corrupt "$fx/model.lbm" "$1/model.lbm" "$2"
    cp "$1/model.lbm" "$1/before"
    run_lboost "$1" localize localize --model "$1/model.lbm" --map "$tiny/map.h5" --out "$1/poses.json"
    expect_clean "localize" localize 1 "$1/localize.err" "$1"
    expect_python model "$1/model.lbm" 1
    unchanged "$1/model.lbm" "$1/before"
  }
  input_bundle_index() {
    models_dir "$1"
    corrupt "$fx/bundle/bundle.txt" "$1/models/bundle.txt" "$2"
    cp "$1/models/bundle.txt" "$1/before"
    run_lboost "$1" localize localize --bundle "$1/models/bundle.txt" --no-prior --map "$tiny/map.h5" \
      --out "$1/poses.json"
    expect_clean "localize --bundle" localize 0 "$1/localize.err" "$1"
    expect_python bundle "$1/models/bundle.txt" 0
    unchanged "$1/models/bundle.txt" "$1/before"
  }
  input_areas() {
    models_dir "$1"
    corrupt "$fx/areas.txt" "$1/areas.txt" "$2"
    cp "$1/areas.txt" "$1/before"
    run_lboost "$1" bundle bundle --areas "$1/areas.txt" --models "$1/models"
    expect_clean "bundle" bundle 0 "$1/bundle.err" "$1"
    run_lboost "$1" train train --map "$tiny/map.h5" --vocab "$tiny/vocab.lbv" --area "$1/areas.txt:0" --rounds 2 \
      --dims-per-round 32 --threads 1 --out "$1/run"
    expect_clean "train --area" train 0 "$1/train.err" "$1"
    unchanged "$1/areas.txt" "$1/before"
  }
  input_sessions() {
    local e
    mkdir -p "$1/collection"
    for e in "$tiny"/collection/*; do
      [ "$(basename "$e")" = sessions.txt ] || ln -s "$e" "$1/collection/$(basename "$e")"
    done
    corrupt "$sessions_file" "$1/collection/sessions.txt" "$2"
    cp "$1/collection/sessions.txt" "$1/before"
    run_lboost "$1" map map --collection "$1/collection" --out "$1/map.h5" --threads 2
    expect_clean "map" map 0 "$1/map.err" "$1"
    unchanged "$1/collection/sessions.txt" "$1/before"
  }
  input_report() {
    corrupt "$fx/report.json" "$1/report.json" "$2"
    cp "$1/report.json" "$1/before"
    expect_python report "$1/report.json" 0
    unchanged "$1/report.json" "$1/before"
  }

  IFS=, read -r -a cases <<< "$cases_arg"
  for c in "${cases[@]}"; do declare -F "input_$c" > /dev/null || { echo "fault_inject: no input case '$c'" >&2; exit 2; }; done
  [ "$have_python" -eq 1 ] || echo "fault_inject: $python cannot import landmarkboost from $build_dir/python: Python checks skipped"
  failures=0 total=0
  started=$(date +%s)
  for seed in "${seeds[@]}"; do
    for c in "${cases[@]}"; do
      for (( k = 0; k < faults; k++ )); do
        RANDOM=$(( seed * 1000 + k * 101 + ${#c} * 17 + $(printf '%d' "'${c:0:1}") ))
        dir=$work/inputs-seed-$seed/$c-$k
        rm -rf "$dir" && mkdir -p "$dir"
        problem="" outcome="" fault=""
        "input_$c" "$dir" $(( (seed + k) % 3 ))
        total=$(( total + 1 ))
        verdict=PASS
        if [ -n "$problem" ]; then verdict=FAIL; failures=$(( failures + 1 )); fi
        why=${problem#; }
        printf '%-4s %-12s seed %-3s %-38s %s\n' "$verdict" "$c" "$seed" "$fault" "${outcome#; }${why:+ -- $why}"
      done
    done
  done
  echo "fault_inject: $(( total - failures )) of $total damaged inputs handled (seeds ${seeds[*]}, $faults faults each, $(( $(date +%s) - started )) s)"
  [ "$failures" -eq 0 ]
  exit
fi

command -v "$mpiexec" > /dev/null || { echo "fault_inject: no $mpiexec" >&2; exit 2; }
[ "$(id -u)" -eq 0 ] || { echo "fault_inject: needs root (tmpfs and bind mounts)" >&2; exit 2; }
if [ "$(id -u)" -eq 0 ]; then export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1; fi
export OMPI_MCA_rmaps_base_oversubscribe=1 OMPI_MCA_btl_vader_single_copy_mechanism=none

mkdir -p "$work"
work=$(cd "$work" && pwd)
mounts=()
cleanup() {
  local m
  for m in "${mounts[@]}"; do umount -l "$m" 2> /dev/null; done
  [ "$keep_work" -eq 1 ] || rm -rf "$work"/seed-* "$work/reference"
}
trap cleanup EXIT
trap 'exit 130' INT TERM

# The problem: the tiny world, its map and a 16-word vocabulary.
tiny=$work/tiny
if [ ! -f "$tiny/map.h5" ] || [ ! -f "$tiny/vocab.lbv" ]; then
  echo "fault_inject: making the tiny world in $tiny"
  rm -rf "$tiny" && mkdir -p "$tiny"
  { "$lboost" world --preset tiny --seed 1 --out "$tiny/collection" &&
    "$lboost" map --collection "$tiny/collection" --out "$tiny/map.h5" &&
    "$lboost" vocab --images "$tiny/collection/images" --out "$tiny/vocab.lbv" --words 16 --seed 7; } \
    > "$tiny/setup.log" 2>&1 || { tail -20 "$tiny/setup.log"; echo "fault_inject: fixture failed" >&2; exit 1; }
fi
train_args=(train --map "$tiny/map.h5" --vocab "$tiny/vocab.lbv" --rounds "$rounds" --threads 1
            --checkpoint-interval "$interval" --checkpoint-keep 2)

now() { date +%s%N; }
# launch RUN LOG: starts the 2-rank job in the background; $job is the pid of its `timeout`.
launch() {
  launched=$(now)
  timeout -k 10 "$limit" "$mpiexec" -n 2 "$lboost" "${train_args[@]}" --out "$1" > "$2" 2>&1 &
  job=$!
}
# finish: waits for the job; $status is its exit status, $hung 1 if `timeout` had to stop it.
finish() {
  status=0
  wait "$job" || status=$?
  hung=0
  [ $(( ($(now) - launched) / 1000000000 )) -ge "$limit" ] && hung=1
}
# rank_pid RUN R: the pid of rank R of the job writing RUN (empty if it is not running).
rank_pid() {
  local p
  for p in $(pgrep -f -- "--out $1\$"); do
    if tr '\0' '\n' < "/proc/$p/environ" 2> /dev/null | grep -qx "OMPI_COMM_WORLD_RANK=$2"; then echo "$p"; return; fi
  done
}
running() { kill -0 "$job" 2> /dev/null; }
rounds_done() { [ -f "$1/metrics.jsonl" ] && wc -l < "$1/metrics.jsonl" || echo 0; }
# wait_until CMD...: polls CMD every 10 ms while the job runs; fails when the job has ended.
wait_until() {
  while ! "$@"; do
    running || return 1
    sleep 0.01
  done
}
has_rank() { [ -n "$(rank_pid "$1" "$2")" ]; }
# catches_sigterm PID: the process has installed a SIGTERM handler (bit 15 of SigCgt in
# /proc/PID/status), i.e. `lboost train` is past the dynamic loader and its first lines.
catches_sigterm() {
  local mask
  mask=$(awk '/^SigCgt:/ { print $2 }' "/proc/$1/status" 2> /dev/null)
  [ -n "$mask" ] && (( (16#$mask >> 14) & 1 ))
}
has_rounds() { [ "$(rounds_done "$1")" -ge "$2" ]; }
has_checkpoint() { [ -f "$1/checkpoints/ckpt-$(printf %07d "$2").h5" ]; }
# rand_delay N: $delay = a random 0..N-1 ms, in seconds for sleep (not in a $(...) subshell:
# bash reseeds RANDOM there, and a seed must replay its case exactly).
rand_delay() {
  local r=$(( RANDOM % $1 ))
  delay=$(printf '%d.%03d' $(( r / 1000 )) $(( r % 1000 )))
}

# check_checkpoints RUN: every ckpt-*.h5 reads back whole; $newest = its highest round (0: none).
check_checkpoints() {
  local f n
  newest=0
  for f in "$1"/checkpoints/ckpt-*.h5; do
    [ -e "$f" ] || continue
    if ! "$lboost" inspect "$f" >> "$1.inspect.log" 2>&1; then
      problem="$problem; unreadable $(basename "$f")"
      continue
    fi
    n=$(basename "$f" .h5)
    n=$((10#${n#ckpt-}))
    [ "$n" -gt "$newest" ] && newest=$n
  done
}

# rerun RUN: the same command again; it must resume from $newest and end with the reference model.
rerun() {
  local st=0
  timeout -k 10 "$limit" "$mpiexec" -n 2 "$lboost" "${train_args[@]}" --out "$1" > "$1.rerun.log" 2>&1 || st=$?
  if [ "$st" -ne 0 ]; then
    problem="$problem; rerun exit $st$( [ "$st" -eq 124 ] && echo ' (hang)')"
    return
  fi
  if [ "$newest" -gt 0 ]; then
    grep -q "resumed from .*ckpt-$(printf %07d "$newest").h5" "$1.rerun.log" || problem="$problem; rerun did not resume from round $newest"
    resumed="resumed@$newest"
  else
    grep -q "resumed from" "$1.rerun.log" && problem="$problem; rerun resumed without a checkpoint"
    resumed="from scratch"
  fi
  if grep -q "skipping checkpoint" "$1.rerun.log"; then problem="$problem; rerun skipped a checkpoint"; fi
  cmp -s "$1/model.bin" "$reference" || problem="$problem; model.bin differs from the reference"
}

# expect_exit WANT: $status must be WANT ("nonzero": anything but 0), and the job ended by itself.
expect_exit() {
  if [ "$hung" -eq 1 ]; then problem="$problem; hang (stopped by timeout after $limit s)"; return; fi
  if [ "$1" = nonzero ]; then
    [ "$status" -ne 0 ] || problem="$problem; exit 0 after the fault"
  else
    [ "$status" -eq "$1" ] || problem="$problem; exit $status, expected $1"
  fi
}
# expect_log LOG REGEX: the job's log names the fault.
expect_log() { grep -qE "$2" "$1" || problem="$problem; no '$2' in the log"; }
# expect_requeue RUN: a stop by signal (exit 75, logged); $after = the round it stopped after.
expect_requeue() {
  expect_exit 75
  expect_log "$1.log" "stop requested by a signal after round"
  after=$(grep -o 'stop requested by a signal after round [0-9]*' "$1.log" | grep -o '[0-9]*$')
}

results=()
failures=0
# report CASE SEED WHAT: one line per case; $problem empty = pass.
report() {
  local verdict=PASS why=${problem#; }
  if [ -n "$problem" ]; then verdict=FAIL; failures=$((failures + 1)); fi
  printf '%-4s %-12s seed %-3s exit %-3s newest ckpt %-4s rerun %-14s %s\n' "$verdict" "$1" "$2" "$status" \
    "$newest" "$resumed" "$3${why:+ -- $why}"
  results+=("$verdict"$'\t'"$1"$'\t'"$2"$'\t'"$status"$'\t'"$newest"$'\t'"$resumed"$'\t'"$3${why:+ -- $why}")
}

# The reference: the same command, uninterrupted.
reference_dir=$work/reference
reference=$reference_dir/model.bin
rm -rf "$reference_dir"
start=$(date +%s.%N)
timeout -k 10 "$limit" "$mpiexec" -n 2 "$lboost" "${train_args[@]}" --out "$reference_dir" \
  > "$reference_dir.log" 2>&1 || { tail -20 "$reference_dir.log"; echo "fault_inject: the reference run failed" >&2; exit 1; }
ref_seconds=$(awk "BEGIN { printf \"%.1f\", $(date +%s.%N) - $start }")
ckpt_bytes=$(stat -c %s "$(ls "$reference_dir"/checkpoints/ckpt-*.h5 | tail -n 1)")
echo "fault_inject: reference: $rounds rounds on 2 ranks in ${ref_seconds} s, checkpoint $ckpt_bytes bytes, model $(cksum < "$reference" | cut -d' ' -f1)"
last_ckpt=$(( (rounds - 1) / interval ))  # checkpoints before the final one

case_kill9() {
  local run=$1 target=$(( RANDOM % (rounds - 2 * interval) )) victim=$(( RANDOM % 2 )) pid
  launch "$run" "$run.log"
  if [ "$target" -eq 0 ]; then rand_delay 2000; else rand_delay 100; fi
  if [ "$target" -eq 0 ] || wait_until has_rounds "$run" "$target"; then
    sleep "$delay"
    wait_until has_rank "$run" "$victim" && pid=$(rank_pid "$run" "$victim")
    if [ -n "${pid:-}" ]; then kill -9 "$pid"; else problem="$problem; rank $victim not found"; fi
  else
    problem="$problem; the job ended before round $target"
  fi
  finish
  expect_exit nonzero
  expect_log "$run.log" "signal 9|Killed"
  [ -f "$run/model.bin" ] && problem="$problem; the killed job wrote model.bin"
  detail="rank $victim killed after $(rounds_done "$run") rounds (target $target + ${delay}s)"
}

case_kill9_ckpt() {
  local run=$1 pid="" tmp="" f t=$(( RANDOM % last_ckpt ))
  launch "$run" "$run.log"
  # Skip to a random checkpoint, then catch the next temporary file: a poll without forks (about
  # 10 us a turn), so that the kill lands while rank 0 writes.
  wait_until has_rank "$run" 0 && pid=$(rank_pid "$run" 0)
  [ "$t" -eq 0 ] || wait_until has_checkpoint "$run" $(( t * interval ))
  while [ -n "$pid" ] && [ -z "$tmp" ] && running; do
    for f in "$run"/checkpoints/.ckpt-*.tmp-*; do [ -e "$f" ] && tmp=$f; done
  done
  if [ -n "$tmp" ]; then kill -9 "$pid"; fi
  finish
  if [ -z "$tmp" ]; then
    problem="$problem; never saw a checkpoint being written"
  else
    expect_exit nonzero
    expect_log "$run.log" "signal 9|Killed"
  fi
  detail="rank 0 killed writing $(basename "${tmp:-none}" | sed 's/\.tmp-.*//; s/^\.//')"
}

case_disk_full() {
  local run=$1 t=$(( 1 + RANDOM % (last_ckpt - 1) )) free_pct=$(( 10 + RANDOM % 81 )) at_end=$(( RANDOM % 2 ))
  local ck=$1/checkpoints free
  mkdir -p "$ck"
  mount -t tmpfs -o size=$(( 4 * ckpt_bytes + 1048576 )) lmb_fault_tmpfs "$ck" || { problem="mount -t tmpfs failed"; return; }
  mounts+=("$ck")
  launch "$run" "$run.log"
  if wait_until has_checkpoint "$run" $(( t * interval )); then
    free=$(( ckpt_bytes * free_pct / 100 ))
    [ "$at_end" -eq 1 ] && free=$(( $(stat -c %s "$ck/ckpt-$(printf %07d $(( t * interval ))).h5") + RANDOM % 30000 ))
    dd if=/dev/zero of="$ck/filler" bs=64k 2> /dev/null
    truncate -s -"$free" "$ck/filler"
  else
    problem="$problem; no checkpoint $(( t * interval ))"
  fi
  finish
  expect_exit 1
  expect_log "$run.log" "cannot write the checkpoint"
  rm -f "$ck/filler"  # the disk has room again
  detail="full after ckpt $(( t * interval )), $free bytes free$( [ "$at_end" -eq 1 ] && echo ' (the next write ends short)'); $(grep -m1 -o 'cannot write the checkpoint.*' "$run.log")"
}

case_read_only() {
  local run=$1 t=$(( 1 + RANDOM % (last_ckpt - 1) )) ck=$1/checkpoints
  launch "$run" "$run.log"
  if wait_until has_checkpoint "$run" $(( t * interval )); then
    mount --bind "$ck" "$ck" && mounts+=("$ck") && mount -o remount,bind,ro "$ck" || problem="$problem; read-only bind mount failed"
    touch "$ck/probe" 2> /dev/null && problem="$problem; root can still write the folder"
  else
    problem="$problem; no checkpoint $(( t * interval ))"
  fi
  finish
  expect_exit 1
  expect_log "$run.log" "cannot write the checkpoint"
  umount "$ck" 2> /dev/null  # writable again
  detail="read-only after ckpt $(( t * interval )); $(grep -m1 -o 'cannot write the checkpoint.*' "$run.log")"
}

case_sigterm() {
  local run=$1 victim=$(( RANDOM % 2 )) pid=""
  launch "$run" "$run.log"
  if wait_until test -f "$run/metrics.jsonl"; then
    pid=$(rank_pid "$run" "$victim")
    [ -n "$pid" ] && kill -TERM "$pid"
  fi
  [ -n "$pid" ] || problem="$problem; rank $victim not found"
  finish
  expect_requeue "$run"
  detail="SIGTERM to rank $victim; stopped after round ${after:-?}"
}

case_sigterm_load() {
  local run=$1 victim=$(( RANDOM % 2 )) pid="" when=loading
  rand_delay 1500
  launch "$run" "$run.log"
  wait_until has_rank "$run" "$victim" && pid=$(rank_pid "$run" "$victim")
  # From the moment the rank catches SIGTERM (not a fixed time after its start: on a busy machine
  # the dynamic loader alone can take over 0.5 s, a window before main() no handler can close).
  if [ -n "$pid" ] && wait_until catches_sigterm "$pid"; then
    sleep "$delay"
    [ -f "$run/metrics.jsonl" ] && when="training (missed the loading)"
    kill -TERM "$pid"
  else
    problem="$problem; rank $victim not found or never caught SIGTERM"
  fi
  finish
  expect_requeue "$run"
  detail="SIGTERM to rank $victim during $when (handler + ${delay}s); stopped after round ${after:-?}"
}

case_sigterm_mpirun() {
  local run=$1 launcher bare status_bare=0
  # 1. The launcher: jobs/train_local.sh traps SIGTERM and asks mpirun (SIGUSR1, which mpirun
  #    forwards) to stop the ranks; it must exit 75.
  launched=$(now)
  LBOOST=$lboost MPIEXEC=$mpiexec timeout -k 10 "$limit" "$root/jobs/train_local.sh" 2 "${train_args[@]:1}" --out "$run" \
    > "$run.log" 2>&1 &
  job=$!
  if wait_until has_rounds "$run" 1; then
    # The script itself, the child of `timeout` (not `timeout`, whose command line matches too: a
    # SIGTERM to it goes to the whole process group, mpirun included).
    launcher=$(pgrep -P "$job" -f -- "train_local.sh 2 .*--out $run\$" | head -n 1)
    if [ -n "$launcher" ]; then kill -TERM "$launcher"; else problem="$problem; launcher not found"; fi
  else
    problem="$problem; the job ended before round 1"
  fi
  finish
  expect_requeue "$run"
  local first_after=${after:-?}
  # 2. A bare mpirun, on a copy of the run: Open MPI 4.1 forwards SIGUSR1 to the ranks, which stop
  #    like on SIGTERM: exit 75 with a checkpoint. (SIGTERM to a bare mpirun cannot give that: it
  #    tears the job down, and the ranks end within odls_base_sigkill_timeout, 1 s, without
  #    finishing their round: docs/training.md.)
  check_checkpoints "$run"
  local bare_run=$run.bare
  rm -rf "$bare_run"
  cp -a "$run" "$bare_run"
  launch "$bare_run" "$bare_run.log"
  if wait_until has_rounds "$bare_run" "$(( $(rounds_done "$bare_run") + 1 ))"; then
    bare=$(pgrep -f -- "^$mpiexec -n 2 .*--out $bare_run\$" | head -n 1)
    if [ -n "$bare" ]; then kill -USR1 "$bare"; else problem="$problem; bare mpirun not found"; fi
  fi
  wait "$job" || status_bare=$?
  grep -q "stop requested by a signal after round" "$bare_run.log" || problem="$problem; bare mpirun: the ranks did not checkpoint"
  [ "$status_bare" -eq 75 ] || problem="$problem; SIGUSR1 to a bare mpirun: exit $status_bare, not 75"
  [ -n "$problem" ] || rm -rf "$bare_run" "$bare_run".*
  detail="SIGTERM to jobs/train_local.sh: exit 75 after round $first_after; SIGUSR1 to a bare mpirun: exit $status_bare, ranks checkpointed"
}

IFS=, read -r -a cases <<< "$cases_arg"
for c in "${cases[@]}"; do declare -F "case_$c" > /dev/null || { echo "fault_inject: no case '$c'" >&2; exit 2; }; done
for seed in "${seeds[@]}"; do
  for c in "${cases[@]}"; do
    RANDOM=$(( seed * 1000 + ${#c} * 17 + $(printf '%d' "'${c:0:1}") ))
    run=$work/seed-$seed/$c
    rm -rf "$run" "$run".*
    mkdir -p "$(dirname "$run")"
    problem="" detail="" status=- hung=0 newest=0 resumed=-
    "case_$c" "$run"
    if [ "$status" != - ]; then
      check_checkpoints "$run"
      rerun "$run"
      # Not a failure, but disk space: a temporary file that a killed writer left behind.
      left=$(compgen -G "$run/checkpoints/.ckpt-*.tmp-*" | wc -l)
      [ "$left" -gt 0 ] && detail="$detail; $left stale .tmp file(s) left after the rerun"
    fi
    for m in "${mounts[@]}"; do umount -l "$m" 2> /dev/null; done
    mounts=()
    report "$c" "$seed" "$detail"
  done
done

echo
echo "| case | seed | result | job exit | newest checkpoint | rerun | details |"
echo "|---|---|---|---|---|---|---|"
for r in "${results[@]}"; do
  IFS=$'\t' read -r verdict c s st n res det <<< "$r"
  echo "| $c | $s | $verdict | $st | $n | $res | $det |"
done
echo
echo "fault_inject: $(( ${#results[@]} - failures )) of ${#results[@]} cases passed (seeds ${seeds[*]}, $rounds rounds)"
[ "$failures" -eq 0 ]
