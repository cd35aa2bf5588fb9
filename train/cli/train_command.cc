// lboost train: trains the shared-stump classifier of a landmark map, on one process or on MPI
// ranks (`mpirun -n R lboost train ...`, `srun --mpi=pmix lboost train ...`; train/dist/).
//   lboost train --map map.h5 --vocab vocab.lbv --out RUN_DIR [--config cfg.toml] [--rounds N]
//                [--dims-per-round N] [--top-k N] [--seed S] [--threads N]
//                [--checkpoint-minutes M] [--checkpoint-interval N] [--checkpoint-keep K]
//                [--area AREAS_FILE:ID] [--calibration-folds K]
//   lboost train --synthetic small|medium|paper --out RUN_DIR ...   (synthetic problem of
//                train/boost/synthetic_problem.h instead of a map: tests, job tests, benchmarks)
// The run itself: train/dist/run_training.h (rank 0 locks RUN_DIR; a run resumes from the newest
// valid checkpoint of RUN_DIR; after SIGTERM / SIGUSR1 it checkpoints and exits with code 75,
// requeue; a refused run leaves RUN_DIR exactly as it was).
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <new>
#include <optional>
#include <stdexcept>
#include <string>

#include <spdlog/spdlog.h>

#include "common/error.h"
#include "common/file_io.h"
#include "common/machine_info.h"
#include "train/areas/area_training.h"
#include "train/boost/train_config.h"
#include "train/cli/commands.h"
#include "train/dist/communicator.h"
#include "train/dist/run_training.h"
#include "train/dist/stop_signal.h"
#include "train/dist/training_job.h"
#include "train/eval/run_export.h"

