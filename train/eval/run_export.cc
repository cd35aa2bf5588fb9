#include "train/eval/run_export.h"

#include <memory>
#include <string>
#include <vector>

#include <spdlog/spdlog.h>

#include "common/context_regions.h"
#include "common/error.h"
#include "common/feature_space.h"
#include "infer/localizer.h"
#include "train/areas/area_training.h"
#include "train/boost/boost_model.h"
#include "train/eval/landmarkboost_matcher.h"
#include "train/eval/walk_calibration_fit.h"
#include "train/features/build_features.h"

namespace lmb {

namespace {

// The regions of training, from the model's record. --regions / --region-seed, when given, must
// describe the same regions.
ContextRegions training_regions(const RunExport& a, const FeatureSpace& trained, const std::string& model_name) {
  const ContextRegions& recorded = trained.regions;
  if (!a.regions && !a.region_seed) return recorded;
  ContextRegionOptions ro = recorded.options();
  if (a.regions) ro.num_regions = *a.regions;
  if (a.region_seed) ro.seed = *a.region_seed;
  ro.check();
  const ContextRegions given(ro);
  LMB_CHECK(given == recorded, model_name << " was trained with " << recorded.size() << " regions of seed "
                                          << recorded.options().seed << ", not " << given.size() << " of seed "
                                          << ro.seed
                                          << " (--regions and --region-seed are optional: the model records them)");
  return recorded;
}

}  // namespace

// Fits the pose calibration of `data` with the Localizer's default options (see the header).
void add_pose_calibration(PoseCalibrationOptions options, const TrainingSetOptions& training, const LandmarkMap& map,
                          ModelData& data, const std::vector<FoldModel>& folds) {
  options = with_holdout_frames(std::move(options), map, training);
  const LocalizerOptions localizer;  // what `lboost localize` and the library use by default
  LMB_CHECK(localizer.pose_top_k == 1,
            "export: the pose calibration assumes the Localizer's default of one match per keypoint");
  CalibrationFit fit;
  const int32_t num_folds = cross_fitting_folds(map, training);
  if (num_folds > 0) {
    LMB_CHECK(static_cast<int32_t>(folds.size()) == num_folds, "export: the run is cross-fitted with "
                                                                   << num_folds << " folds, " << folds.size()
                                                                   << " fold models given");
    std::vector<std::unique_ptr<LandmarkBoostMatcher>> matchers;
    std::vector<CalibrationFold> calibration_folds;
    for (const FoldModel& fold : folds) {
      const auto model = without_exemplars(fold.model, map, calibration_frame_keypoints(map, fold.frames), true);
      matchers.push_back(std::make_unique<LandmarkBoostMatcher>(model, localizer.classifier, /*rank=*/false));
      calibration_folds.push_back(CalibrationFold{matchers.back().get(), fold.frames});
    }
    fit = fit_cross_fitted_calibration(calibration_folds, map, localizer.pose, localizer.max_correspondences,
                                       PoseThresholds{}, options);
  } else {
    const std::vector<int64_t> own = calibration_frame_keypoints(map, calibration_frames(map, options));
    const auto model = without_exemplars(std::make_shared<const Model>(data), map, own, /*keep_sole=*/true);
    const LandmarkBoostMatcher matcher(model, localizer.classifier, /*rank=*/false);
    fit =
        fit_method_calibration(matcher, map, localizer.pose, localizer.max_correspondences, PoseThresholds{}, options);
  }
  if (!fit.fitted) {
    spdlog::warn(
        "export: pose calibration: only {} poses from {} map frames (at least {} needed): the model is written "
        "uncalibrated (a pose is trusted by its inlier count alone)",
        fit.num_poses, fit.num_frames, options.min_poses);
    return;
  }
  data.calibration = fit.calibration;
  const std::string how = num_folds > 0 ? fmt::format(
                                              ", cross-fitted (each of {} folds matched by the fold model trained "
                                              "without it)",
                                              num_folds)
                          : options.frames.empty() ? std::string(" (the model trained on them)")
                                                   : std::string(" held out of training");
  spdlog::info(
      "export: pose calibration on {} map frames{}: {} poses ({} of them with no landmark of the frame's view in the "
      "map), {} right; operating point {:.4f} (precision {}: {:.4f}; at most {} of the frames elsewhere: {:.4f}) "
      "keeps {} poses, {} right, {} of them elsewhere",
      fit.num_frames, how, fit.num_poses, fit.num_elsewhere, fit.num_right, fit.calibration.threshold,
      fit.calibration.target_precision, fit.precision_threshold, options.max_elsewhere_share, fit.elsewhere_threshold,
      fit.passed, fit.passed_right, fit.elsewhere_passed);
  if (!fit.saw_wrong_pose()) {
    spdlog::warn(
        "export: pose calibration: none of the {} poses is wrong, so nothing tells a wrong pose from a right one: "
        "every pose the inlier rule finds is reported (confidence 0.5); in a walk, the agreement of neighbouring "
        "frames' poses still refuses a pose",
        fit.num_poses);
  }
  // The walk calibration on the same poses: the calibration frames in session order are walks.
  const WalkCalibrationFit walk = fit_walk_calibration_on_map(map, fit, options);
  if (!walk.fitted) {
    spdlog::warn(
        "export: walk calibration: not fitted ({} walk samples, {} right): a tracked frame is judged by the pose "
        "calibration alone",
        walk.num_samples, walk.num_right);
    return;
  }
  data.walk_calibration = walk.calibration;
  const WalkCalibration& w = walk.calibration;
  if (w.adds) {
    spdlog::info(
        "export: walk calibration on {} walk samples ({} right, {} elsewhere; median step {:.3f} m, {:.2f} deg): "
        "operating point {:.4f}; either rule reports {} samples, {} right, {} of them elsewhere",
        walk.num_samples, walk.num_right, walk.num_elsewhere, w.translation_scale_m, w.rotation_scale_deg, w.threshold,
        walk.passed, walk.passed_right, walk.elsewhere_passed);
  } else {
    spdlog::info(
        "export: walk rule not fitted ({} walk samples, {} right): a tracked frame is judged by the pose "
        "calibration and the agreement",
        walk.num_samples, walk.num_right);
  }
  if (w.has_agreement()) {
    spdlog::info(
        "export: walk agreement: poses of frames g apart agree within {:.3f} m + g x {:.3f} m and {:.2f} deg + g x "
        "{:.2f} deg (right calibration poses' error and the map walks' step per frame, {} quantiles)",
        w.agreement_tolerance_m(0), w.agreement_step_m, w.agreement_tolerance_deg(0), w.agreement_step_deg,
        options.target_precision);
  }
}

std::filesystem::path fold_run_dir(const std::filesystem::path& run_dir, int32_t fold) {
  return run_dir / "folds" / std::to_string(fold);
}

std::vector<FoldModel> export_fold_models(const std::string& run_dir, const TrainConfig& config, const LandmarkMap& map,
                                          const Vocabulary& vocabulary) {
  const int32_t folds = cross_fitting_folds(map, config.training_set);
  LMB_CHECK(folds > 0, run_dir << ": not a cross-fitted run (its map holds calibration frames out, or "
                               << "training_set.calibration_folds is 0)");
  std::vector<FoldModel> out;
  for (int32_t k = 0; k < folds; ++k) {
    const std::filesystem::path dir = fold_run_dir(run_dir, k);
    const std::string retrain = "run `lboost train` again with the same flags: it trains the missing fold models";
    LMB_CHECK(std::filesystem::exists(dir / "model.bin") && std::filesystem::exists(dir / "config.toml"),
              dir.string() << ": fold " << k << " of the cross-fitted run " << run_dir << " has no trained model; "
                           << retrain);
    TrainConfig fold_config = read_run_train_config(dir / "config.toml");
    LMB_CHECK(fold_config.training_set.calibration_fold == k, dir.string() << "/config.toml: trained as fold "
                                                                           << fold_config.training_set.calibration_fold
                                                                           << ", not " << k);
    LMB_CHECK(fold_config.training_set.calibration_folds == folds,
              dir.string() << "/config.toml: trained as fold " << k << " of "
                           << fold_config.training_set.calibration_folds << ", not of " << folds);
    fold_config.training_set.calibration_fold = config.training_set.calibration_fold;
    fold_config.training_set.calibration_folds = config.training_set.calibration_folds;
    fold_config.feature_threads = config.feature_threads;
    fold_config.checkpoint_minutes = config.checkpoint_minutes;
    fold_config.checkpoint_interval = config.checkpoint_interval;
    fold_config.checkpoint_keep = config.checkpoint_keep;
    LMB_CHECK(train_config_toml(fold_config) == train_config_toml(config),
              dir.string() << "/config.toml: fold " << k << " was trained with other settings than " << run_dir
                           << "/config.toml; " << retrain << " after deleting " << dir.string());
    spdlog::info("export: fold model {} of {} ({}), for the cross-fitted pose calibration", k + 1, folds, dir.string());
    RunExport fold;
    fold.run_dir = dir.string();
    fold.calibration = false;
    ExportStats stats;
    out.push_back(FoldModel{std::make_shared<const Model>(export_run(fold, map, vocabulary, &stats)),
                            calibration_fold_frames(map, folds, k)});
  }
  return out;
}

std::vector<FoldModel> fold_models_of_run(const std::string& run_dir, const LandmarkMap& map,
                                          const std::string& vocab_path, const std::string& command) {
  const std::optional<TrainConfig> config = run_config_of(run_dir);
  const int32_t folds = config ? cross_fitting_folds(map, config->training_set) : 0;
  if (folds == 0) return {};
  LMB_CHECK(!vocab_path.empty(), command << ": --run " << run_dir << " is cross-fitted (" << folds
                                         << " fold models): give --vocab (the vocabulary of training), which its fold "
                                            "models need to be exported for the pose calibration");
  return export_fold_models(run_dir, *config, map, Vocabulary::load(vocab_path));
}

// The config of a training run dir (RUN/config.toml, read_run_train_config); nullopt without one.
std::optional<TrainConfig> run_config_of(const std::string& run_dir) {
  if (run_dir.empty()) return std::nullopt;
  return read_run_train_config(std::filesystem::path(run_dir) / "config.toml");
}

// The training-set options a model was trained with: its run's, or the defaults without a run.
TrainingSetOptions training_set_of(const std::optional<TrainConfig>& run_config) {
  if (run_config) return run_config->training_set;
  TrainingSetOptions defaults;
  defaults.calibration_folds = 0;  // no run, no fold models
  return defaults;
}

// The trained model of a run dir: <run>/model.bin (the trainer's file, magic "LMBBOOST"), unless
// --boost-model names one.
std::filesystem::path boost_model_path(const std::string& run_dir, const std::string& boost_model) {
  LMB_CHECK(run_dir.empty() || boost_model.empty(), "give --run RUN_DIR or --boost-model FILE, not both");
  if (!boost_model.empty()) return boost_model;
  LMB_CHECK(!run_dir.empty(), "give --run RUN_DIR or --boost-model FILE");
  const std::filesystem::path p = std::filesystem::path(run_dir) / "model.bin";
  LMB_CHECK(std::filesystem::exists(p), p.string() << ": no trained model in the run dir (has the training finished?)");
  return p;
}

ModelData export_run(const RunExport& a, const LandmarkMap& map, const Vocabulary& vocabulary, ExportStats* stats) {
  const std::filesystem::path boost_path = boost_model_path(a.run_dir, a.boost_model);
  const std::string model_name = boost_path.string();
  const TrainedModel trained = load_trained_model(boost_path);
  LMB_CHECK(!trained.feature_space.is_synthetic(),
            model_name << ": trained on " << trained.feature_space.synthetic << ", not on a map: nothing to export");
  const ContextRegions regions = training_regions(a, trained.feature_space, model_name);
  const FeatureSpace given = map_feature_space(regions, vocabulary, map);
  if (trained.feature_space.vocabulary_fingerprint != given.vocabulary_fingerprint ||
      trained.feature_space.num_words != given.num_words) {
    LMB_FAIL(model_name << " was not trained with the vocabulary " << a.vocab_name << ": "
                        << feature_space_difference(trained.feature_space, given));
  }
  if (trained.feature_space.map_fingerprint != given.map_fingerprint ||
      trained.feature_space.descriptor_bytes != given.descriptor_bytes) {
    LMB_FAIL(model_name << " was not trained on the map " << a.map_name << ": "
                        << feature_space_difference(trained.feature_space, given));
  }
  const std::string diff = feature_space_difference(trained.feature_space, given);
  LMB_CHECK(diff.empty(), model_name << ": " << diff);
  ModelData data = export_model_data(trained.model, map, vocabulary, regions, a.options, stats);
  // The run's training set (its config.toml), or the defaults with --boost-model.
  const std::optional<TrainConfig> run_config = run_config_of(a.run_dir);
  if (a.fusion) {
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
  if (a.calibration) {
    const TrainingSetOptions training = training_set_of(run_config);
    const std::vector<FoldModel> folds = cross_fitting_folds(map, training) > 0
                                             ? export_fold_models(a.run_dir, *run_config, map, vocabulary)
                                             : std::vector<FoldModel>{};
    add_pose_calibration(a.calibration_options, training, map, data, folds);
  }
  return data;
}

}  // namespace lmb
