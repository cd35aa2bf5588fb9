// `lboost calibrate`: the pose calibration of an exported model (e.g. one exported without it),
// fitted as `lboost export` fits it (train/eval/run_export.h), written as a new model file.
#include <memory>
#include <string>

#include <spdlog/spdlog.h>

#include "common/error.h"
#include "common/file_io.h"
#include "common/io/map_h5.h"
#include "infer/model.h"
#include "train/cli/commands.h"
#include "train/eval/evaluation.h"
#include "train/eval/run_export.h"

namespace lmb::cli {

namespace {

struct CalibrateArgs {
  std::string model, map, out;
  std::string run_dir;  // optional: the training run (its config.toml's held-out frames)
  std::string vocab;    // the vocabulary of training: needed with a cross-fitted run
  PoseCalibrationOptions options;
};

// `lboost calibrate`: the pose calibration of an exported model (e.g. one exported before the
// calibration existed), fitted as export fits it, written as a new model file.
void run_calibrate(const CalibrateArgs& a) {
  check_outputs_not_inputs(
      {{a.out, "--out"}},
      {{a.model, "--model"}, {a.map, "--map"}, {a.vocab, "--vocab"}, {run_file(a.run_dir, "config.toml"), "--run"}});
  check_writable_file(a.out, "--out");
  const std::shared_ptr<const Model> model = Model::load(a.model);
  const LandmarkMap map = read_map_h5(a.map);
  check_model_fits_map(*model, a.model, map, a.map);
  ModelData data = model->data();
  data.calibration.reset();
  data.walk_calibration.reset();
  add_pose_calibration(a.options, training_set_of(run_config_of(a.run_dir)), map, data,
                       fold_models_of_run(a.run_dir, map, a.vocab, "calibrate"));
  LMB_CHECK(data.calibration.has_value(), "calibrate: too few calibration poses in " << a.map << " (see above)");
  Model(std::move(data)).save(a.out);
  spdlog::info("calibrate: {} -> {}", a.model, a.out);
}

}  // namespace

void add_calibrate_command(CLI::App& app) {
  auto args = std::make_shared<CalibrateArgs>();
  auto* cmd = app.add_subcommand(
      "calibrate", "Fit an exported model's pose confidence on its map's own frames (what export does by default)");
  cmd->add_option("--model", args->model, "The exported model (model.lbm)")->required();
  cmd->add_option("--map", args->map, "The map it was trained on (map.h5)")->required();
  cmd->add_option("--out", args->out, "Output model file with the calibration, written atomically")->required();
  cmd->add_option("--run", args->run_dir,
                  "The model's training run: the frames its config.toml held out of training are the calibration "
                  "frames (default: the frames the default training options hold out)");
  cmd->add_option("--vocab", args->vocab,
                  "The vocabulary of training (.lbv): needed with a --run trained with --calibration-folds (its fold "
                  "models are exported to cross-fit the calibration)")
      ->check(CLI::ExistingFile);
  cmd->add_option("--calibration-frames", args->options.max_frames,
                  "Map frames the calibration is fitted on at most (every n-th map-session frame), when training held "
                  "none out")
      ->capture_default_str();
  cmd->add_option("--target-precision", args->options.target_precision,
                  "Precision of reported poses the operating point is chosen for, in (0, 1]")
      ->capture_default_str();
  cmd->add_option("--max-elsewhere-share", args->options.max_elsewhere_share,
                  "Share of the calibration frames, matched as if nothing of their view were in the map, that the "
                  "operating point may still localize, in [0, 1]")
      ->capture_default_str();
  cmd->callback([args] { run_calibrate(*args); });
}

}  // namespace lmb::cli
