// `lboost export`: a training run's model + the map and vocabulary it was trained with -> model.lbm,
// the one file the inference library needs (infer/model.h). With --fusion on (the default) it also
// fits the descriptor-distance fusion (train/export/descriptor_fusion.h) on the run's held-out map
// observations and stores it with the class exemplars (every map observation of a class, or
// --max-exemplars of them chosen by k-centre).
//
// With --calibration on (the default) it fits the pose confidence's calibration on the map's own
// map-session frames (train/eval/pose_calibration_fit.h: every method's calibration of `lboost
// eval` is fitted the same way, no query frame is read) with the Localizer's default options, and
// stores it in the model (format version 3); --target-precision sets the operating point.
//
// The trained model (model.bin) records the feature space its stumps were trained in
// (common/feature_space.h): export takes the context regions from that record and refuses a map or
// vocabulary other than the ones of training, so it cannot build a silently wrong model. The run's
// config.toml is read only for the fusion's held-out observations (train rewrites it only after a
// resume is accepted).
#include <filesystem>
#include <memory>
#include <optional>
#include <string>

#include <spdlog/spdlog.h>

#include "common/context_regions.h"
#include "common/error.h"
#include "common/feature_space.h"
#include "common/file_io.h"
#include "common/io/map_h5.h"
#include "common/vocabulary.h"
#include "infer/localizer.h"
#include "infer/model.h"
#include "train/areas/area_training.h"
#include "train/boost/boost_model.h"
#include "train/boost/train_config.h"
#include "train/boost/training_set.h"
#include "train/cli/commands.h"
#include "train/eval/evaluation.h"
#include "train/eval/landmarkboost_matcher.h"
#include "train/eval/pose_calibration_fit.h"
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
  std::optional<int32_t> regions;  // as recorded in the model unless given (then checked)
  std::optional<int64_t> region_seed;
  ExportOptions options;
  std::string fusion = "on";
  DescriptorFusionOptions fusion_options;
  std::string calibration = "on";
  PoseCalibrationOptions calibration_options;
};

// Fits the pose calibration of `data` with the Localizer's default options (see the file comment)
// on the frames its training held out (`training`: the run's training-set options, or the
// defaults), else on options.max_frames map frames. The fusion's exemplars leave those frames'
// own descriptors out (else each keypoint finds itself at distance 0).
void add_pose_calibration(PoseCalibrationOptions options, const TrainingSetOptions& training, const LandmarkMap& map,
                          ModelData& data) {
  options = with_holdout_frames(std::move(options), map, training);
  const std::vector<int64_t> own = calibration_frame_keypoints(map, calibration_frames(map, options));
  const auto model = without_exemplars(std::make_shared<const Model>(data), map, own, /*keep_sole=*/true);
  const LocalizerOptions localizer;  // what `lboost localize` and the library use by default
  LMB_CHECK(localizer.pose_top_k == 1,
            "export: the pose calibration assumes the Localizer's default of one match per keypoint");
  const LandmarkBoostMatcher matcher(model, localizer.classifier, /*rank=*/false);
  const CalibrationFit fit =
      fit_method_calibration(matcher, map, localizer.pose, localizer.max_correspondences, PoseThresholds{}, options);
  if (!fit.fitted) {
    spdlog::warn(
        "export: pose calibration: only {} poses from {} map frames (at least {} needed): the model is written "
        "uncalibrated (a pose is trusted by its inlier count alone)",
        fit.num_poses, fit.num_frames, options.min_poses);
    return;
  }
  data.calibration = fit.calibration;
  spdlog::info(
      "export: pose calibration on {} map frames{}: {} poses ({} of them with no landmark of the frame's view in the "
      "map), {} right; operating point {:.4f} (precision {}: {:.4f}; at most {} of the frames elsewhere: {:.4f}) "
      "keeps {} poses, {} right, {} of them elsewhere",
      fit.num_frames, options.frames.empty() ? " (the model trained on them)" : " held out of training", fit.num_poses,
      fit.num_elsewhere, fit.num_right, fit.calibration.threshold, fit.calibration.target_precision,
      fit.precision_threshold, options.max_elsewhere_share, fit.elsewhere_threshold, fit.passed, fit.passed_right,
      fit.elsewhere_passed);
}

// The config of a training run dir (RUN/config.toml, read_run_train_config); nullopt without one.
std::optional<TrainConfig> run_config_of(const std::string& run_dir) {
  if (run_dir.empty()) return std::nullopt;
  return read_run_train_config(std::filesystem::path(run_dir) / "config.toml");
}

// The training-set options a model was trained with: its run's, or the defaults without a run.
TrainingSetOptions training_set_of(const std::optional<TrainConfig>& run_config) {
  return run_config ? run_config->training_set : TrainingSetOptions{};
}

