// `lboost export`: a training run's model + the map, vocabulary and regions it was trained with ->
// model.lbm, the one file the inference library needs (infer/model.h).
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
#include "train/cli/commands.h"
#include "train/export/model_export.h"

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
  ExportStats stats;
  const Model model(export_model_data(boost, map, vocabulary, regions, a.options, &stats));
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
  cmd->callback([args] { run_export(*args); });
}

}  // namespace lmb::cli
