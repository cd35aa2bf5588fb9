// lboost train: trains the shared-stump classifier of a landmark map, on one process or on MPI
// ranks (`mpirun -n R lboost train ...`, `srun --mpi=pmix lboost train ...`; train/dist/).
//   lboost train --map map.h5 --vocab vocab.lbv --out RUN_DIR [--config cfg.toml] [--rounds N]
//                [--dims-per-round N] [--top-k N] [--seed S] [--threads N]
//                [--checkpoint-interval N] [--checkpoint-keep K]
//   lboost train --synthetic small|medium|paper --out RUN_DIR ...   (synthetic problem of
//                train/boost/synthetic_problem.h instead of a map: tests, job tests, benchmarks)
// Rank 0 writes RUN_DIR/config.toml (effective config), log.txt, metrics.jsonl (one line per
// round), checkpoints/ckpt-*.h5, model.bin (train/boost/boost_model.h: cereal portable binary in
// the "LMBBOOST" container) and summary.json (final validation P@1 next to the Hamming
// nearest-neighbour baseline; per-rank memory and communication). Each rank builds only the
// feature columns it owns. A run resumes from the newest valid checkpoint of RUN_DIR; after
// SIGTERM / SIGUSR1 it checkpoints and exits with code 75 (requeue).
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>
#include <optional>
#include <string>

#include <spdlog/sinks/basic_file_sink.h>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include "common/context_regions.h"
#include "common/error.h"
#include "common/file_container.h"
#include "common/hamming.h"
#include "common/io/map_h5.h"
#include "common/machine_info.h"
#include "common/vocabulary.h"
#include "train/boost/round_log.h"
#include "train/boost/stump_learner.h"
#include "train/boost/synthetic_problem.h"
#include "train/boost/train_config.h"
#include "train/boost/training_set.h"
#include "train/checkpoint/checkpoint_h5.h"
#include "train/cli/commands.h"
#include "train/dist/communicator.h"
#include "train/dist/dist_bench.h"
#include "train/dist/feature_parallel_learner.h"
#include "train/dist/stop_signal.h"
#include "train/dist/training_job.h"
#include "train/features/build_features.h"

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
  std::optional<int32_t> checkpoint_interval;
  std::optional<int32_t> checkpoint_keep;
  std::string synthetic;
};

// Precision@1 of exact Hamming nearest-neighbour matching (descriptor only) of the held-out
// observations against the training samples' descriptors: the baselines the classifier must beat.
// `all`: against every training sample, background included (compare with validation_p1, where
// the background class competes too); `landmarks`: against the landmark classes' samples only
// (compare with validation_p1_landmarks).
struct HammingBaseline {
  double all = -1.0;
  double landmarks = -1.0;
};
HammingBaseline hamming_nn_validation_p1(const LandmarkMap& map, const TrainingSet& set) {
  std::vector<int64_t> train, validation;
  for (int64_t s = 0; s < set.num_samples(); ++s) {
    (set.sample_is_validation[s] ? validation : train).push_back(s);
  }
  HammingBaseline out;
  if (validation.empty()) return out;
  const int bytes = map.descriptor_bytes;
  std::vector<uint8_t> rows(train.size() * static_cast<size_t>(bytes));
  for (size_t i = 0; i < train.size(); ++i) {
    std::memcpy(rows.data() + i * bytes, map.descriptor(set.sample_keypoint[train[i]]), static_cast<size_t>(bytes));
  }
  std::vector<uint16_t> dist(train.size());
  int64_t correct_all = 0, correct_landmarks = 0;
  for (int64_t v : validation) {
    hamming_rows(map.descriptor(set.sample_keypoint[v]), rows.data(), static_cast<int64_t>(train.size()), bytes,
                 dist.data());
    int best_all = 1 << 30, best_landmark = 1 << 30;
    int32_t class_all = -1, class_landmark = -1;
    for (size_t i = 0; i < train.size(); ++i) {
      const int d = dist[i];
      const int32_t c = set.sample_class[train[i]];
      if (d < best_all) {
        best_all = d;
        class_all = c;
      }
      if (c != set.background_class() && d < best_landmark) {
        best_landmark = d;
        class_landmark = c;
      }
    }
    correct_all += class_all == set.sample_class[v];
    correct_landmarks += class_landmark == set.sample_class[v];
  }
  const double n = static_cast<double>(validation.size());
  out.all = static_cast<double>(correct_all) / n;
  out.landmarks = static_cast<double>(correct_landmarks) / n;
  return out;
}