// The trained model of a run dir: <run>/model.bin (the trainer's file, magic "LMBBOOST"), unless
// --boost-model names one.
std::filesystem::path boost_model_path(const ExportArgs& a) {
  LMB_CHECK(a.run_dir.empty() || a.boost_model.empty(), "give --run RUN_DIR or --boost-model FILE, not both");
  if (!a.boost_model.empty()) return a.boost_model;
  LMB_CHECK(!a.run_dir.empty(), "give --run RUN_DIR or --boost-model FILE");
  const std::filesystem::path p = std::filesystem::path(a.run_dir) / "model.bin";
  LMB_CHECK(std::filesystem::exists(p), p.string() << ": no trained model in the run dir (has the training finished?)");
  return p;
}

// The regions of training, from the model's record. --regions / --region-seed, when given, must
// describe the same regions.
ContextRegions training_regions(const ExportArgs& a, const FeatureSpace& trained, const std::string& model_name) {
  const ContextRegions& recorded = trained.regions;
  if (!a.regions && !a.region_seed) return recorded;
  ContextRegionOptions ro = recorded.options();
  if (a.regions) ro.num_regions = *a.regions;
  if (a.region_seed) {
    LMB_CHECK(*a.region_seed >= 0, "--region-seed " << *a.region_seed << ": must be >= 0");
    ro.seed = static_cast<uint64_t>(*a.region_seed);
  }
  ro.check();
  const ContextRegions given(ro);
  LMB_CHECK(given == recorded, model_name << " was trained with " << recorded.size() << " regions of seed "
                                          << recorded.options().seed << ", not " << given.size() << " of seed "
                                          << ro.seed
                                          << " (--regions and --region-seed are optional: the model records them)");
  return recorded;
}

void run_export(const ExportArgs& a) {
  const std::filesystem::path boost_path = boost_model_path(a);
  const std::string model_name = boost_path.string();
  check_writable_file(a.out, "--out");
  const TrainedModel trained = load_trained_model(boost_path);
  LMB_CHECK(!trained.feature_space.is_synthetic(),
            model_name << ": trained on " << trained.feature_space.synthetic << ", not on a map: nothing to export");
  const LandmarkMap map = read_map_h5(a.map);
  const Vocabulary vocabulary = Vocabulary::load(a.vocab);
  const ContextRegions regions = training_regions(a, trained.feature_space, model_name);
  const FeatureSpace given = map_feature_space(regions, vocabulary, map);
  if (trained.feature_space.vocabulary_fingerprint != given.vocabulary_fingerprint ||
      trained.feature_space.num_words != given.num_words) {
    LMB_FAIL(model_name << " was not trained with the vocabulary " << a.vocab << ": "
                        << feature_space_difference(trained.feature_space, given));
  }
  if (trained.feature_space.map_fingerprint != given.map_fingerprint ||
      trained.feature_space.descriptor_bytes != given.descriptor_bytes) {
    LMB_FAIL(model_name << " was not trained on the map " << a.map << ": "
                        << feature_space_difference(trained.feature_space, given));
  }
  const std::string diff = feature_space_difference(trained.feature_space, given);
  LMB_CHECK(diff.empty(), model_name << ": " << diff);
  LMB_CHECK(a.fusion == "on" || a.fusion == "off", "export: --fusion must be on or off, got '" << a.fusion << "'");
  ExportStats stats;
  ModelData data = export_model_data(trained.model, map, vocabulary, regions, a.options, &stats);
  // The run's training set (its config.toml), or the defaults with --boost-model.
  const std::optional<TrainConfig> run_config = run_config_of(a.run_dir);
  if (a.fusion == "on") {
    // The held-out observations are those of the run's training set: rebuilt from its config.
    LMB_CHECK(run_config.has_value(),
              "export: --fusion on needs --run (the training set of its config.toml); "
              "give --fusion off with --boost-model");
    const TrainConfig& config = *run_config;
    const std::vector<uint8_t> words8 = keypoint_words(map, vocabulary);
    TrainingSetOptions set_options = config.training_set;
    if (config.area.set()) set_options.class_landmarks = area_class_landmarks(config.area, map);
    const TrainingSet set = build_training_set(map, std::vector<int32_t>(words8.begin(), words8.end()), set_options);
    const Model plain(data);
    DescriptorFusionStats fs;
    data.fusion = fit_descriptor_fusion(plain, map, set, a.fusion_options, &fs);
    std::string curve;
    for (size_t i = 0; i < fs.weight_p1.size(); ++i) {
      curve += fmt::format("{}{}:{:.3f}", i ? " " : "", a.fusion_options.weights[i], fs.weight_p1[i]);
    }
    spdlog::info(
        "export: descriptor fusion weight {} ({} exemplars; g from {} training observations); held-out "
        "P@1 {:.4f} with it, {:.4f} stump sums alone, {:.4f} nearest exemplar alone ({} samples)",
        fs.weight, fs.exemplars, fs.distance_samples, fs.fit_p1_with, fs.fit_p1_without, fs.fit_p1_hamming,
        fs.fit_samples);
    spdlog::info("export: held-out P@1 by weight: {}", curve);
  }
  LMB_CHECK(a.calibration == "on" || a.calibration == "off",
            "export: --calibration must be on or off, got '" << a.calibration << "'");
  if (a.calibration == "on") {
    add_pose_calibration(a.calibration_options, training_set_of(run_config), map, data);
  }
  const Model model(std::move(data));
  model.save(a.out);
  spdlog::info(
      "export: {} classes, {} stumps reading {} dims, {} sharing entries, inverted file {} entries "
      "({:.1f} candidates per keypoint) -> {} ({} bytes)",
      stats.num_classes, stats.num_stumps, stats.num_used_dims, stats.sharing_entries, stats.inverted_file_entries,
      stats.mean_candidates, a.out, std::filesystem::file_size(a.out));
}

