#include "train/dist/training_job.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include <spdlog/spdlog.h>

#include "common/error.h"
#include "common/machine_info.h"
#include "train/dist/stop_signal.h"

namespace lmb {

namespace {
using Clock = std::chrono::steady_clock;
double since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

void agree(Communicator& comm, const std::function<void()>& fn) {
  std::string error;
  if (comm.rank() == 0) {
    try {
      fn();
    } catch (const Error& e) {
      error = e.what();
    }
  }
  comm.broadcast_string(&error, 0);
  if (error.empty()) return;
  if (comm.rank() == 0) throw AgreedError(error);
  throw AgreedError("rank " + std::to_string(comm.rank()) + ": stopped with rank 0");
}
}  // namespace

void agree_on_rank0(Communicator& comm, const std::function<void()>& fn) { agree(comm, fn); }

void check_resume_feature_space(Communicator& comm, const TrainingJobOptions& options,
                                const std::optional<Checkpoint>& resume) {
  if (!resume) return;
  agree(comm, [&] {
    const std::string diff = feature_space_difference(resume->feature_space, options.feature_space);
    LMB_CHECK(diff.empty(), CheckpointDir(options.run_dir).path_for(resume->rounds).string()
                                << ": cannot resume: " << diff
                                << "; give the --map and --vocab of the run, or use another --out folder");
  });
}

std::optional<Checkpoint> find_resume_checkpoint(Communicator& comm, const TrainingJobOptions& options) {
  const CheckpointDir dir(options.run_dir);
  std::optional<Checkpoint> found;
  std::string path;
  agree(comm, [&] {
    found = dir.newest_valid([](const std::filesystem::path& p, const std::string& why) {
      spdlog::warn("train: skipping checkpoint {}: {}", p.string(), why);
    });
    if (!found) return;
    const std::string diff = config_difference(found->config, options.config_toml);
    LMB_CHECK(diff.empty(), dir.path_for(found->rounds).string()
                                << ": the config differs from the checkpoint's in " << diff
                                << "; use the same settings or another --out folder");
    LMB_CHECK(found->data == options.data, dir.path_for(found->rounds).string()
                                               << ": trained on '" << found->data << "', this run uses '"
                                               << options.data << "'; use another --out folder");
    path = dir.path_for(found->rounds).string();
  });
  comm.broadcast_string(&path, 0);
  if (comm.rank() != 0 && !path.empty()) found = read_checkpoint(path);
  return found;
}

TrainingJobResult run_training_job(Communicator& comm, FeatureParallelLearner& learner,
                                   const TrainingJobOptions& options, const std::optional<Checkpoint>& resume,
                                   const std::function<void(const RoundStats&)>& on_round) {
  LMB_CHECK(options.checkpoint_interval >= 0, "checkpoint.interval must be >= 0, got " << options.checkpoint_interval);
  LMB_CHECK(std::isfinite(options.checkpoint_minutes) && options.checkpoint_minutes >= 0.0,
            "checkpoint.minutes must be finite and >= 0, got " << options.checkpoint_minutes);
  LMB_CHECK(options.checkpoint_keep >= 1, "checkpoint.keep must be >= 1, got " << options.checkpoint_keep);
  TrainingJobResult result;
  if (resume) {
    learner.restore_state(resume->state);
    result.resumed_from = resume->rounds;
    if (comm.rank() == 0) {
      spdlog::info("train: resumed from {} ({} rounds, written by {} rank(s)), now {} rank(s)",
                   CheckpointDir(options.run_dir).path_for(resume->rounds).string(), resume->rounds, resume->ranks,
                   comm.size());
    }
  }
  const CheckpointDir dir(options.run_dir);
  auto checkpoint = [&] {
    const auto t0 = Clock::now();
    // Collective: every rank's tracked rows go to rank 0, which writes.
    LearnerState state = learner.save_state();
    agree(comm, [&] {
      Checkpoint ck;
      ck.rounds = learner.rounds_done();
      ck.seed = learner.options().seed;
      ck.ranks = comm.size();
      ck.config = options.config_toml;
      ck.data = options.data;
      ck.feature_space = options.feature_space;
      ck.state = std::move(state);
      const auto path = dir.write(ck, options.checkpoint_keep);
      spdlog::info("train: checkpoint {} written in {:.2f} s", path.string(), since(t0));
    });
    result.checkpoint_seconds += since(t0);
    ++result.checkpoints_written;
  };
  install_stop_signal_handlers();
  const int64_t sent0 = comm.bytes_sent(), received0 = comm.bytes_received();
  const auto t0 = Clock::now();
  const double cpu0 = cpu_seconds();
  double checkpoint_time = 0.0, checkpoint_cpu = 0.0;
  auto last_checkpoint = t0;
  // One allreduce a round: 2 = a stop was requested on some rank, 1 = rank 0's clock says a
  // checkpoint is due.
  constexpr int64_t kStop = 2, kDue = 1;
  while (learner.rounds_done() < learner.options().num_rounds) {
    const RoundStats stats = learner.run_round();
    ++result.rounds_run;
    if (comm.rank() == 0 && on_round) on_round(stats);
    int64_t flag = stop_signal_received() != 0 ? kStop : 0;
    if (comm.rank() == 0 && options.checkpoint_minutes > 0.0 &&
        since(last_checkpoint) >= 60.0 * options.checkpoint_minutes)
      flag = std::max(flag, kDue);
    const int64_t agreed = comm.allreduce_max(flag);
    const bool stop = agreed == kStop;
    const int32_t done = learner.rounds_done();
    const bool last = done == learner.options().num_rounds;
    if (stop || last || agreed == kDue ||
        (options.checkpoint_interval > 0 && done % options.checkpoint_interval == 0)) {
      const double before = result.checkpoint_seconds, cpu_before = cpu_seconds();
      checkpoint();
      checkpoint_time += result.checkpoint_seconds - before;
      checkpoint_cpu += cpu_seconds() - cpu_before;
      last_checkpoint = Clock::now();
    }
    if (stop && !last) {
      if (comm.rank() == 0)
        spdlog::warn("train: stop requested by a signal after round {}: checkpointed, exiting for a requeue", done);
      result.stopped = true;
      break;
    }
  }
  result.round_seconds = since(t0) - checkpoint_time;
  result.round_cpu_seconds = cpu_seconds() - cpu0 - checkpoint_cpu;
  result.bytes_sent = comm.bytes_sent() - sent0;
  result.bytes_received = comm.bytes_received() - received0;
  return result;
}

}  // namespace lmb