// The training data of this rank: the set (replicated) and the feature columns it owns.
struct RankData {
  TrainingSet set;
  FeatureMatrix features;
  std::string source;  // checked on resume
  HammingBaseline hamming;
};

SyntheticBoostOptions synthetic_preset(const std::string& name) {
  SyntheticBoostOptions o;
  if (name == "small") return o;
  if (name == "medium") {
    o.num_classes = 1000;
    o.num_background = 2000;
    o.context_dims = 4096;
    o.descriptor_bits = 256;
    o.signature_dims = 16;
    return o;
  }
  if (name == "paper") return paper_shape_synthetic_options();
  LMB_FAIL("--synthetic: unknown preset '" << name << "' (small, medium, paper)");
}

RankData load_rank_data(const TrainArgs& a, const TrainConfig& config, const Communicator& comm) {
  RankData d;
  const auto t0 = std::chrono::steady_clock::now();
  if (!a.synthetic.empty()) {
    SyntheticBoostProblem p = make_synthetic_boost_problem(synthetic_preset(a.synthetic));
    d.set = std::move(p.set);
    d.features = comm.distributed() ? keep_rank_columns(std::move(p.features), comm.rank(), comm.size())
                                    : std::move(p.features);
    d.source = "synthetic:" + a.synthetic;
  } else {
    LMB_CHECK(!a.map.empty() && !a.vocab.empty(), "--map and --vocab are required (or --synthetic)");
    const LandmarkMap map = read_map_h5(a.map);
    const Vocabulary vocabulary = Vocabulary::load(a.vocab);
    const std::vector<uint8_t> words8 = keypoint_words(map, vocabulary, config.feature_threads);
    const std::vector<int32_t> words(words8.begin(), words8.end());
    d.set = build_training_set(map, words, config.training_set);
    const ContextRegions regions(config.regions);
    FeatureBuildOptions feature_options;
    feature_options.num_threads = config.feature_threads;
    if (comm.distributed()) {
      feature_options.dims =
          rank_dims(embedding_layout(map, regions, vocabulary).num_dims(), comm.rank(), comm.size());
    }
    d.features = build_training_features(map, regions, vocabulary, d.set.sample_keypoint, feature_options);
    if (comm.rank() == 0) d.hamming = hamming_nn_validation_p1(map, d.set);
    d.source = std::filesystem::absolute(a.map).lexically_normal().string();
  }
  int64_t validation = 0, background = 0;
  for (int64_t s = 0; s < d.set.num_samples(); ++s) {
    validation += d.set.sample_is_validation[s];
    background += d.set.sample_class[s] == d.set.background_class();
  }
  spdlog::info("train: {} classes, {} samples ({} held out, {} background) from {}", d.set.num_classes,
               d.set.num_samples(), validation, background, d.source);
  spdlog::info("train: features {} samples x {} of {} dims on rank 0 of {} ({:.1f} MB) in {:.1f} s",
               d.features.num_samples, d.features.num_stored_columns(), d.features.num_dims, comm.size(),
               static_cast<double>(d.features.data.size()) / 1048576.0,
               std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  if (d.hamming.all >= 0.0) {
    spdlog::info("train: Hamming nearest-neighbour baseline, validation P@1 {:.4f} against every training "
                 "sample, {:.4f} against the landmark classes' samples only", d.hamming.all, d.hamming.landmarks);
  }
  return d;
}

void train_on_ranks(const TrainArgs& a, const TrainConfig& config, Communicator& comm) {
  const std::filesystem::path run_dir(a.out);
  const std::string config_text = train_config_toml(config);
  if (comm.rank() == 0) {
    std::filesystem::create_directories(run_dir);
    LMB_CHECK(std::filesystem::is_directory(run_dir), "--out " << a.out << ": not a folder");
    write_file_atomically(run_dir / "config.toml", config_text.data(), config_text.size());
  }
  comm.barrier();

  // Rank 0 logs to the console and RUN_DIR/log.txt; the other ranks print warnings and errors only.
  auto previous = spdlog::default_logger();
  auto console = std::make_shared<spdlog::sinks::stdout_color_sink_mt>();
  std::shared_ptr<spdlog::logger> logger;
  if (comm.rank() == 0) {
    auto file = std::make_shared<spdlog::sinks::basic_file_sink_mt>((run_dir / "log.txt").string(), false);
    logger = std::make_shared<spdlog::logger>("train", spdlog::sinks_init_list{console, file});
    logger->set_pattern("[%H:%M:%S] %v");
  } else {
    logger = std::make_shared<spdlog::logger>("train", console);
    logger->set_pattern("[%H:%M:%S] rank " + std::to_string(comm.rank()) + ": %v");
    logger->set_level(spdlog::level::warn);
  }
  logger->flush_on(spdlog::level::info);
  spdlog::set_default_logger(logger);
  struct Restore {
    std::shared_ptr<spdlog::logger> logger;
    ~Restore() { spdlog::set_default_logger(logger); }
  } restore{previous};
  if (comm.distributed()) spdlog::info("train: {} MPI ranks, feature-parallel", comm.size());

  TrainingJobOptions job;
  job.run_dir = run_dir;
  job.config_toml = config_text;
  job.checkpoint_interval = config.checkpoint_interval;
  job.checkpoint_keep = config.checkpoint_keep;
  job.data = a.synthetic.empty() ? std::filesystem::absolute(a.map).lexically_normal().string()
                                  : "synthetic:" + a.synthetic;
  const std::optional<Checkpoint> resume = find_resume_checkpoint(comm, job);

  const RankData data = load_rank_data(a, config, comm);
  FeatureParallelLearner learner(comm, data.features, data.set, config.boost);
  std::optional<RoundLogger> round_log;
  if (comm.rank() == 0) round_log.emplace(run_dir / "metrics.jsonl", config.boost.num_rounds);
  const TrainingJobResult r = run_training_job(comm, learner, job, resume, [&](const RoundStats& s) { round_log->log(s); });

  // Per-rank figures for the summary.
  const int64_t max_rss_kb = comm.allreduce_max(static_cast<int64_t>(peak_rss_mb() * 1024.0));
  const int64_t total_sent = comm.allreduce_sum(r.bytes_sent);
  const int64_t max_rss_end_kb = comm.allreduce_max(static_cast<int64_t>(current_rss_mb() * 1024.0));
  const int64_t max_cpu_us = comm.allreduce_max(static_cast<int64_t>(r.round_cpu_seconds * 1e6));
  const double validation_p1 = learner.validation_precision();  // collective
  const double validation_p1_landmarks = learner.validation_precision(true);
  if (r.stopped) throw CommandExit{kRequeueExitCode};
  if (comm.rank() != 0) return;
  save_boost_model(run_dir / "model.bin", learner.model());
  nlohmann::json summary;
  summary["classes"] = data.set.num_classes;
  summary["samples"] = data.set.num_samples();
  summary["dims"] = data.features.num_dims;
  summary["data"] = data.source;
  summary["rounds"] = learner.rounds_done();
  summary["ranks"] = comm.size();
  summary["machine"] = machine_info().summary();
  summary["resumed_from_round"] = r.resumed_from;
  summary["validation_p1"] = validation_p1;
  summary["validation_p1_landmarks"] = validation_p1_landmarks;
  summary["hamming_nn_validation_p1"] = data.hamming.all;
  summary["hamming_nn_validation_p1_landmarks"] = data.hamming.landmarks;
  const int32_t n = std::max(1, r.rounds_run);
  summary["seconds_per_round"] = r.round_seconds / n;
  // CPU time of the slowest rank: the wall time on idle cores (ranks meet every round), and fair
  // when the machine is shared.
  summary["cpu_seconds_per_round_max_rank"] = static_cast<double>(max_cpu_us) / 1e6 / n;
  summary["checkpoint_seconds"] = r.checkpoint_seconds;
  summary["peak_rss_mb_rank0"] = peak_rss_mb();
  summary["peak_rss_mb_max_rank"] = static_cast<double>(max_rss_kb) / 1024.0;
  summary["rss_mb_end_max_rank"] = static_cast<double>(max_rss_end_kb) / 1024.0;
  summary["feature_mb_rank0"] = static_cast<double>(data.features.data.size()) / 1048576.0;
  summary["bytes_sent_per_round_all_ranks"] = static_cast<double>(total_sent) / n;
  summary["bytes_sent_per_round_rank0"] = static_cast<double>(r.bytes_sent) / n;
  summary["bytes_received_per_round_rank0"] = static_cast<double>(r.bytes_received) / n;
  const std::string summary_text = summary.dump(2) + "\n";
  write_file_atomically(run_dir / "summary.json", summary_text.data(), summary_text.size());
  spdlog::info("train: {} stumps written to {}", learner.model().stumps.size(), (run_dir / "model.bin").string());
}

void run_train(const TrainArgs& a) {
  TrainConfig config = a.config.empty() ? TrainConfig() : read_train_config(a.config);
  if (a.rounds) config.boost.num_rounds = *a.rounds;
  if (a.dims_per_round) config.boost.dims_per_round = *a.dims_per_round;
  if (a.top_k) config.training_set.top_k_landmarks = *a.top_k;
  if (a.seed) config.boost.seed = config.training_set.seed = *a.seed;
  if (a.threads) config.feature_threads = *a.threads;
  if (a.checkpoint_interval) config.checkpoint_interval = *a.checkpoint_interval;
  if (a.checkpoint_keep) config.checkpoint_keep = *a.checkpoint_keep;
  config.check();

  // From the start, not only once training runs: a SIGTERM / SIGUSR1 while the ranks load the
  // data (minutes at paper scale) stops the job after its first round with a checkpoint and exit
  // code 75 (requeue) instead of killing the rank (scripts/fault_inject.sh, case sigterm_load).
  install_stop_signal_handlers();
  MpiSession mpi;
  Communicator comm = Communicator::world(mpi);
  try {
    train_on_ranks(a, config, comm);
  } catch (const CommandExit&) {
    throw;
  } catch (const AgreedError&) {
    throw;  // every rank stops together
  } catch (const std::exception& e) {
    if (!comm.distributed()) throw;
    // One rank failed alone: the others may be waiting in a collective, so end the whole job.
    std::fprintf(stderr, "lboost train: rank %d of %d: error: %s\n", comm.rank(), comm.size(), e.what());
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
  cmd->add_option("--config", args->config, "TOML config ([training_set], [boost], [regions], [features])")
      ->check(CLI::ExistingFile);
  // The flags' help: the config key they set, its help and default (train/boost/train_config.h).
  auto key = [](const char* name) { return std::string(name) + ": " + describe_config_key(name); };
  cmd->add_option("--rounds", args->rounds, key("boost.num_rounds"));
  cmd->add_option("--dims-per-round", args->dims_per_round, key("boost.dims_per_round") + ", at most the feature dimension");
  cmd->add_option("--top-k", args->top_k, key("training_set.top_k_landmarks"));
  cmd->add_option("--seed", args->seed, "boost.seed and training_set.seed (default " +
                                            std::to_string(TrainConfig().boost.seed) + ")");
  cmd->add_option("--threads", args->threads, key("features.threads"));
  cmd->add_option("--checkpoint-interval", args->checkpoint_interval, key("checkpoint.interval"));
  cmd->add_option("--checkpoint-keep", args->checkpoint_keep, key("checkpoint.keep"));
  cmd->callback([args] { run_train(*args); });
}

}  // namespace lmb::cli
