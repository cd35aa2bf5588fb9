// lboost train: trains the shared-stump classifier of a landmark map (single process; the MPI
// layer of issue #5 wraps the same learner).
//   lboost train --map map.h5 --vocab vocab.lbv --out RUN_DIR [--config cfg.toml] [--rounds N]
//                [--dims-per-round N] [--top-k N] [--seed S] [--threads N]
// Writes RUN_DIR/config.toml (effective config), log.txt, metrics.jsonl (one line per round) and
// model.bin (train/boost/boost_model.h: cereal portable binary in the "LMBBOOST" container) and
// summary.json (final validation P@1 next to the Hamming nearest-neighbour baseline).
#include <chrono>
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
#include "common/hamming.h"
#include "common/file_container.h"
#include "common/io/map_h5.h"
#include "common/vocabulary.h"
#include "train/boost/round_log.h"
#include "train/boost/stump_learner.h"
#include "train/boost/train_config.h"
#include "train/boost/training_set.h"
#include "train/cli/commands.h"
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
};

// Precision@1 of exact Hamming nearest-neighbour matching (descriptor only) of the held-out
// observations against every training sample's descriptor: the baseline the classifier must beat.
double hamming_nn_validation_p1(const LandmarkMap& map, const TrainingSet& set) {
  std::vector<int64_t> train, validation;
  for (int64_t s = 0; s < set.num_samples(); ++s) {
    (set.sample_is_validation[s] ? validation : train).push_back(s);
  }
  if (validation.empty()) return -1.0;
  int64_t correct = 0;
  for (int64_t v : validation) {
    const uint8_t* q = map.descriptor(set.sample_keypoint[v]);
    int best = 1 << 30;
    int32_t best_class = -1;
    for (int64_t s : train) {
      const int d = hamming_distance(q, map.descriptor(set.sample_keypoint[s]), map.descriptor_bytes);
      if (d < best) {
        best = d;
        best_class = set.sample_class[s];
      }
    }
    correct += best_class == set.sample_class[v];
  }
  return static_cast<double>(correct) / static_cast<double>(validation.size());
}

void run_train(const TrainArgs& a) {
  TrainConfig config = a.config.empty() ? TrainConfig() : read_train_config(a.config);
  if (a.rounds) config.boost.num_rounds = *a.rounds;
  if (a.dims_per_round) config.boost.dims_per_round = *a.dims_per_round;
  if (a.top_k) config.training_set.top_k_landmarks = *a.top_k;
  if (a.seed) config.boost.seed = config.training_set.seed = *a.seed;
  if (a.threads) config.feature_threads = *a.threads;
  config.check();

  const std::filesystem::path run_dir(a.out);
  std::filesystem::create_directories(run_dir);
  LMB_CHECK(std::filesystem::is_directory(run_dir), "--out " << a.out << ": not a folder");
  const std::string config_text = train_config_toml(config);
  write_file_atomically(run_dir / "config.toml", config_text.data(), config_text.size());

  // Log to the console and RUN_DIR/log.txt for the duration of the command.
  auto previous = spdlog::default_logger();
  auto console = std::make_shared<spdlog::sinks::stdout_color_sink_mt>();
  auto file = std::make_shared<spdlog::sinks::basic_file_sink_mt>((run_dir / "log.txt").string(), true);
  auto logger = std::make_shared<spdlog::logger>("train", spdlog::sinks_init_list{console, file});
  logger->set_pattern("[%H:%M:%S] %v");
  spdlog::set_default_logger(logger);
  struct Restore {
    std::shared_ptr<spdlog::logger> logger;
    ~Restore() { spdlog::set_default_logger(logger); }
  } restore{previous};

  const auto t0 = std::chrono::steady_clock::now();
  const LandmarkMap map = read_map_h5(a.map);
  const Vocabulary vocabulary = Vocabulary::load(a.vocab);
  const std::vector<uint8_t> words8 = keypoint_words(map, vocabulary, config.feature_threads);
  const std::vector<int32_t> words(words8.begin(), words8.end());
  const TrainingSet set = build_training_set(map, words, config.training_set);
  int64_t validation = 0, background = 0;
  for (int64_t s = 0; s < set.num_samples(); ++s) {
    validation += set.sample_is_validation[s];
    background += set.sample_class[s] == set.background_class();
  }
  spdlog::info("train: {} classes, {} samples ({} held out, {} background) from {}", set.num_classes,
               set.num_samples(), validation, background, a.map);
  const ContextRegions regions(config.regions);
  FeatureBuildOptions feature_options;
  feature_options.num_threads = config.feature_threads;
  const FeatureMatrix features =
      build_training_features(map, regions, vocabulary, set.sample_keypoint, feature_options);
  spdlog::info("train: features {} samples x {} dims ({:.1f} MB) in {:.1f} s", features.num_samples,
               features.num_dims, static_cast<double>(features.data.size()) / 1048576.0,
               std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());

  const double hamming_p1 = hamming_nn_validation_p1(map, set);
  spdlog::info("train: Hamming nearest-neighbour baseline, validation P@1 {:.4f}", hamming_p1);
  SerialStumpLearner learner(features, set, config.boost);
  RoundLogger round_log(run_dir / "metrics.jsonl", config.boost.num_rounds);
  double seconds = 0.0;
  learner.train([&](const RoundStats& s) {
    round_log.log(s);
    seconds += s.seconds;
  });
  save_boost_model(run_dir / "model.bin", learner.model());
  nlohmann::json summary;
  summary["classes"] = set.num_classes;
  summary["samples"] = set.num_samples();
  summary["validation_samples"] = validation;
  summary["dims"] = features.num_dims;
  summary["rounds"] = learner.rounds_done();
  summary["validation_p1"] = learner.validation_precision();
  summary["validation_p1_landmarks"] = learner.validation_precision(true);
  summary["hamming_nn_validation_p1"] = hamming_p1;
  summary["seconds_per_round"] = seconds / std::max(1, learner.rounds_done());
  const std::string summary_text = summary.dump(2) + "\n";
  write_file_atomically(run_dir / "summary.json", summary_text.data(), summary_text.size());
  spdlog::info("train: {} stumps written to {}", learner.model().stumps.size(), (run_dir / "model.bin").string());
}

}  // namespace

void add_train_command(CLI::App& app) {
  auto args = std::make_shared<TrainArgs>();
  auto* cmd = app.add_subcommand("train", "Train the shared-stump landmark classifier of a map");
  cmd->add_option("--map", args->map, "map file (lboost map)")->required()->check(CLI::ExistingFile);
  cmd->add_option("--vocab", args->vocab, "vocabulary file (lboost vocab)")->required()->check(CLI::ExistingFile);
  cmd->add_option("--out", args->out, "run folder: config.toml, log.txt, metrics.jsonl, model.bin")->required();
  cmd->add_option("--config", args->config, "TOML config ([training_set], [boost], [regions], [features])")
      ->check(CLI::ExistingFile);
  cmd->add_option("--rounds", args->rounds, "boost.num_rounds");
  cmd->add_option("--dims-per-round", args->dims_per_round, "boost.dims_per_round (|F_m|, at most the feature dimension)");
  cmd->add_option("--top-k", args->top_k, "training_set.top_k_landmarks");
  cmd->add_option("--seed", args->seed, "boost.seed and training_set.seed");
  cmd->add_option("--threads", args->threads, "features.threads (feature building only)");
  cmd->callback([args] { run_train(*args); });
}

}  // namespace lmb::cli
