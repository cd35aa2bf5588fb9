# Sourced by the batch scripts of jobs/slurm: runs one `lboost train` job step on the job's tasks
# and turns the requeue exit code into a Slurm requeue.
#
# run_train_step LBOOST_TRAIN_ARGS...
#   srun --mpi=pmix (Debian's OpenMPI needs pmix; pmi2 and the default fail) --kill-on-bad-exit=1
#   (a rank that dies ends the step at once). --signal=B:USR1@N signals only this batch shell: the
#   trap forwards SIGUSR1 to srun, which passes it to every rank; the ranks agree, checkpoint and
#   exit 75, and the job is requeued (it resumes from the newest checkpoint of its --out folder).
#   SIGTERM (a plain `scancel`, or the end of the time limit after the USR1 warning) also makes the
#   ranks checkpoint and exit 75, but the job is not requeued: a cancelled job stays cancelled, and
#   resubmitting the same job resumes it. (Preemption with PreemptMode=REQUEUE is requeued by
#   Slurm itself.)
run_train_step() {
  local lboost=${LBOOST:-lboost}
  local requeue_code=75
  local step_pid=
  local requeue=0 cancelled=0
  forward_stop() {
    echo "$(date +%T) train_step: $1 received, asking the ranks to checkpoint"
    [ -n "$step_pid" ] && kill -USR1 "$step_pid" 2> /dev/null
  }
  trap 'requeue=1; forward_stop USR1' USR1
  trap 'cancelled=1; forward_stop TERM' TERM
  echo "$(date +%T) train_step: job ${SLURM_JOB_ID:-?} restart ${SLURM_RESTART_COUNT:-0} on ${SLURM_NTASKS:-1} task(s): $lboost train $*"
  srun --mpi=pmix --kill-on-bad-exit=1 "$lboost" train "$@" &
  step_pid=$!
  local status=0
  wait "$step_pid" || status=$?
  while kill -0 "$step_pid" 2> /dev/null; do
    status=0
    wait "$step_pid" || status=$?
  done
  if [ "$status" -eq "$requeue_code" ] && [ "$cancelled" -eq 1 ] && [ "$requeue" -eq 0 ]; then
    echo "$(date +%T) train_step: checkpointed; cancelled (SIGTERM), not requeueing job $SLURM_JOB_ID (resubmit it to resume)"
    exit 0
  fi
  if [ "$status" -eq "$requeue_code" ]; then
    # The requeued job reuses this step's id: let the step's slurmstepd finish (and remove its
    # PMIx socket) before requeueing, or the next launch of step 0 may fail.
    for _ in $(seq 60); do
      squeue -h -s -j "$SLURM_JOB_ID" -o %i 2> /dev/null | grep -qE "^${SLURM_JOB_ID}\.[0-9]+$" || break
      sleep 1
    done
    sleep 2
    echo "$(date +%T) train_step: checkpointed; requeueing job $SLURM_JOB_ID"
    scontrol requeue "$SLURM_JOB_ID"
    exit 0
  fi
  echo "$(date +%T) train_step: lboost train ended with status $status"
  exit "$status"
}
