#include "train/dist/run_training.h"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <memory>
#include <mutex>
#include <optional>
#include <sstream>
#include <string>
#include <string_view>

#include <spdlog/sinks/base_sink.h>
#include <spdlog/sinks/ostream_sink.h>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>
#include <nlohmann/json.hpp>

#include "common/context_regions.h"
#include "common/error.h"
#include "common/feature_space.h"
#include "common/file_io.h"
#include "common/io/map_h5.h"
#include "common/machine_info.h"
#include "common/vocabulary.h"
#include "train/areas/area_training.h"
#include "train/boost/round_log.h"
#include "train/boost/stump_learner.h"
#include "train/boost/synthetic_problem.h"
#include "train/boost/training_set.h"
#include "train/checkpoint/checkpoint_h5.h"
#include "train/dist/dist_bench.h"
#include "train/dist/feature_parallel_learner.h"
#include "train/dist/training_job.h"
#include "train/eval/baselines.h"
#include "train/features/augmentation.h"
#include "train/features/build_features.h"

namespace lmb {

namespace {

// The training data of this rank: the set (replicated) and the feature columns it owns.
struct RankData {
  TrainingSet set;
  FeatureMatrix features;
  std::string source;          // checked on resume
  FeatureSpace feature_space;  // rank 0 (the map's fingerprint is computed there only)
  HammingValidationP1 hamming;
  AugmentNoise augment;             // the noise of the augmented copies (when config.augment.copies > 0)
  int32_t cross_fitting_folds = 0;  // the fold models this run's model is cross-fitted with
};

// The augmentation noise of a run: each rate the config leaves at -1 measured on the map (the same
// on every rank: the measurement is deterministic).
AugmentNoise resolve_augment_noise(const AugmentOptions& o, const LandmarkMap& map) {
  AugmentNoise noise;
  noise.seed = o.seed;
  noise.rotation_rad = o.rotation_deg * M_PI / 180.0;
  noise.dropout = o.dropout;
  noise.position_sigma = o.position_sigma;
  noise.scale_sigma = o.scale_sigma;
  if (o.dropout < 0.0 || o.position_sigma < 0.0 || o.scale_sigma < 0.0) {
    const MapNoiseEstimate m = measure_map_noise(map);
    spdlog::info(
        "train: map noise: detector repeatability {:.3f} (chance {:.3f}; {} tests), track re-observation rate "
        "{:.3f} ({} projections into covisible frames), position sigma {:.4f} keypoint scales ({} observations), "
        "log-scale sigma {:.4f} ({} track observations)",
        m.repeatability, m.chance_rate, m.repeat_tests, m.reobservation_rate, m.projected, m.position_sigma,
        m.residuals, m.scale_sigma, m.track_observations);
    if (o.dropout < 0.0) noise.dropout = std::min(0.95, 1.0 - m.repeatability);
    if (o.position_sigma < 0.0) noise.position_sigma = m.position_sigma;
    if (o.scale_sigma < 0.0) noise.scale_sigma = m.scale_sigma;
  }
  noise.check();
  return noise;
}

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

// The ranks of `comm` on this rank's machine (same host name), this one included. Collective.
int ranks_on_this_machine(Communicator& comm) {
  if (!comm.distributed()) return 1;
  char host[256] = {};
  ::gethostname(host, sizeof(host) - 1);
  const std::string name(host);
  std::vector<int64_t> offsets;
  const std::vector<uint8_t> all = comm.allgather_bytes(std::vector<uint8_t>(name.begin(), name.end()), &offsets);
  int same = 0;
  for (int r = 0; r < comm.size(); ++r) {
    same += std::string(all.begin() + offsets[r], all.begin() + offsets[r + 1]) == name;
  }
  return same;
}

// Refuses, before allocating, training features larger than the memory this machine has left: a
// region count within its range (1..1048576) can still ask for terabytes (regions x words dims a
// sample). Collective: rank 0 decides for its machine's ranks (each builds its share of the dims).
void check_feature_memory(const TrainRunInputs& a, const TrainConfig& config, const EmbeddingLayout& layout,
                          int64_t num_samples, const FeatureBuildOptions& options, Communicator& comm) {
  const int ranks = ranks_on_this_machine(comm);
  agree_on_rank0(comm, [&] {
    const bool all_dims = options.dims.empty();
    const int64_t stored = all_dims ? layout.num_dims() : static_cast<int64_t>(options.dims.size());
    const int64_t bytes = training_feature_bytes(num_samples, stored, options.num_threads, all_dims) * ranks;
    const MemoryInfo memory = memory_info();
    if (memory.available_bytes <= 0 || bytes <= memory.available_bytes) return;
    LMB_FAIL((a.config.empty() ? std::string() : a.config + ": ")
             << "regions.num_regions = " << config.regions.num_regions << ": the training features would need " << bytes
             << " bytes (" << num_samples << " samples x " << layout.num_dims() << " dims: " << layout.num_regions
             << " regions x " << layout.num_words << " words + " << layout.descriptor_bytes * 8 << " descriptor bits"
             << (ranks > 1 ? ", on " + std::to_string(ranks) + " ranks of this machine" : std::string())
             << "), more than the memory of this machine (" << memory.available_bytes << " bytes available, "
             << memory.total_bytes << " in all); lower regions.num_regions or training_set.top_k_landmarks");
  });
}

RankData load_rank_data(const TrainRunInputs& a, const TrainConfig& config, Communicator& comm, std::string* step) {
  RankData d;
  const auto t0 = std::chrono::steady_clock::now();
  if (!a.synthetic.empty()) {
    *step = "building the synthetic problem " + a.synthetic;
    SyntheticBoostProblem p = make_synthetic_boost_problem(synthetic_preset(a.synthetic));
    d.set = std::move(p.set);
    d.features =
        comm.distributed() ? keep_rank_columns(std::move(p.features), comm.rank(), comm.size()) : std::move(p.features);
    d.source = "synthetic:" + a.synthetic;
    d.feature_space = synthetic_feature_space(d.source, d.features.num_dims);
  } else {
    LMB_CHECK(!a.map.empty() && !a.vocab.empty(), "--map and --vocab are required (or --synthetic)");
    *step = "reading the map " + a.map;
    const LandmarkMap map = read_map_h5(a.map);
    *step = "reading the vocabulary " + a.vocab;
    const Vocabulary vocabulary = Vocabulary::load(a.vocab);
    *step = "building the training set";
    const std::vector<uint8_t> words8 = keypoint_words(map, vocabulary, config.feature_threads);
    const std::vector<int32_t> words(words8.begin(), words8.end());
    TrainingSetOptions set_options = config.training_set;
    if (config.area.set()) {
      set_options.class_landmarks = area_class_landmarks(config.area, map);
      spdlog::info("train: area {} of {}: {} landmark classes (training_set.top_k_landmarks not used)", config.area.id,
                   config.area.file, set_options.class_landmarks.size());
    }
    d.set = build_training_set(map, words, set_options);
    const size_t calibration_frames = calibration_holdout_frames(map, set_options).size();
    const int32_t folds = config.area.set() ? 0 : cross_fitting_folds(map, set_options);
    if (set_options.calibration_fold >= 0) {
      spdlog::info(
          "train: fold model: fold {} of {} (one map frame in {}, {} frames) held out whole for the "
          "cross-fitted pose calibration",
          set_options.calibration_fold, set_options.calibration_folds, set_options.calibration_folds,
          calibration_frames);
    } else if (folds > 0) {
      d.cross_fitting_folds = folds;
      spdlog::info(
          "train: too few map frames to hold calibration frames out: every map frame trains, and the pose "
          "calibration is cross-fitted on {} fold models, trained next (training_set.calibration_folds)",
          d.cross_fitting_folds);
    } else if (calibration_frames > 0) {
      spdlog::info("train: {} map frames held out whole for the pose calibration (training_set.calibration_frames)",
                   calibration_frames);
    } else if (!config.area.set()) {
      spdlog::warn(
          "train: no map frame held out and no fold models (training_set.calibration_folds 0, or one map frame): the "
          "pose calibration will be fitted on frames the model trained on");
    }
    *step = "generating " + std::to_string(config.regions.num_regions) + " context regions";
    const ContextRegions regions(config.regions);
    *step = "adding augmented copies";
    FeatureBuildOptions feature_options;
    feature_options.num_threads = config.feature_threads;
    if (config.augment.enabled()) {
      d.augment = resolve_augment_noise(config.augment, map);
      const int64_t originals = d.set.num_samples();
      add_augmented_copies(&d.set, config.augment.copies, [&](int64_t keypoint, int32_t copy) {
        return augmented_keypoint_kept(d.augment, keypoint, copy);
      });
      spdlog::info("train: augmentation: {} copies a training observation, {}: {} augmented samples",
                   config.augment.copies, d.augment.text(), d.set.num_samples() - originals);
      feature_options.copies = d.set.sample_copy;
      feature_options.augment = d.augment;
    }
    const EmbeddingLayout layout = embedding_layout(map, regions, vocabulary);
    if (comm.distributed()) feature_options.dims = rank_dims(layout.num_dims(), comm.rank(), comm.size());
    check_feature_memory(a, config, layout, d.set.num_samples(), feature_options, comm);
    *step = "building the training features (" + std::to_string(d.set.num_samples()) + " samples x " +
            std::to_string(layout.num_dims()) + " dims)";
    d.features = build_training_features(map, regions, vocabulary, d.set.sample_keypoint, feature_options);
    *step = "computing the Hamming baseline";
    if (comm.rank() == 0) {
      d.hamming = hamming_validation_p1(map, d.set);
      d.feature_space = map_feature_space(regions, vocabulary, map);
    }
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
    spdlog::info(
        "train: Hamming nearest-neighbour baseline, validation P@1 {:.4f} against every training "
        "sample, {:.4f} against the landmark classes' samples only",
        d.hamming.all, d.hamming.landmarks);
  }
  return d;
}

// Rank 0's hold on the run folder: the lock, and what to undo if the run is refused before it
// starts (a folder or lock file this process created).
class RunFolder {
 public:
  explicit RunFolder(const std::filesystem::path& dir) : dir_(dir) {}
  ~RunFolder() {
    if (started_) return;
    std::error_code ec;
    if (created_lock_) std::filesystem::remove(dir_ / kLockName, ec);
    lock_.unlock();
    if (created_dir_) std::filesystem::remove(dir_, ec);  // only if empty
  }
  // Creates the folder if needed and locks it. Throws lmb::Error (one line) when another trainer
  // holds the lock.
  void lock() {
    namespace fs = std::filesystem;
    std::error_code ec;
    if (fs::exists(dir_, ec)) {
      LMB_CHECK(fs::is_directory(dir_, ec), "--out " << dir_.string() << ": exists and is not a folder");
    } else {
      fs::create_directories(dir_, ec);
      LMB_CHECK(!ec, "--out " << dir_.string() << ": cannot create the folder: " << ec.message());
      created_dir_ = true;
    }
    const fs::path lock_path = dir_ / kLockName;
    created_lock_ = !fs::exists(lock_path, ec);
    std::string holder;
    const FileLock::Status status = lock_.try_lock(lock_path, &holder);
    if (status == FileLock::Status::kBusy) {
      created_lock_ = false;
      LMB_FAIL("--out " << dir_.string() << ": another lboost train is using this run folder ("
                        << (holder.empty() ? std::string("it holds ") : holder + " holds ") << lock_path.string()
                        << "); wait for it to end or use another --out folder");
    }
    if (status == FileLock::Status::kUnsupported) {
      spdlog::warn(
          "train: {}: the file system does not support file locks; nothing stops a second trainer "
          "from using this run folder at the same time",
          lock_path.string());
    }
  }
  // From here on the folder is the run's: nothing is undone.
  void start() { started_ = true; }

