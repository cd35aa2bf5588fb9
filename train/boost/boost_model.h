// The trained classifier: M shared decision stumps plus one bias per class.
//
//   score(v, c) = bias[c] + sum over stumps m with c in S_m of (a_m * [v[dim_m] > theta_m] + b_m)
//
// which equals the GentleBoost sum over stumps of (c in S_m ? a_m [v > theta] + b_m : k_{c,m}):
// the constants k_{c,m} of the stumps that do not share c are folded into bias[c]. Class
// num_classes (the last one) is the background: a keypoint whose best class is the background is
// rejected ("no match").
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "common/feature_space.h"
#include "common/shared_stump.h"
#include "common/types.h"

namespace lmb {

struct BoostModel {
  int32_t num_dims = 0;                    // feature dimension the stumps index
  int32_t num_classes = 0;                 // landmark classes C; class C is the background
  std::vector<landmark_t> class_landmark;  // size C
  std::vector<double> bias;                // size C + 1: folded constants
  std::vector<SharedStump> stumps;

  int32_t background_class() const { return num_classes; }
  // Scores of all C + 1 classes for one dense feature vector of num_dims bins. scores: C + 1.
  void scores(const uint8_t* v, double* scores) const;
  double score(const uint8_t* v, int32_t c) const;
  // Best class (ties: smaller index); background_class() means "no match".
  int32_t classify(const uint8_t* v) const;
  // Throws lmb::Error on inconsistent sizes, class or dim out of range, unsorted sets,
  // non-finite parameters.
  void check() const;
  bool operator==(const BoostModel&) const = default;

  template <class Archive>
  void serialize(Archive& ar) {
    ar(num_dims, num_classes, class_landmark, bias, stumps);
  }
};

// cereal portable binary. Loading checks every count against the bytes left before allocating,
// then model.check().
std::string serialize_boost_model(const BoostModel& model);
BoostModel deserialize_boost_model(const std::string& bytes, const std::string& what = "model");

// The trainer's output file, model.bin: the file container (common/file_container.h) with magic
// "LMBBOOST", version 2, around the BoostModel payload followed by the feature space it was
// trained in (common/feature_space.h). Version 1 files (no feature space) are refused: nothing
// could prove which regions and vocabulary their stumps read.
struct TrainedModel {
  BoostModel model;
  FeatureSpace feature_space;
};
// Throws lmb::Error when the model is invalid or its num_dims differs from the feature space's.
void save_trained_model(const std::filesystem::path& path, const BoostModel& model, const FeatureSpace& space);
TrainedModel load_trained_model(const std::filesystem::path& path);

}  // namespace lmb
