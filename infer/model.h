// The inference model: everything the inference library needs to classify a frame's keypoints
// into landmark classes, in one file (model.lbm) written by `lboost export`.
//
//   score(v, c) = bias[c] + sum over stumps m with c in S_m of (v[dim_m] > theta_m ? a_m + b_m : b_m)
//
// (the trainer's BoostModel with the non-sharing constants folded into bias[c]). Class num_classes
// (the last one) is the background. Stumps are added in their training order, so a class's score
// is summed in the same order as BoostModel::scores and is bit-identical to it.
//
// File model.lbm: lmb container (common/file_container.h) with magic "LMBMODEL", version 1, around
// a cereal portable binary payload, in this order:
//   string detector; int32 descriptor_bytes;
//   regions: ContextRegionOptions fields (int32, uint64, 4 x double), uint64 count, count x 4 float;
//   vocabulary: uint64 size + the vocabulary payload bytes (common/vocabulary.h);
//   int32 num_classes C; uint64 C, C x int64 class landmark ids; uint64 C, C x 3 double positions;
//   uint64 C + 1, (C + 1) x double biases;
//   uint64 M stumps, each: int32 dim, uint8 theta, double a, double b, uint32 |S|, sharing set
//     as a byte string (uint64 size + bytes) of LEB128 varint gaps between ascending class ids;
//   int32 W words; W inverted lists, each: uint32 count + byte string of varint gaps (ascending
//     landmark classes whose training observations quantize to the word);
//   version 2 only, the descriptor-distance fusion: uint64 C + 1, (C + 1) x int64 exemplar
//     offsets; byte string of the exemplar rows; uint64 8 * descriptor_bytes + 1, that many
//     doubles (distance_score);
//   version 3 only: uint8 has_fusion (0 or 1), then the fusion as in version 2 when 1; then the
//     pose calibration (infer/pose_confidence.h): uint32 F = PoseEvidence::kNumFeatures, F x
//     double weights, double bias, double threshold, int64 num_samples, int64 num_positive,
//     double target_precision;
//   version 4 and 5: version 3's contents, then the walk calibration (infer/walk_confidence.h):
//     uint32 F = WalkEvidence::kNumFeatures, F x double weights, double bias, double threshold,
//     double translation_scale_m, double rotation_scale_deg, int32 max_gap, int64 num_samples,
//     int64 num_positive, double target_precision;
//   version 5 only: then uint8 adds (0 or 1), double agreement_noise_m,
//     double agreement_noise_deg, double agreement_step_m, double agreement_step_deg.
// Every count is checked against the bytes left in the payload before anything is allocated.
//
// Threading: a Model is immutable after construction; all methods are const and may be called
// from any number of threads at once.
#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "common/context_regions.h"
#include "common/shared_stump.h"
#include "common/types.h"
#include "common/vocabulary.h"
#include "infer/export.h"
#include "infer/pose_confidence.h"
#include "infer/walk_confidence.h"

namespace lmb {

namespace detail {
class ScoringIndex;  // infer/detail/scoring_index.h (internal)
}  // namespace detail

// Descriptor-distance fusion (optional; fitted by train/export/descriptor_fusion.h): a landmark
// class's score becomes
//   score(v, c) = H(v, c) + distance_score[d_c],
// H the stump sum and d_c the smallest Hamming distance between the keypoint's descriptor and
// class c's exemplars (its map observations' descriptors). The background's score stays H.
struct DescriptorFusion {
  // Class c's exemplars are rows [exemplar_begin[c], exemplar_begin[c + 1]) of `exemplars`, each
  // descriptor_bytes bytes; C + 1 non-decreasing offsets starting at 0, every class with at least
  // one row. Empty = no fusion.
  std::vector<int64_t> exemplar_begin;
  std::vector<uint8_t> exemplars;
  // The score added at Hamming distance d = 0 .. 8 * descriptor_bytes (that many + 1 entries),
  // finite.
  std::vector<double> distance_score;

