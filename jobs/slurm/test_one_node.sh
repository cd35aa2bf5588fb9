#!/usr/bin/env bash
# The Slurm job scripts, for real, on a one-node slurm-wlm cluster started on this machine
# (Debian bookworm, root): munged, slurmctld and slurmd with proctrack/linuxproc and task/none,
# configuration, state and logs under a temporary folder.
#
#   jobs/slurm/test_one_node.sh [LBOOST]      (default build/train/lboost)
#
# 1. train.sbatch on 2 tasks (srun --mpi=pmix) is signalled mid-training with
#    `scancel --signal=USR1 --batch`, checkpoints, is requeued (its ~2 min BeginTime is cut with
#    `scontrol update starttime=now`), resumes and finishes; its model.bin must equal the model of
#    an uninterrupted one-process run, byte for byte. A plain scancel of another: checkpointed,
#    CANCELLED, not requeued.
# 2. sweep.sbatch as a 2-task job array over --dims-per-round: both tasks finish.
# 3. train_areas.sbatch as a job array over the areas of a tiny rendered world (lboost world
#    --preset tiny, map, vocab, areas: 3 areas); one task is killed mid-training (SIGKILL to every
#    process of the task, listed by `scontrol listpids`: nothing checkpoints on the way out) and
#    must end FAILED while the others complete; that task rerun alone (`sbatch --array=ID`, the same
#    arguments) resumes from its newest checkpoint; every area's model.bin must then equal the model
#    of the same area trained by an uninterrupted one-process `lboost train --area`, byte for byte.
# Installs slurm-wlm (apt) when missing. Stops only the daemons it started.
set -euo pipefail
here=$(cd "$(dirname "$0")/../.." && pwd)
lboost=$(realpath "${1:-$here/build/train/lboost}")
[ -x "$lboost" ] || { echo "test_one_node: no lboost at $lboost (build it first)"; exit 2; }
[ "$(id -u)" -eq 0 ] || { echo "test_one_node: needs root (SlurmUser=root, munged as munge)"; exit 2; }

if ! command -v slurmctld > /dev/null || ! command -v munged > /dev/null; then
  echo "test_one_node: installing slurm-wlm and munge"
  DEBIAN_FRONTEND=noninteractive apt-get update -qq
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends slurm-wlm munge > /dev/null
fi