 private:
  static constexpr const char* kLockName = ".train.lock";
  std::filesystem::path dir_;
  FileLock lock_;
  bool created_dir_ = false;
  bool created_lock_ = false;
  bool started_ = false;
};

// Appends the log to RUN_DIR/log.txt through the project's checked appender.
class LogFileSink : public spdlog::sinks::base_sink<std::mutex> {
 public:
  explicit LogFileSink(const std::filesystem::path& path) : file_(path) {}
  // Lines already formatted (the log kept in memory before the run was accepted).
  void write_raw(std::string_view text) {
    std::lock_guard<std::mutex> lock(mutex_);
    file_.write(text);
  }

 protected:
  void sink_it_(const spdlog::details::log_msg& msg) override {
    spdlog::memory_buf_t formatted;
    formatter_->format(msg, formatted);
    file_.write(std::string_view(formatted.data(), formatted.size()));
  }
  void flush_() override {}

 private:
  AppendFile file_;
};

}  // namespace

bool train_on_ranks(const TrainRunInputs& a, const TrainConfig& config, Communicator& comm, std::string* step,
                    int32_t* cross_fitting_folds) {
  const std::filesystem::path run_dir(a.run_dir);
  const std::string config_text = train_config_toml(config);

  // Rank 0 logs to the console and RUN_DIR/log.txt (kept in memory until the run is accepted);
  // the other ranks print warnings and errors only.
  auto previous = spdlog::default_logger();
  auto console = std::make_shared<spdlog::sinks::stdout_color_sink_mt>();
  std::ostringstream early_log;
  std::shared_ptr<spdlog::logger> logger;
  if (comm.rank() == 0) {
    auto memory = std::make_shared<spdlog::sinks::ostream_sink_mt>(early_log);
    logger = std::make_shared<spdlog::logger>("train", spdlog::sinks_init_list{console, memory});
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

  // 1. Lock the run folder before reading or writing anything in it.
  RunFolder folder(run_dir);
  agree_on_rank0(comm, [&] { folder.lock(); });

  // 2. Validate: the checkpoint to resume (config, data source), the data, the feature space.
  TrainingJobOptions job;
  job.run_dir = run_dir;
  job.config_toml = config_text;
  job.checkpoint_minutes = config.checkpoint_minutes;
  job.checkpoint_interval = config.checkpoint_interval;
  job.checkpoint_keep = config.checkpoint_keep;
  job.data =
      a.synthetic.empty() ? std::filesystem::absolute(a.map).lexically_normal().string() : "synthetic:" + a.synthetic;
  const std::optional<Checkpoint> resume = find_resume_checkpoint(comm, job);
  const RankData data = load_rank_data(a, config, comm, step);
  if (cross_fitting_folds != nullptr) *cross_fitting_folds = data.cross_fitting_folds;
  job.feature_space = data.feature_space;
  check_resume_feature_space(comm, job, resume);
  *step = "setting up the learner (" + std::to_string(data.features.num_samples) + " samples x " +
          std::to_string(data.features.num_stored_columns()) + " dims)";
  FeatureParallelLearner learner(comm, data.features, data.set, config.boost);
  *step = "training";

  // 3. Accepted: from here on the run writes into its folder.
  std::optional<RoundLogger> round_log;
  agree_on_rank0(comm, [&] {
    write_file_atomically(run_dir / "config.toml", config_text);
    auto file = std::make_shared<LogFileSink>(run_dir / "log.txt");
    file->write_raw(early_log.str());
    file->set_pattern("[%H:%M:%S] %v");
    logger->sinks().back() = file;  // replaces the in-memory sink
    round_log.emplace(run_dir / "metrics.jsonl", config.boost.num_rounds);
    folder.start();
  });
  const TrainingJobResult r =
      run_training_job(comm, learner, job, resume, [&](const RoundStats& s) { round_log->log(s); });

  // Per-rank figures for the summary.
  const int64_t max_rss_kb = comm.allreduce_max(static_cast<int64_t>(peak_rss_mb() * 1024.0));
  const int64_t total_sent = comm.allreduce_sum(r.bytes_sent);
  const int64_t max_rss_end_kb = comm.allreduce_max(static_cast<int64_t>(current_rss_mb() * 1024.0));
  const int64_t max_cpu_us = comm.allreduce_max(static_cast<int64_t>(r.round_cpu_seconds * 1e6));
  const double validation_p1 = learner.validation_precision();  // collective
  const double validation_p1_landmarks = learner.validation_precision(true);
  if (r.stopped) return false;
  if (comm.rank() != 0) return true;
  *step = "writing the model";
  save_trained_model(run_dir / "model.bin", learner.model(), data.feature_space);
  nlohmann::json summary;
  summary["classes"] = data.set.num_classes;
  summary["samples"] = data.set.num_samples();
  summary["dims"] = data.features.num_dims;
  summary["data"] = data.source;
  if (config.area.set()) {
    summary["area"] = config.area.id;
    summary["area_file"] = config.area.file;
  }
  if (config.augment.enabled()) {
    summary["augment"] = {{"copies", config.augment.copies},
                          {"dropout", data.augment.dropout},
                          {"position_sigma", data.augment.position_sigma},
                          {"scale_sigma", data.augment.scale_sigma},
                          {"rotation_deg", data.augment.rotation_rad * 180.0 / M_PI},
                          {"seed", data.augment.seed}};
  }
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
  write_file_atomically(run_dir / "summary.json", summary.dump(2) + "\n");
  spdlog::info("train: {} stumps written to {}", learner.model().stumps.size(), (run_dir / "model.bin").string());
  return true;
}

}  // namespace lmb
