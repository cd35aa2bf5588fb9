#!/usr/bin/env bash
# kill -9 of one rank of `mpirun -n 2 lboost train` ends the job with an error instead of a hang,
# and rerunning the same command resumes from the newest checkpoint to the model of an
# uninterrupted one-process run.
#   kill_rank_test.sh LBOOST MPIEXEC
set -euo pipefail
lboost=$1
mpiexec=$2
work=$(mktemp -d -t lmb_kill_rank.XXXXXX)
trap 'rm -rf "$work"' EXIT
args=(train --synthetic small --rounds 2000 --dims-per-round 64 --checkpoint-interval 20 --checkpoint-keep 2)

fail() { echo "kill_rank_test: FAIL: $*" >&2; exit 1; }

# The reference: one process, no MPI.
"$lboost" "${args[@]}" --out "$work/reference" > "$work/reference.log" 2>&1 || fail "reference run failed"

# The job: 2 ranks, killed as soon as it has written a checkpoint.
"$mpiexec" -n 2 "$lboost" "${args[@]}" --out "$work/run" > "$work/first.log" 2>&1 &
launcher=$!
for _ in $(seq 600); do
  compgen -G "$work/run/checkpoints/ckpt-*.h5" > /dev/null && break
  sleep 0.1
done
compgen -G "$work/run/checkpoints/ckpt-*.h5" > /dev/null || fail "no checkpoint after 60 s"
victim=$(pgrep -P "$launcher" -f lboost | tail -n 1)
[ -n "$victim" ] || fail "no rank process under the launcher $launcher"
kill -9 "$victim"
start=$(date +%s)
status=0
# The launcher must end by itself: a hang would be stopped by this loop after 60 s.
for _ in $(seq 600); do
  kill -0 "$launcher" 2> /dev/null || break
  sleep 0.1
done
if kill -0 "$launcher" 2> /dev/null; then
  kill -9 "$launcher"
  fail "the job still runs 60 s after kill -9 of one rank (hang)"
fi
wait "$launcher" || status=$?
echo "kill_rank_test: the job ended $(( $(date +%s) - start )) s after kill -9, exit status $status"
[ "$status" -ne 0 ] || fail "the killed job reported success"
grep -qi "signal 9\|killed" "$work/first.log" || { cat "$work/first.log"; fail "no clear error naming the killed rank"; }
[ -f "$work/run/model.bin" ] && fail "the killed job wrote a model"

# Rerun: resumes from the newest checkpoint and finishes with the reference model.
"$mpiexec" -n 2 "$lboost" "${args[@]}" --out "$work/run" > "$work/second.log" 2>&1 || { cat "$work/second.log"; fail "rerun failed"; }
grep -q "resumed from" "$work/second.log" || fail "the rerun did not resume"
cmp "$work/run/model.bin" "$work/reference/model.bin" || fail "resumed model differs from the uninterrupted one"
# `lboost inspect` reads a checkpoint whole (CRC included) and refuses a torn one with its name.
newest=$(ls "$work/run/checkpoints"/ckpt-*.h5 | sort | tail -n 1)
"$lboost" inspect "$newest" | grep -q "CRC-32 ok" || fail "lboost inspect does not accept $newest"
cp "$newest" "$work/ckpt-torn.h5"
truncate -s $(( $(stat -c %s "$newest") / 2 )) "$work/ckpt-torn.h5"
if "$lboost" inspect "$work/ckpt-torn.h5" > /dev/null 2> "$work/inspect.err"; then fail "inspect accepted a torn checkpoint"; fi
grep -q "ckpt-torn.h5" "$work/inspect.err" || { cat "$work/inspect.err"; fail "no error naming the torn checkpoint"; }
echo "kill_rank_test: OK ($(grep -o 'resumed from [^ ]*' "$work/second.log"))"
