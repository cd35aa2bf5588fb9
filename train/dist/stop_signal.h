// SIGTERM / SIGUSR1 as a request to checkpoint and stop: the handler only sets a flag; the
// training loop reads it after every round and the ranks agree through an allreduce, so all of
// them stop after the same round. Slurm sends SIGTERM to every task on preemption or time limit,
// and the job scripts forward --signal=B:USR1@N to the ranks.
#pragma once

namespace lmb {

// `lboost train` exits with this code (EX_TEMPFAIL) after a checkpoint requested by SIGTERM or
// SIGUSR1: the job scripts requeue the job on it.
inline constexpr int kRequeueExitCode = 75;

// Installs the handlers (idempotent). Other signals keep their default action.
void install_stop_signal_handlers();
// The signal that asked to stop (SIGTERM or SIGUSR1), 0 if none yet.
int stop_signal_received();
// Forgets a received signal (tests that stop a run and resume it in one process).
void clear_stop_signal();

}  // namespace lmb