namespace lmb::cli {

namespace {

struct TrainArgs {
  std::string map;
  std::string vocab;
  std::string out;
  std::string config;
  std::optional<int32_t> rounds;
  std::optional<int32_t> dims_per_round;
  std::optional<int32_t> top_k;
  std::optional<uint64_t> seed;
  std::optional<int> threads;
  std::optional<int32_t> augment_copies;
  std::optional<double> checkpoint_minutes;
  std::optional<int32_t> checkpoint_interval;
  std::optional<int32_t> checkpoint_keep;
  std::optional<int32_t> calibration_folds;
  std::string synthetic;
  std::string area;  // --area FILE:ID
};

void run_train(const TrainArgs& a) {
  // --out is the run folder, which train reads on resume and writes into: nothing else it reads may
  // lie in it, except the run's own config.toml given back as --config (train rewrites that file as
  // the run's effective config).
  const std::string area_file = a.area.substr(0, std::min(a.area.size(), a.area.rfind(':')));
  const bool own_config = !a.config.empty() && same_file(a.config, std::filesystem::path(a.out) / "config.toml");
  check_outputs_not_inputs({{a.out, "--out", true}}, {{a.map, "--map"},
                                                      {a.vocab, "--vocab"},
                                                      {own_config ? std::string() : a.config, "--config"},
                                                      {area_file, "--area"}});
  TrainConfig config = a.config.empty() ? TrainConfig() : read_train_config(a.config);
  if (a.rounds) config.boost.num_rounds = *a.rounds;
  if (a.dims_per_round) config.boost.dims_per_round = *a.dims_per_round;
  if (a.top_k) config.training_set.top_k_landmarks = *a.top_k;
  if (a.seed) config.boost.seed = config.training_set.seed = *a.seed;
  if (a.threads) config.feature_threads = *a.threads;
  if (a.augment_copies) config.augment.copies = *a.augment_copies;
  if (a.checkpoint_minutes) config.checkpoint_minutes = *a.checkpoint_minutes;
  if (a.checkpoint_interval) config.checkpoint_interval = *a.checkpoint_interval;
  if (a.checkpoint_keep) config.checkpoint_keep = *a.checkpoint_keep;
  if (a.calibration_folds) config.training_set.calibration_folds = *a.calibration_folds;
  if (!a.area.empty()) {
    LMB_CHECK(a.synthetic.empty(), "--area trains an area of a map: give --map, not --synthetic");
    config.area = make_area_reference(a.area, "--area");
    // An area's model is calibrated within its bundle (lboost bundle), on the areas' held-out frames.
    config.training_set.calibration_folds = 0;
  }
  LMB_CHECK(!config.area.set() || a.synthetic.empty(),
            a.config << ": [area] trains an area of a map: give --map, not --synthetic");
  config.check();

  // From the start, not only once training runs: a SIGTERM / SIGUSR1 while the ranks load the
  // data (minutes at paper scale) stops the job after its first round with a checkpoint and exit
  // code 75 (requeue) instead of killing the rank (scripts/fault_inject.sh, case sigterm_load).
  install_stop_signal_handlers();
  MpiSession mpi;
  Communicator comm = Communicator::world(mpi);
  std::string step = "starting";
  try {
    try {
      TrainRunInputs in;
      in.map = a.map;
      in.vocab = a.vocab;
      in.config = a.config;
      in.run_dir = a.out;
      in.synthetic = a.synthetic;
      int32_t folds = 0;
      if (!train_on_ranks(in, config, comm, &step, &folds)) throw CommandExit{kRequeueExitCode};
      // Cross-fitting (a map too small to hold calibration frames out): the model first, then one fold
      // model a fold of the frames, each its own resumable run in RUN/folds/k (a finished one
      // resumes at its end). `folds` is 0 for a run that is itself a fold model.
      for (int32_t k = 0; k < folds; ++k) {
        TrainConfig fold = config;
        fold.training_set.calibration_folds = folds;  // at most one a map frame
        fold.training_set.calibration_fold = k;
        TrainRunInputs fold_in = in;
        fold_in.config.clear();
        fold_in.run_dir = fold_run_dir(a.out, k).string();
        if (comm.rank() == 0) {
          spdlog::info("train: fold model {} of {} (held out: one map frame in {} from position {}) -> {}", k + 1,
                       folds, folds, k, fold_in.run_dir);
        }
        if (!train_on_ranks(fold_in, fold, comm, &step)) throw CommandExit{kRequeueExitCode};
      }
    } catch (const std::bad_alloc&) {
      LMB_FAIL("out of memory while " << step << " (" << memory_info().summary() << " on this machine)");
    } catch (const std::length_error& e) {
      LMB_FAIL("out of memory while " << step << ": a size beyond what can be allocated (" << e.what() << ")");
    }
  } catch (const CommandExit&) {
    throw;
  } catch (const AgreedError&) {
    // Every rank stops together; rank 0 prints the one line, the others end quietly.
    if (comm.rank() != 0) throw CommandExit{1};
    throw;
  } catch (const std::exception& e) {
    if (!comm.distributed()) throw;
    // One rank failed alone: the others may be waiting in a collective, so end the whole job.
    std::fprintf(stderr, "lboost train: rank %d of %d: error: %s\n", comm.rank(), comm.size(),
                 one_line(e.what()).c_str());
    std::fflush(stderr);
    comm.abort(1);
  }
}

}  // namespace

void add_train_command(CLI::App& app) {
  auto args = std::make_shared<TrainArgs>();
  auto* cmd = app.add_subcommand("train", "Train the shared-stump landmark classifier of a map");
  auto* map = cmd->add_option("--map", args->map, "map file (lboost map)")->check(CLI::ExistingFile);
  auto* vocab = cmd->add_option("--vocab", args->vocab, "vocabulary file (lboost vocab)")->check(CLI::ExistingFile);
  cmd->add_option("--synthetic", args->synthetic,
                  "train on a synthetic problem instead of a map: small, medium or paper (7,500 classes x "
                  "16,896 dims; train/boost/synthetic_problem.h)")
      ->excludes(map)
      ->excludes(vocab);
  cmd->add_option("--out", args->out, "run folder: config.toml, log.txt, metrics.jsonl, model.bin")->required();
  cmd->add_option("--config", args->config, "TOML config ([training_set], [boost], [regions], [augment], [features])")
      ->check(CLI::ExistingFile);
  // The flags' help: the config key they set, its help and default (train/boost/train_config.h).
  auto key = [](const char* name) { return std::string(name) + ": " + describe_config_key(name); };
  cmd->add_option("--rounds", args->rounds, key("boost.num_rounds"));
  cmd->add_option("--dims-per-round", args->dims_per_round,
                  key("boost.dims_per_round") + ", at most the feature dimension");
  cmd->add_option("--top-k", args->top_k, key("training_set.top_k_landmarks"));
  cmd->add_option("--area", args->area,
                  "FILE:ID: train area ID of the areas file FILE (lboost areas): its landmarks are the classes "
                  "(recorded as [area] in config.toml and checked on resume)");
  add_seed_option(cmd, "--seed", &args->seed,
                  "boost.seed and training_set.seed (default " + std::to_string(TrainConfig().boost.seed) + ")");
  cmd->add_option("--threads", args->threads, key("features.threads"));
  cmd->add_option("--augment-copies", args->augment_copies, key("augment.copies"));
  cmd->add_option("--checkpoint-minutes", args->checkpoint_minutes, key("checkpoint.minutes"));
  cmd->add_option("--checkpoint-interval", args->checkpoint_interval, key("checkpoint.interval"));
  cmd->add_option("--checkpoint-keep", args->checkpoint_keep, key("checkpoint.keep"));
  cmd->add_option("--calibration-folds", args->calibration_folds,
                  key("training_set.calibration_folds") +
                      "; the fold models are trained after the model, into RUN_DIR/folds/0 .. K-1");
  cmd->callback([args] { run_train(*args); });
}

}  // namespace lmb::cli