  bool enabled() const { return !exemplar_begin.empty(); }
};

// The model's contents as plain data: what export builds and the file holds.
struct ModelData {
  std::string detector = "BRISK";  // detector the descriptors come from (informative)
  int32_t descriptor_bytes = 0;    // descriptor length; equals the vocabulary's
  ContextRegions regions;
  Vocabulary vocabulary;
  int32_t num_classes = 0;                      // landmark classes C; class C is the background
  std::vector<landmark_t> class_landmark;       // size C: the map landmark id of each class
  std::vector<Eigen::Vector3d> class_position;  // size C: world frame, map units (metres)
  std::vector<double> bias;                     // size C + 1, folded constants
  std::vector<SharedStump> stumps;              // in training order (non-empty sharing sets)
  // Inverted file: inverted_file[w] lists (ascending) the landmark classes (< C) whose training
  // observations quantize to word w. Size: vocabulary.num_words().
  std::vector<std::vector<int32_t>> inverted_file;
  DescriptorFusion fusion;  // optional (version 2 and 3 files)
  // The pose confidence's calibration (version 3 files; fitted by `lboost export`). Absent = an
  // uncalibrated model: a pose counts as localized by its inlier count alone.
  std::optional<PoseCalibration> calibration;
  // The walk calibration (version 4 files; fitted by `lboost export` beside the pose calibration,
  // which it needs): how a tracked pose's consistency with the walk counts. Absent = every frame
  // of a walk is judged by the pose calibration alone.
  std::optional<WalkCalibration> walk_calibration;

  // Throws lmb::Error (prefixed by `where`) naming the field: sizes, ranges, ordering, finiteness.
  LMB_INFER_EXPORT void check(const std::string& where = "model") const;
};

// Immutable model with the indices scoring needs.
class LMB_INFER_EXPORT Model {
 public:
  // Validates `data` (check()) and builds the scoring indices. Throws lmb::Error.
  explicit Model(ModelData data);

  // Reads model.lbm. Throws lmb::Error naming the path: missing or unreadable file, wrong magic,
  // wrong version, length or CRC mismatch, truncated or corrupt payload.
  static std::shared_ptr<const Model> load(const std::filesystem::path& path);
  // The same from a file image in memory (header + payload). `what` names the source in errors.
  static std::shared_ptr<const Model> from_bytes(const uint8_t* data, size_t size, const std::string& what = "model");
  // Writes model.lbm atomically (temp file, fsync, rename). Throws lmb::Error.
  void save(const std::filesystem::path& path) const;
  // The whole file image (header + payload).
  std::vector<uint8_t> to_bytes() const;

  const ModelData& data() const { return data_; }
  int32_t num_classes() const { return data_.num_classes; }
  int32_t background_class() const { return data_.num_classes; }
  int32_t descriptor_bytes() const { return data_.descriptor_bytes; }
  int32_t num_words() const { return data_.vocabulary.num_words(); }
  const ContextRegions& regions() const { return data_.regions; }
  const Vocabulary& vocabulary() const { return data_.vocabulary; }
  landmark_t class_landmark(int32_t c) const { return data_.class_landmark[c]; }
  const Eigen::Vector3d& class_position(int32_t c) const { return data_.class_position[c]; }
  // Whether the model has a descriptor-distance fusion (DescriptorFusion).
  bool has_fusion() const { return data_.fusion.enabled(); }
  // The pose calibration: whether the model has one (false for models older than version 3 or
  // exported without one), and it (only when calibrated()).
  bool calibrated() const { return data_.calibration.has_value(); }
  const PoseCalibration& calibration() const { return *data_.calibration; }
  // The walk calibration, if the model has one (WalkTracker reads it).
  const std::optional<WalkCalibration>& walk_calibration() const { return data_.walk_calibration; }

  // The scoring indices the classifier reads (infer/detail/scoring_index.h in the source tree;
  // internal, not installed).
  const detail::ScoringIndex& scoring() const { return *scoring_; }

 private:
  ModelData data_;
  std::shared_ptr<const detail::ScoringIndex> scoring_;  // shared by copies (immutable)
};

}  // namespace lmb
