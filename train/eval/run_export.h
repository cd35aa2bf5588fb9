// `lboost export` and `lboost calibrate` as library calls: a training run's model + the map and
// vocabulary it was trained with -> the inference model's data (infer/model.h). With the fusion on,
// the descriptor-distance fusion (train/export/descriptor_fusion.h) is fitted on the run's held-out
// map observations; with the calibration on, the pose confidence's calibration is fitted on the
// map's own map-session frames (train/eval/pose_calibration_fit.h, as `lboost eval` fits every
// method's) with the Localizer's default options.
//
// The trained model (model.bin) records the feature space its stumps were trained in
// (common/feature_space.h): the context regions come from that record and a map or vocabulary other
// than the ones of training is refused, so no silently wrong model is built. The run's config.toml
// is read only for the held-out observations and frames.
#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "common/landmark_map.h"
#include "common/vocabulary.h"
#include "infer/model.h"
#include "train/boost/train_config.h"
#include "train/boost/training_set.h"
#include "train/eval/pose_calibration_fit.h"
#include "train/export/descriptor_fusion.h"
#include "train/export/model_export.h"

namespace lmb {

struct RunExport {
  std::string run_dir;               // a run dir of `lboost train` (RUN/model.bin, RUN/config.toml), or
  std::string boost_model;           // a trained model file instead (then no fusion)
  std::string map_name, vocab_name;  // the map and vocabulary's files, named in errors
  std::optional<int32_t> regions;    // as recorded in the model unless given (then checked)
  std::optional<uint64_t> region_seed;
  ExportOptions options;
  bool fusion = true;
  DescriptorFusionOptions fusion_options;
  bool calibration = true;
  PoseCalibrationOptions calibration_options;
};

// The trained model of a run dir, <run>/model.bin, or `boost_model`. Throws lmb::Error unless
// exactly one is given and the file exists.
std::filesystem::path boost_model_path(const std::string& run_dir, const std::string& boost_model);

// The config of a training run dir (RUN/config.toml); nullopt without a run dir.
std::optional<TrainConfig> run_config_of(const std::string& run_dir);

// The training-set options a model was trained with: its run's, or the defaults without a run
// (without cross-fitting: there are no fold models).
TrainingSetOptions training_set_of(const std::optional<TrainConfig>& run_config);

// The inference model's data of a trained run (the fusion and the calibration as asked). Throws
// lmb::Error for a map, vocabulary or regions other than training's, or fusion without a run.
ModelData export_run(const RunExport& a, const LandmarkMap& map, const Vocabulary& vocabulary, ExportStats* stats);

// A fold model of a cross-fitted run (training_set.calibration_folds K > 0): `lboost train` trains
// the model on every frame into RUN and fold k's, without fold k of the frames
// (calibration_fold_frames), into fold_run_dir(RUN, k).
struct FoldModel {
  std::shared_ptr<const Model> model;
  std::vector<frame_t> frames;  // the fold it never trained on
};
std::filesystem::path fold_run_dir(const std::filesystem::path& run_dir, int32_t fold);
// Every fold model of the cross-fitted run `run_dir` (config: its config), exported as `lboost
// export` would (fusion on, no calibration). Throws lmb::Error naming the fold when its run is
// missing or unfinished, or was trained with other settings than the run's (calibration_fold
// aside).
std::vector<FoldModel> export_fold_models(const std::string& run_dir, const TrainConfig& config, const LandmarkMap& map,
                                          const Vocabulary& vocabulary);
// The fold models of the run `run_dir` (empty: none) when it is cross-fitted on `map`, else none.
// `vocab_path`, the vocabulary of training, is read only then; without it the error names
// `command` and its --vocab flag.
std::vector<FoldModel> fold_models_of_run(const std::string& run_dir, const LandmarkMap& map,
                                          const std::string& vocab_path, const std::string& command);

// Fits the pose calibration of `data` with the Localizer's default options (see the file comment)
// on the frames its training held out (`training`: the run's training-set options, or the
// defaults), else on options.max_frames map frames; cross-fitted on `folds` when given (each fold
// model on its own fold). The fusion's exemplars leave the matched frames' own descriptors out
// (else each keypoint finds itself at distance 0).
void add_pose_calibration(PoseCalibrationOptions options, const TrainingSetOptions& training, const LandmarkMap& map,
                          ModelData& data, const std::vector<FoldModel>& folds = {});

}  // namespace lmb