struct CalibrateArgs {
  std::string model, map, out;
  std::string run_dir;  // optional: the training run (its config.toml's held-out frames)
  PoseCalibrationOptions options;
};

// `lboost calibrate`: the pose calibration of an exported model (e.g. one exported before the
// calibration existed), fitted as export fits it, written as a new model file.
void run_calibrate(const CalibrateArgs& a) {
  check_writable_file(a.out, "--out");
  const std::shared_ptr<const Model> model = Model::load(a.model);
  const LandmarkMap map = read_map_h5(a.map);
  check_model_fits_map(*model, a.model, map, a.map);
  ModelData data = model->data();
  data.calibration.reset();
  add_pose_calibration(a.options, training_set_of(run_config_of(a.run_dir)), map, data);
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

void add_export_command(CLI::App& app) {
  auto args = std::make_shared<ExportArgs>();
  auto* cmd = app.add_subcommand("export", "Turn a training run into model.lbm, the file the inference library loads");
  cmd->add_option("--run", args->run_dir, "Run dir of `lboost train` (reads RUN/model.bin)");
  cmd->add_option("--boost-model", args->boost_model, "The trained model file (LMBBOOST) instead of --run");
  cmd->add_option("--map", args->map, "The map the model was trained on (map.h5)")->required();
  cmd->add_option("--vocab", args->vocab, "The vocabulary used in training (.lbv)")->required();
  cmd->add_option("--out", args->out, "Output model file (model.lbm), written atomically")->required();
  cmd->add_option("--regions", args->regions,
                  "Context regions of training (optional: the model records them; checked when given)");
  cmd->add_option("--region-seed", args->region_seed,
                  "Seed of the training regions (optional: the model records it; checked when given)");
  cmd->add_option("--min-word-observations", args->options.min_word_observations,
                  "Observations of a (landmark, word) pair for an inverted-file entry")
      ->capture_default_str();
  cmd->add_option("--fusion", args->fusion,
                  "Descriptor-distance fusion fitted on the run's held-out map observations: on | off "
                  "(off: the stump sums alone, the model file as before)")
      ->capture_default_str();
  cmd->add_option("--max-exemplars", args->fusion_options.max_exemplars,
                  "The fusion's exemplars kept a class, chosen by k-centre in Hamming space (0: every map "
                  "observation); fewer make a smaller, faster model")
      ->capture_default_str();
  cmd->add_option("--calibration", args->calibration,
                  "Pose confidence calibrated on the map's own map-session frames: on | off (off: the model "
                  "trusts a pose by its inlier count alone, as models before format 3)")
      ->capture_default_str();
  cmd->add_option("--calibration-frames", args->calibration_options.max_frames,
                  "Map frames the calibration is fitted on at most (every n-th map-session frame), when the run's "
                  "training held none out (training_set.calibration_frames)")
      ->capture_default_str();
  cmd->add_option("--target-precision", args->calibration_options.target_precision,
                  "Precision of reported poses the operating point is chosen for, in (0, 1]")
      ->capture_default_str();
  cmd->add_option("--max-elsewhere-share", args->calibration_options.max_elsewhere_share,
                  "Share of the calibration frames, matched as if nothing of their view were in the map, that the "
                  "operating point may still localize, in [0, 1]")
      ->capture_default_str();
  cmd->callback([args] { run_export(*args); });
}

}  // namespace lmb::cli
