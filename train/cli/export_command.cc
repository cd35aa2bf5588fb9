// `lboost export`: a training run's model + the map, vocabulary and regions it was trained with ->
// model.lbm, the one file the inference library needs (infer/model.h). With --fusion on (the
// default) it also fits the descriptor-distance fusion (train/export/descriptor_fusion.h) on the
// run's held-out map observations and stores it with the class exemplars.
#include <filesystem>
#include <memory>
#include <string>

#include <spdlog/spdlog.h>

#include "common/context_regions.h"
#include "common/error.h"
#include "common/io/map_h5.h"
#include "common/vocabulary.h"
#include "infer/model.h"
#include "train/boost/boost_model.h"
#include "train/boost/train_config.h"
#include "train/boost/training_set.h"
#include "train/cli/commands.h"
#include "train/export/descriptor_fusion.h"
#include "train/export/model_export.h"
#include "train/features/build_features.h"

namespace lmb::cli {

namespace {

struct ExportArgs {
  std::string run_dir;
  std::string boost_model;
  std::string map;
  std::string vocab;
  std::string out;
  int regions = -1;            // -1: from the run's config.toml (or the default without --run)
  int64_t region_seed = -1;
  ExportOptions options;
  std::string fusion = "on";
  DescriptorFusionOptions fusion_options;
};

// The trained model of a run dir: <run>/model.bin (the trainer's BoostModel file, magic
// "LMBBOOST"), unless --boost-model names one.
std::filesystem::path boost_model_path(const ExportArgs& a) {
  if (!a.boost_model.empty()) return a.boost_model;
  LMB_CHECK(!a.run_dir.empty(), "export: give --run RUN_DIR or --boost-model FILE");
  const std::filesystem::path p = std::filesystem::path(a.run_dir) / "model.bin";
  LMB_CHECK(std::filesystem::exists(p), p.string() << ": no trained model in the run dir");
  return p;
}

// The context regions of training: the run's config.toml [regions] (when --run is given), then
// --regions / --region-seed overrides.
ContextRegionOptions region_options(const ExportArgs& a) {
  ContextRegionOptions ro;
  if (!a.run_dir.empty()) {
    const std::filesystem::path config = std::filesystem::path(a.run_dir) / "config.toml";
    LMB_CHECK(std::filesystem::exists(config), config.string() << ": missing (the run's effective config)");
    ro = read_train_config(config).regions;
  }
  if (a.regions != -1) ro.num_regions = a.regions;
  if (a.region_seed != -1) ro.seed = static_cast<uint64_t>(a.region_seed);
  ro.check();
  return ro;
}

void run_export(const ExportArgs& a) {
  const std::filesystem::path boost_path = boost_model_path(a);
  const BoostModel boost = load_boost_model(boost_path);
  const LandmarkMap map = read_map_h5(a.map);
  const Vocabulary vocabulary = Vocabulary::load(a.vocab);
  const ContextRegions regions(region_options(a));
  LMB_CHECK(a.fusion == "on" || a.fusion == "off", "export: --fusion must be on or off, got '" << a.fusion << "'");
  ExportStats stats;
  ModelData data = export_model_data(boost, map, vocabulary, regions, a.options, &stats);
  if (a.fusion == "on") {
    // The held-out observations are those of the run's training set: rebuilt from its config.
    LMB_CHECK(!a.run_dir.empty(), "export: --fusion on needs --run (the training set of its config.toml); "
                                  "give --fusion off with --boost-model");
    const TrainConfig config = read_train_config(std::filesystem::path(a.run_dir) / "config.toml");
    const std::vector<uint8_t> words8 = keypoint_words(map, vocabulary);
    const TrainingSet set = build_training_set(map, std::vector<int32_t>(words8.begin(), words8.end()),
                                               config.training_set);
    const Model plain(data);
    DescriptorFusionStats fs;
    data.fusion = fit_descriptor_fusion(plain, map, set, a.fusion_options, &fs);
    std::string curve;
    for (size_t i = 0; i < fs.weight_p1.size(); ++i) {
      curve += fmt::format("{}{}:{:.3f}", i ? " " : "", a.fusion_options.weights[i], fs.weight_p1[i]);
    }
    spdlog::info("export: descriptor fusion weight {} ({} exemplars; g from {} training observations); held-out "
                 "P@1 {:.4f} with it, {:.4f} stump sums alone, {:.4f} nearest exemplar alone ({} samples)",
                 fs.weight, fs.exemplars, fs.distance_samples, fs.fit_p1_with, fs.fit_p1_without, fs.fit_p1_hamming,
                 fs.fit_samples);
    spdlog::info("export: held-out P@1 by weight: {}", curve);
  }
  const Model model(std::move(data));
  model.save(a.out);
  spdlog::info(
      "export: {} classes, {} stumps reading {} dims, {} sharing entries, inverted file {} entries "
      "({:.1f} candidates per keypoint) -> {} ({} bytes)",
      stats.num_classes, stats.num_stumps, stats.num_used_dims, stats.sharing_entries,
      stats.inverted_file_entries, stats.mean_candidates, a.out,
      std::filesystem::file_size(a.out));
}

}  // namespace

void add_export_command(CLI::App& app) {
  auto args = std::make_shared<ExportArgs>();
  auto* cmd = app.add_subcommand(
      "export", "Turn a training run into model.lbm, the file the inference library loads");
  cmd->add_option("--run", args->run_dir, "Run dir of `lboost train` (reads RUN/model.bin and RUN/config.toml)");
  cmd->add_option("--boost-model", args->boost_model, "The trained model file (LMBBOOST) instead of --run");
  cmd->add_option("--map", args->map, "The map the model was trained on (map.h5)")->required();
  cmd->add_option("--vocab", args->vocab, "The vocabulary used in training (.lbv)")->required();
  cmd->add_option("--out", args->out, "Output model file (model.lbm), written atomically")->required();
  cmd->add_option("--regions", args->regions, "Context regions used in training (default: the run's config)");
  cmd->add_option("--region-seed", args->region_seed, "Seed of the training regions (default: the run's config)");
  cmd->add_option("--min-word-observations", args->options.min_word_observations,
                  "Observations of a (landmark, word) pair for an inverted-file entry")
      ->capture_default_str();
  cmd->add_option("--fusion", args->fusion,
                  "Descriptor-distance fusion fitted on the run's held-out map observations: on | off "
                  "(off: the stump sums alone, the model file as before)")
      ->capture_default_str();
  cmd->callback([args] { run_export(*args); });
}

}  // namespace lmb::cli
