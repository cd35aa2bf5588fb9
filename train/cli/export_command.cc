// `lboost export`: a training run's model + the map and vocabulary it was trained with -> model.lbm,
// the one file the inference library needs (train/eval/run_export.h).
#include <filesystem>
#include <memory>
#include <optional>
#include <string>

#include <spdlog/spdlog.h>

#include "common/error.h"
#include "common/file_io.h"
#include "common/io/map_h5.h"
#include "common/vocabulary.h"
#include "infer/model.h"
#include "train/cli/commands.h"
#include "train/eval/run_export.h"

namespace lmb::cli {

namespace {

struct ExportArgs {
  RunExport run;
  std::string map;
  std::string vocab;
  std::string out;
  std::string fusion = "on";
  std::string calibration = "on";
};

void run_export(ExportArgs a) {
  check_outputs_not_inputs({{a.out, "--out"}}, {{run_file(a.run.run_dir, "model.bin"), "--run"},
                                                {run_file(a.run.run_dir, "config.toml"), "--run"},
                                                {a.run.boost_model, "--boost-model"},
                                                {a.map, "--map"},
                                                {a.vocab, "--vocab"}});
  boost_model_path(a.run.run_dir, a.run.boost_model);
  check_writable_file(a.out, "--out");
  LMB_CHECK(a.fusion == "on" || a.fusion == "off", "export: --fusion must be on or off, got '" << a.fusion << "'");
  LMB_CHECK(a.calibration == "on" || a.calibration == "off",
            "export: --calibration must be on or off, got '" << a.calibration << "'");
  a.run.fusion = a.fusion == "on";
  a.run.calibration = a.calibration == "on";
  a.run.map_name = a.map;
  a.run.vocab_name = a.vocab;
  const LandmarkMap map = read_map_h5(a.map);
  const Vocabulary vocabulary = Vocabulary::load(a.vocab);
  ExportStats stats;
  const Model model(export_run(a.run, map, vocabulary, &stats));
  model.save(a.out);
  spdlog::info(
      "export: {} classes, {} stumps reading {} dims, {} sharing entries, inverted file {} entries "
      "({:.1f} candidates per keypoint) -> {} ({} bytes)",
      stats.num_classes, stats.num_stumps, stats.num_used_dims, stats.sharing_entries, stats.inverted_file_entries,
      stats.mean_candidates, a.out, std::filesystem::file_size(a.out));
}

}  // namespace

void add_export_command(CLI::App& app) {
  auto args = std::make_shared<ExportArgs>();
  auto* cmd = app.add_subcommand("export", "Turn a training run into model.lbm, the file the inference library loads");
  cmd->add_option("--run", args->run.run_dir, "Run dir of `lboost train` (reads RUN/model.bin)");
  cmd->add_option("--boost-model", args->run.boost_model, "The trained model file (LMBBOOST) instead of --run");
  cmd->add_option("--map", args->map, "The map the model was trained on (map.h5)")->required();
  cmd->add_option("--vocab", args->vocab, "The vocabulary used in training (.lbv)")->required();
  cmd->add_option("--out", args->out, "Output model file (model.lbm), written atomically")->required();
  cmd->add_option("--regions", args->run.regions,
                  "Context regions of training (optional: the model records them; checked when given)");
  add_seed_option(cmd, "--region-seed", &args->run.region_seed,
                  "Seed of the training regions (optional: the model records it; checked when given)");
  cmd->add_option("--min-word-observations", args->run.options.min_word_observations,
                  "Observations of a (landmark, word) pair for an inverted-file entry")
      ->capture_default_str();
  cmd->add_option("--fusion", args->fusion,
                  "Descriptor-distance fusion fitted on the run's held-out map observations: on | off "
                  "(off: the stump sums alone; the model file holds no fusion)")
      ->capture_default_str();
  cmd->add_option("--max-exemplars", args->run.fusion_options.max_exemplars,
                  "The fusion's exemplars kept a class, chosen by k-centre in Hamming space (0: every map "
                  "observation); fewer make a smaller, faster model")
      ->capture_default_str();
  cmd->add_option("--calibration", args->calibration,
                  "Pose confidence calibrated on the map's own map-session frames: on | off (off: the model "
                  "trusts a pose by its inlier count alone, as models before format 3)")
      ->capture_default_str();
  cmd->add_option("--calibration-frames", args->run.calibration_options.max_frames,
                  "Map frames the calibration is fitted on at most (every n-th map-session frame), when the run's "
                  "training held none out (training_set.calibration_frames)")
      ->capture_default_str();
  cmd->add_option("--target-precision", args->run.calibration_options.target_precision,
                  "Precision of reported poses the operating point is chosen for, in (0, 1]")
      ->capture_default_str();
  cmd->add_option("--max-elsewhere-share", args->run.calibration_options.max_elsewhere_share,
                  "Share of the calibration frames, matched as if nothing of their view were in the map, that the "
                  "operating point may still localize, in [0, 1]")
      ->capture_default_str();
  cmd->callback([args] { run_export(*args); });
}

}  // namespace lmb::cli
