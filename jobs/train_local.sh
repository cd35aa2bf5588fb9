#!/usr/bin/env bash
# Distributed training on this machine: `mpirun -n RANKS lboost train ARGS...`, rerun after the
# requeue exit code (75: a rank received SIGTERM/SIGUSR1 and checkpointed) so the run resumes from
# its newest checkpoint; any other failure stops the script with that status.
#   jobs/train_local.sh RANKS LBOOST_TRAIN_ARGS...
#   e.g. jobs/train_local.sh 2 --map out/default/map.h5 --vocab out/default/vocab.lbv --out out/default/run
# SIGTERM / SIGUSR1 / SIGINT to this script: the ranks checkpoint and stop, the script exits 75;
# run the same command again to continue. As root, OpenMPI needs OMPI_ALLOW_RUN_AS_ROOT=1 and
# OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1; more ranks than cores need OMPI_MCA_rmaps_base_oversubscribe=1.
# LBOOST: the lboost binary (default build/train/lboost); MPIEXEC: the launcher (default mpirun).
set -uo pipefail
[ $# -ge 1 ] || { sed -n '2,11p' "$0"; exit 2; }
ranks=$1
shift
here=$(cd "$(dirname "$0")/.." && pwd)
lboost=${LBOOST:-$here/build/train/lboost}
mpiexec=${MPIEXEC:-mpirun}
requeue_code=75

stop=0
pid=
on_signal() {
  stop=1
  [ -n "$pid" ] && kill -USR1 "$pid" 2> /dev/null  # mpirun forwards SIGUSR1 to every rank
}
trap on_signal TERM INT USR1

attempt=0
while true; do
  attempt=$((attempt + 1))
  echo "train_local: attempt $attempt: $mpiexec -n $ranks $lboost train $*"
  "$mpiexec" -n "$ranks" "$lboost" train "$@" &
  pid=$!
  status=0
  wait "$pid" || status=$?
  # A trapped signal interrupts `wait`: wait again until the job itself has ended.
  while kill -0 "$pid" 2> /dev/null; do
    status=0
    wait "$pid" || status=$?
  done
  pid=
  if [ "$status" -eq "$requeue_code" ]; then
    if [ "$stop" -eq 1 ]; then
      echo "train_local: checkpointed and stopped; rerun the same command to resume"
      exit "$requeue_code"
    fi
    echo "train_local: a rank asked for a requeue; resuming"
    continue
  fi
  exit "$status"
done
