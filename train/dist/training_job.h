// The training loop of `lboost train` on one or many ranks: resume from the newest valid
// checkpoint, rounds, periodic checkpoints, and the stop-on-signal protocol.
//
// Resume: rank 0 picks the newest checkpoint of RUN_DIR/checkpoints that reads back whole
// (torn or corrupt newer ones are reported through the log and skipped), refuses it when the
// compared settings or the data source differ (the error names the setting), and broadcasts its
// path; every rank loads it. The checkpoint may come from any rank count.
//
// After every round the ranks allreduce the stop flag (SIGTERM / SIGUSR1, train/dist/stop_signal.h)
// together with rank 0's clock: when checkpoint_minutes of wall time have passed since the last
// checkpoint (or the start), every checkpoint_interval rounds, on a stop request and at the end
// rank 0 writes a checkpoint, keeping the newest checkpoint_keep. Which rounds get one does not
// change the trained model (a checkpoint only reads the state). A stop returns stopped = true
// (the command then exits with kRequeueExitCode).
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>

#include "common/error.h"
#include "train/checkpoint/checkpoint_h5.h"
#include "train/dist/communicator.h"
#include "train/dist/feature_parallel_learner.h"

namespace lmb {

// An error every rank raised together (decided by rank 0 and broadcast): the ranks end normally,
// no MPI_Abort needed.
class AgreedError : public Error {
 public:
  using Error::Error;
};

// Collective. Rank 0 runs `fn`; an lmb::Error it throws is thrown on every rank as AgreedError:
// on rank 0 with its message, on the others as "rank R: stopped with rank 0".
void agree_on_rank0(Communicator& comm, const std::function<void()>& fn);

struct TrainingJobOptions {
  std::filesystem::path run_dir;
  std::string config_toml;          // the effective config (train/boost/train_config.h)
  std::string data;                 // the training data source, checked on resume
  FeatureSpace feature_space;       // what the stumps are trained on (rank 0), checked on resume
  double checkpoint_minutes = 0.0;  // wall minutes between checkpoints, by rank 0's clock; 0 = none by time
  int32_t checkpoint_interval = 0;  // rounds between checkpoints; 0 = none by rounds
  int32_t checkpoint_keep = 3;
};

struct TrainingJobResult {
  bool stopped = false;            // stopped on a signal after checkpointing
  int32_t resumed_from = 0;        // rounds done by the checkpoint resumed from (0 = fresh start)
  int32_t rounds_run = 0;          // rounds this process ran
  double round_seconds = 0.0;      // wall time of those rounds
  double round_cpu_seconds = 0.0;  // this process's CPU time in those rounds (checkpoints excluded)
  double checkpoint_seconds = 0.0;
  int32_t checkpoints_written = 0;
  int64_t bytes_sent = 0;  // this rank's communicated payload during the rounds
  int64_t bytes_received = 0;
};

// Collective. The checkpoint to resume from (nullopt: start afresh). Throws lmb::Error on every
// rank when the newest valid checkpoint does not fit the run (config or data differ).
std::optional<Checkpoint> find_resume_checkpoint(Communicator& comm, const TrainingJobOptions& options);

// Collective. Throws AgreedError on every rank when `resume` was trained in another feature space
// than options.feature_space (as rank 0 knows it): another vocabulary, map or regions.
void check_resume_feature_space(Communicator& comm, const TrainingJobOptions& options,
                                const std::optional<Checkpoint>& resume);

// Collective. Restores `resume` (if any) into the learner and trains to options().num_rounds or a
// stop. on_round runs on rank 0 only.
TrainingJobResult run_training_job(Communicator& comm, FeatureParallelLearner& learner,
                                   const TrainingJobOptions& options, const std::optional<Checkpoint>& resume,
                                   const std::function<void(const RoundStats&)>& on_round);

}  // namespace lmb
