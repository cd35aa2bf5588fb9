// The methods of `lboost eval` and their options: a table of named matcher factories
// (train/eval/matcher.h). Adding a method is one entry in eval_methods() (methods.cc) and, when
// it needs one, a Matcher class.
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "common/landmark_map.h"
#include "infer/model.h"
#include "infer/pose_estimator.h"
#include "train/boost/boost_options.h"
#include "train/eval/baselines.h"
#include "train/eval/faiss_index.h"
#include "train/eval/matcher.h"
#include "train/eval/metrics.h"
#include "train/eval/pose_calibration_fit.h"
#include "train/eval/pose_stage.h"

namespace lmb {

// Everything `lboost eval` is configured with (its flags, one field each).
struct EvalOptions {
  std::string model;                 // model.lbm
  std::string map;                   // map.h5 the model was trained on, with its query frames
  std::vector<std::string> methods;  // names from eval_methods(); empty = all
  int top_k = 20;                    // ranked landmarks per keypoint, 1..10000
  double min_margin = 0.0;           // LandmarkBoost's background rejection for the pose (-inf = none)
  int inverted_file_words = 1;       // landmarkboost_invfile: words a keypoint (ClassifierOptions), 1..256
  int max_correspondences = 0;       // most confident accepted matches fed to RANSAC (0 = all)
  PoseEstimatorOptions pose;         // RANSAC: iterations, inlier threshold, min inliers, seed
  // A frame is correct within the first pair (frames_correct, the PR curve, the sweep); recall is
  // reported at every pair.
  std::vector<PoseThresholds> pose_thresholds = {PoseThresholds{}};
  PoseSweepOptions sweep;                  // pose recall over RANSAC budgets and seeds
  PoseCalibrationOptions calibration;      // each method's pose calibration (map frames, operating point)
  std::string hamming_backend = "opencv";  // the exact Hamming methods: opencv (BFMatcher) or popcount
  int pca_dims = 16;                       // projected_kdtree
  double ratio = 0.8;                      // the ratio-test methods: Lowe's ratio, in (0, 1]
  FaissHnswOptions faiss;                  // faiss_hnsw_ratio
  // The query sessions evaluated, by name (sessions of kind query); empty = every query session.
  std::vector<std::string> query_sessions;
  // The training-set options of the model's training run (RUN_DIR/config.toml). When set, the
  // held-out map observations of that run (train/boost/training_set.h, held_out_observations) are
  // ranked too, beside the query sessions: the generalization gap.
  std::optional<TrainingSetOptions> training_set;
  // The training run dir and the vocabulary of training: with a cross-fitted run
  // (training_set.calibration_folds > 0) every method's pose calibration is cross-fitted on the
  // run's fold models (train/eval/run_export.h), which need the vocabulary to be exported.
  std::string run_dir;
  std::string vocab;

  // Throws lmb::Error naming the flag (e.g. "eval: --top-k 0 must be in 1..10000").
  void check() const;
  // The methods to run: `methods`, or every method when empty.
  std::vector<std::string> method_names() const;
};

// What a method's factory gets.
struct MethodContext {
  std::shared_ptr<const Model> model;
  const LandmarkMap* map = nullptr;
  const EvalOptions* options = nullptr;
  // Map keypoints (sorted) the descriptor baselines leave out of their index: the held-out map
  // observations when those are the queries. Null = none.
  const std::vector<int64_t>* excluded_keypoints = nullptr;
  // True when the held-out map observations or the pose calibration's frames are the queries:
  // LandmarkBoost's descriptor fusion ranks them without their own exemplars (without_exemplars),
  // as the baselines' index is without them.
  bool excluded_from_fusion = false;
  // True when only the accepted matches are needed (the pose calibration): LandmarkBoost skips its
  // ranking pass.
  bool accept_only = false;
  // The training observations the descriptor baselines search: every observation of a model
  // class's landmark in the map's non-query frames, except excluded_keypoints. Throws lmb::Error
  // when there is none.
  TrainingObservations class_observations() const;
  // The map's landmark positions by landmark id.
  std::vector<Eigen::Vector3d> landmark_positions() const;
};

struct EvalMethod {
  std::string name;
  std::string description;  // one line, for --help and docs
  std::unique_ptr<Matcher> (*make)(const MethodContext& context);
};

// Every method, in report order.
const std::vector<EvalMethod>& eval_methods();
// The method called `name`; throws lmb::Error naming the known ones otherwise.
const EvalMethod& find_eval_method(const std::string& name);

}  // namespace lmb