work=$(mktemp -d -t lmb_slurm.XXXXXX)
chmod 755 "$work"
host=$(hostname -s)
export SLURM_CONF=$work/slurm.conf
cleanup() {
  # Only the daemons this script started, by their pid files.
  for f in "$work/slurmd.pid" "$work/slurmctld.pid" "$work/munge/munged.pid"; do
    [ -f "$f" ] && kill "$(cat "$f")" 2> /dev/null || true
  done
  sleep 1
  if [ "${LMB_KEEP_SLURM_DIR:-0}" = 1 ]; then echo "test_one_node: kept $work"; else rm -rf "$work"; fi
}
trap cleanup EXIT
fail() {
  echo "test_one_node: FAIL: $*" >&2
  for f in "$work"/*.out "$work"/slurmctld.log "$work"/slurmd.log; do
    [ -f "$f" ] && { echo "---- $f"; tail -n 40 "$f"; }
  done
  exit 1
}

# munged as the munge user, with its own socket under the work folder.
mkdir -p "$work/munge"
chown munge:munge "$work/munge"
[ -f /etc/munge/munge.key ] || { /usr/sbin/mungekey --create 2> /dev/null || create-munge-key; }
runuser -u munge -- /usr/sbin/munged --socket="$work/munge/munge.socket" --pid-file="$work/munge/munged.pid" \
  --log-file="$work/munge/munged.log" --seed-file="$work/munge/munged.seed" --force
sleep 1

mkdir -p "$work/state" "$work/spool"
cat > "$SLURM_CONF" << CONF
ClusterName=lmbtest
SlurmctldHost=$host
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CryptoType=crypto/munge
AuthInfo=socket=$work/munge/munge.socket
MpiDefault=none
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
ReturnToService=2
JobRequeue=1
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
StateSaveLocation=$work/state
SlurmdSpoolDir=$work/spool
SlurmctldPidFile=$work/slurmctld.pid
SlurmdPidFile=$work/slurmd.pid
SlurmctldLogFile=$work/slurmctld.log
SlurmdLogFile=$work/slurmd.log
SlurmctldPort=${LMB_SLURMCTLD_PORT:-6817}
SlurmdPort=${LMB_SLURMD_PORT:-6818}
KillWait=30
NodeName=$host CPUs=2 State=UNKNOWN
PartitionName=debug Nodes=$host Default=YES MaxTime=INFINITE State=UP OverSubscribe=YES
CONF
/usr/sbin/slurmctld -i -f "$SLURM_CONF"
sleep 2
/usr/sbin/slurmd -f "$SLURM_CONF"
for _ in $(seq 60); do
  sinfo -h -o %T 2> /dev/null | grep -q idle && break
  sleep 1
done
sinfo -h -o %T | grep -q idle || fail "the node did not become idle: $(sinfo 2>&1)"
echo "test_one_node: cluster up: $(sinfo -h -o '%P %D %T %c')"

state_of() { scontrol show job "$1" 2> /dev/null | grep -o 'JobState=[A-Z_]*' | cut -d= -f2; }
wait_state() {  # job, regex, seconds
  for _ in $(seq "$3"); do
    s=$(state_of "$1")
    [[ "$s" =~ $2 ]] && return 0
    sleep 1
  done
  fail "job $1 is $(state_of "$1"), expected $2 within $3 s"
}
wait_rounds() {  # run folder, failure message: up to 60 s for 10 rounds in its metrics.jsonl
  for _ in $(seq 300); do
    [ -f "$1/metrics.jsonl" ] && [ "$(wc -l < "$1/metrics.jsonl")" -ge 10 ] && return 0
    sleep 0.2
  done
  [ -f "$1/metrics.jsonl" ] || fail "$2"
}

export OMPI_MCA_btl_vader_single_copy_mechanism=none
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
args=(--synthetic medium --rounds "${LMB_TEST_ROUNDS:-150}" --dims-per-round 200 --checkpoint-interval 1000)

# The uninterrupted reference: one process.
"$lboost" train "${args[@]}" --out "$work/reference" > "$work/reference.log" 2>&1 || fail "reference run"

# 1. Signal, checkpoint, requeue, resume, finish.
cd "$work"
job=$(LMB_REPO=$here LBOOST=$lboost sbatch --parsable --ntasks=2 --output="$work/train-%j.out" \
  "$here/jobs/slurm/train.sbatch" "${args[@]}" --out "$work/run")
echo "test_one_node: submitted train job $job"
wait_state "$job" RUNNING 120
wait_rounds "$work/run" "no training progress"
echo "test_one_node: signalling job $job after $(wc -l < "$work/run/metrics.jsonl") rounds"
scancel --signal=USR1 --batch "$job"
# Requeued: PENDING again (or briefly REQUEUED) with a BeginTime; start it now.
wait_state "$job" 'PENDING|REQUEUED' 120
compgen -G "$work/run/checkpoints/ckpt-*.h5" > /dev/null || fail "no checkpoint after the signal"
checkpoint=$(ls "$work/run/checkpoints" | tail -n 1)
echo "test_one_node: job $job requeued with $checkpoint"
# Start it now, once slurmd has finished killing the first run (starting a requeued job at once
# races with that: "Job credential revoked"; Slurm's own ~2 min BeginTime avoids it).
for _ in $(seq 60); do
  sinfo -h -o %T | grep -q idle && break
  sleep 1
done
sleep 10
for _ in $(seq 30); do
  scontrol update jobid="$job" starttime=now 2> /dev/null && break
  sleep 1
done
wait_state "$job" 'COMPLETED|FAILED|CANCELLED|TIMEOUT' 600
[ "$(state_of "$job")" = COMPLETED ] || fail "job $job ended $(state_of "$job")"
out=$work/train-$job.out
grep -q "checkpointed; requeueing" "$out" || fail "the job did not requeue itself"
grep -q "resumed from" "$work/run/log.txt" || fail "the requeued job did not resume"
cmp "$work/run/model.bin" "$work/reference/model.bin" || fail "the requeued job's model differs from the uninterrupted one"
restarts=$(scontrol show job "$job" | grep -o 'Restarts=[0-9]*')
echo "test_one_node: train job OK ($restarts, $(grep -o 'resumed from [^ ]*' "$work/run/log.txt" | head -n 1)), model identical"

# 1b. A plain scancel (SIGTERM) of a running train job: the ranks checkpoint, the job stays
# cancelled (not requeued).
job=$(LMB_REPO=$here LBOOST=$lboost sbatch --parsable --ntasks=2 --output="$work/cancel-%j.out" \
  "$here/jobs/slurm/train.sbatch" "${args[@]}" --out "$work/cancelled")
wait_state "$job" RUNNING 120
wait_rounds "$work/cancelled" "cancel: no training progress"
scancel "$job"
wait_state "$job" 'CANCELLED|COMPLETED|FAILED|PENDING|REQUEUED' 120
sleep 5
[ "$(state_of "$job")" = CANCELLED ] || fail "cancel: job $job is $(state_of "$job") after scancel, expected CANCELLED"
compgen -G "$work/cancelled/checkpoints/ckpt-*.h5" > /dev/null || fail "cancel: no checkpoint after scancel"
grep -q "not requeueing" "$work/cancel-$job.out" || fail "cancel: the job did not say it stays cancelled"
echo "test_one_node: scancel OK (job $job CANCELLED with $(ls "$work/cancelled/checkpoints" | tail -n 1), not requeued)"

# 2. A job array sweep over --dims-per-round.
array=$(LMB_REPO=$here LBOOST=$lboost LMB_SWEEP_FLAG=--dims-per-round LMB_SWEEP_VALUES="100 200" \
  sbatch --parsable --array=0-1 --ntasks=1 --output="$work/sweep-%A_%a.out" \
  "$here/jobs/slurm/sweep.sbatch" "$work/sweep" --synthetic small --rounds 30)
echo "test_one_node: submitted sweep array $array"
for i in 0 1; do wait_state "${array}_$i" 'COMPLETED|FAILED|CANCELLED' 300; done
for v in 100 200; do
  [ -f "$work/sweep/dims-per-round-$v/model.bin" ] || fail "sweep value $v has no model"
  grep -q "dims_per_round = $v" "$work/sweep/dims-per-round-$v/config.toml" || fail "sweep value $v not applied"
done
echo "test_one_node: sweep OK"

# 3. Every area of a tiny world as a job array; one task killed, rerun alone, every model identical.
tiny=$work/tiny
"$lboost" world --preset tiny --seed 1 --out "$tiny/collection" > "$work/tiny.log" 2>&1 || fail "lboost world"
"$lboost" map --collection "$tiny/collection" --out "$tiny/map.h5" >> "$work/tiny.log" 2>&1 || fail "lboost map"
"$lboost" vocab --words 16 --max-descriptors 20000 --images "$tiny/collection/images" --seed 7 \
  --out "$tiny/vocab.lbv" >> "$work/tiny.log" 2>&1 || fail "lboost vocab"
"$lboost" areas --map "$tiny/map.h5" --out "$tiny/areas.txt" --min-observations 3 --max-classes 1000 \
  --overlap 0.2 >> "$work/tiny.log" 2>&1 || fail "lboost areas: $(tail -n 3 "$work/tiny.log")"
num_areas=$(awk '$1 == "areas" { print $2; exit }' "$tiny/areas.txt")
[ "$num_areas" -ge 3 ] || fail "expected >= 3 areas of the tiny world, got $num_areas"
killed=1
area_args=(--map "$tiny/map.h5" --vocab "$tiny/vocab.lbv" --rounds "${LMB_TEST_AREA_ROUNDS:-100}" \
  --dims-per-round 64 --checkpoint-interval 20)
for ((id = 0; id < num_areas; id++)); do
  "$lboost" train "${area_args[@]}" --area "$tiny/areas.txt:$id" --out "$work/area-reference/area-$id" \
    > "$work/area-reference-$id.log" 2>&1 || fail "reference run of area $id"
done
areas_array=$(LMB_REPO=$here LBOOST=$lboost sbatch --parsable --array=0-$((num_areas - 1)) \
  --output="$work/areas-%A_%a.out" "$here/jobs/slurm/train_areas.sbatch" "$tiny/areas.txt" "$work/areas" \
  "${area_args[@]}")
echo "test_one_node: submitted areas array $areas_array ($num_areas areas)"
# Kill task $killed for real once it has checkpointed and trained on past that checkpoint.
metrics=$work/areas/area-$killed/metrics.jsonl
for _ in $(seq 3000); do
  [ -f "$metrics" ] && [ "$(wc -l < "$metrics")" -ge 30 ] &&
    compgen -G "$work/areas/area-$killed/checkpoints/ckpt-*.h5" > /dev/null && break
  sleep 0.2
done
{ [ -f "$metrics" ] && [ "$(wc -l < "$metrics")" -ge 30 ]; } || fail "area $killed did not get past its first checkpoint"
# For real: SIGKILL to every process of the task at once (batch shell, srun, the ranks), as a crash
# would; nothing checkpoints or requeues on the way out. (scancel --signal=KILL cancels the job:
# SIGTERM first, and the ranks checkpoint and requeue.)
task_job=$(scontrol show job "${areas_array}_$killed" | grep -o '^JobId=[0-9]*' | cut -d= -f2)
mapfile -t pids < <(scontrol listpids "$task_job" | awk 'NR > 1 && $1 ~ /^[0-9]+$/ { print $1 }')
[ "$(ps -o comm= -p "$(IFS=,; echo "${pids[*]}")" | grep -c '^lboost$')" -eq 2 ] ||
  fail "task ${areas_array}_$killed (job $task_job): its 2 lboost ranks are not among its processes ${pids[*]}"
echo "test_one_node: killing task ${areas_array}_$killed (job $task_job, processes ${pids[*]}) after $(wc -l < "$metrics") rounds"
kill -KILL "${pids[@]}"
ended='COMPLETED|FAILED|CANCELLED|TIMEOUT|NODE_FAIL|OUT_OF_MEMORY'
for ((id = 0; id < num_areas; id++)); do
  if [ "$id" -eq "$killed" ]; then
    wait_state "${areas_array}_$id" "$ended|PENDING|REQUEUED" 120
    s=$(state_of "${areas_array}_$id")
    [ "$s" = FAILED ] || fail "the killed task ${areas_array}_$id is $s, expected FAILED"
    [ ! -f "$work/areas/area-$id/model.bin" ] || fail "the killed task wrote a model (killed too late)"
  else
    wait_state "${areas_array}_$id" "$ended" 600
    s=$(state_of "${areas_array}_$id")
    [ "$s" = COMPLETED ] || fail "task ${areas_array}_$id ended $s"
  fi
done
echo "test_one_node: task ${areas_array}_$killed ended $(state_of "${areas_array}_$killed"), the others COMPLETED"
rerun=$(LMB_REPO=$here LBOOST=$lboost sbatch --parsable --array="$killed" \
  --output="$work/areas-%A_%a.out" "$here/jobs/slurm/train_areas.sbatch" "$tiny/areas.txt" "$work/areas" \
  "${area_args[@]}")
echo "test_one_node: rerunning area $killed alone as ${rerun}_$killed"
wait_state "${rerun}_$killed" "$ended" 600
[ "$(state_of "${rerun}_$killed")" = COMPLETED ] || fail "the rerun ${rerun}_$killed ended $(state_of "${rerun}_$killed")"
resumed=$(grep -o 'resumed from [^ ]*' "$work/areas/area-$killed/log.txt" | head -n 1)
[ -n "$resumed" ] || fail "the rerun of area $killed did not resume from a checkpoint"
for ((id = 0; id < num_areas; id++)); do
  cmp "$work/areas/area-$id/model.bin" "$work/area-reference/area-$id/model.bin" ||
    fail "area $id: the job array's model differs from the uninterrupted run's"
done
echo "test_one_node: areas array OK (area $killed killed, rerun $resumed), $num_areas models identical"
echo "test_one_node: PASS"
