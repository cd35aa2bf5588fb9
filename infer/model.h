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
//     double target_precision.
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

#include "common/context_embedding.h"
#include "common/context_regions.h"
#include "common/shared_stump.h"
#include "common/types.h"
#include "common/vocabulary.h"
#include "infer/export.h"
#include "infer/pose_confidence.h"
#include "infer/simd/scoring_kernels.h"

namespace lmb {

constexpr const char* kModelMagic = "LMBMODEL";
// Version 2 appends the descriptor-distance fusion (DescriptorFusion); version 3 an optional
// fusion and the pose calibration (PoseCalibration). A model is written in the oldest version
// that holds it: without a calibration as version 1 or 2, byte for byte as before. All three are
// read; a model of version 1 or 2 is uncalibrated (Model::calibrated() false).
constexpr uint32_t kModelVersion = 3;
constexpr uint32_t kModelVersionWithFusion = 2;
constexpr uint32_t kModelVersionWithoutFusion = 1;

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

  EmbeddingLayout layout() const {
    EmbeddingLayout l;
    l.num_regions = regions.size();
    l.num_words = vocabulary.num_words();
    l.descriptor_bytes = descriptor_bytes;
    return l;
  }
  // Throws lmb::Error (prefixed by `where`) naming the field: sizes, ranges, ordering, finiteness.
  LMB_INFER_EXPORT void check(const std::string& where = "model") const;
};

// The payload (cereal portable binary, see the file comment) and its inverse. parse throws
// lmb::Error naming `what` for truncated or corrupt bytes, a count larger than the bytes left,
// or contents that fail ModelData::check. The payload's version is model_file_version(data):
// kModelVersion with a calibration, else kModelVersionWithFusion with a fusion, else
// kModelVersionWithoutFusion; parse reads each.
LMB_INFER_EXPORT std::string serialize_model_data(const ModelData& data);
LMB_INFER_EXPORT ModelData parse_model_data(const std::string& payload, const std::string& what,
                                            uint32_t version = kModelVersion);
LMB_INFER_EXPORT uint32_t model_file_version(const ModelData& data);

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
  const EmbeddingLayout& layout() const { return layout_; }
  const ContextRegions& regions() const { return data_.regions; }
  const Vocabulary& vocabulary() const { return data_.vocabulary; }
  landmark_t class_landmark(int32_t c) const { return data_.class_landmark[c]; }
  const Eigen::Vector3d& class_position(int32_t c) const { return data_.class_position[c]; }

  // ---- Scoring indices (read by the classifier) -------------------------------------------
  // The feature dimensions any stump reads, ascending ("used dims"); stump m reads used dim
  // stump_used_[m] (an index into used_dims()).
  const std::vector<int32_t>& used_dims() const { return used_dims_; }
  // used_dims() prepared for FrameContext::compute_dims.
  const DimPlan& used_plan() const { return used_plan_; }

  // Dense scoring: stumps as flat arrays (used: index into used_dims(); above = a + b, below = b),
  // sharing sets in CSR form.
  using DenseStump = detail::DenseStump;
  const std::vector<DenseStump>& dense_stumps() const { return dense_stumps_; }
  const std::vector<int64_t>& stump_class_begin() const { return stump_class_begin_; }  // M + 1
  const std::vector<int32_t>& stump_classes() const { return stump_classes_; }

  // Per-class scoring (inverted file): class c's stumps in training order are entries
  // [class_stump_begin()[c], class_stump_begin()[c + 1]) of class_stumps(); the same DenseStump
  // records, copied so that one class's loop reads contiguous memory.
  const std::vector<int64_t>& class_stump_begin() const { return class_stump_begin_; }  // C + 2
  const std::vector<DenseStump>& class_stumps() const { return class_stumps_; }
  // The same entries as stump indices (into dense_stumps()), for the batched classifier.
  const std::vector<int32_t>& class_stump_index() const { return class_stump_index_; }

  // Inverted file in CSR form: word w's candidate classes are [word_class_begin()[w],
  // word_class_begin()[w + 1]) of word_classes(), ascending.
  const std::vector<int32_t>& word_class_begin() const { return word_class_begin_; }
  const std::vector<int32_t>& word_classes() const { return word_classes_; }
  // The used dims that word w's candidate classes and the background read: indices into
  // used_dims(), ascending, in [word_used_begin()[w], word_used_begin()[w + 1]) of word_used();
  // word_used_dims() holds the matching global dims (what FrameContext::compute_dims takes).
  const std::vector<int32_t>& word_used_begin() const { return word_used_begin_; }
  const std::vector<int32_t>& word_used() const { return word_used_; }
  const std::vector<int32_t>& word_used_dims() const { return word_used_dims_; }

  // Descriptor-distance fusion (DescriptorFusion): whether the model has one, the term of class c
  // (< C) for a descriptor of descriptor_bytes() bytes (0 without fusion), and the largest term
  // any descriptor can get (0 without fusion; the screening adds it to every bound).
  bool has_fusion() const { return data_.fusion.enabled(); }
  // The pose calibration: whether the model has one (false for models older than version 3 or
  // exported without one), and it (only when calibrated()).
  bool calibrated() const { return data_.calibration.has_value(); }
  const PoseCalibration& calibration() const { return *data_.calibration; }
  double fusion_term(int32_t cls, const uint8_t* descriptor) const;
  double fusion_max() const { return fusion_max_; }
  // Word w's used dims prepared for FrameContext::compute_dims.
  const DimPlan& word_plan(int32_t w) const { return word_plans_[w]; }

  // Screening (an upper bound of a landmark class's score from 16-bit integer sums, so that the
  // classifier skips, without computing its exact score, a class that cannot be a match):
  //   stump m's step a_m = above - below is rounded to q_m = round(a_m / step), step a power of
  //   two chosen so that |q_m| <= 32767 and each class's sum of |q_m| <= 65535;
  //   Q = sum over the class's stumps of (fires ? q_m : 0), summed modulo 2^16 (uint16 lanes),
  //   is recovered from its residue t = (Q - low_c) mod 2^16 because Q lies in
  //   [low_c, low_c + 65535] (low_c = sum of the negative q_m);
  //   bound = offset_c + step * t >= the class's exact score (the double the trainer sums) for
  //   every input, where offset_c = bias_c + sum of below_m + sum of max(0, a_m - step * q_m)
  //   + step * low_c + a margin covering every rounding error (model.cc proves it).
  // The integer sum does not depend on the order, so each class's screening list holds its stumps
  // by decreasing |q_m| (ties: training order), as uint16 stump indices (screening needs
  // M <= 65536 stumps; with more, every bound is +inf and every class is scored exactly).
  // Checkpoints, after every kScreenCheck entries of that list (k = 1, 2, ... while entries
  // remain): the sum Q_k of the first k kScreenCheck entries is recovered likewise from its
  // residue t_k = (Q_k - low_ck) mod 2^16 (low_ck = the sum of their negative q_m), and
  //   bound_k = offset_c + step * (t_k + add_ck) >= the class's exact score, where
  //   add_ck = low_ck - low_c + the sum of the positive q_m of the remaining entries;
  // a class whose bound_k already fails in every lane is dropped there.
  // The tests run in integers (detail::screen_goals in classifier.h): a lane whose double test
  //   bound - background > min_margin and bound >= min_score
  // passes also passes x + units_c + 2 >= goal_j, x = t + add (the multiple of step in bound),
  // units_c = ceil(offset_c / step) clamped to +-kScreenUnitsLimit, and goal_j =
  // floor(max(background_j + min_margin, min_score) / step). Why: while |background_j|,
  // |min_margin| and |min_score| are at most 2^27 steps (else goal_j = kScreenPassAll, the lane
  // is never dropped) and |offset_c| at most 2^29 steps, each double rounding moves the test by
  // less than 2^-20 steps, and ceil / floor only loosen it; an offset_c beyond -2^29 steps fails
  // the double test anyway, and one beyond +2^29 steps (or +inf) passes the integer one always.
  static constexpr int32_t kScreenCheck = detail::kScreenCheck;
  static constexpr int32_t kScreenUnitsLimit = 1 << 29;
  static constexpr int32_t kScreenPassAll = -(1 << 29) - 2;  // a goal every lane passes
  double screen_step() const { return screen_step_; }
  const std::vector<int16_t>& screen_q() const { return screen_q_; }           // M
  const std::vector<double>& screen_offset() const { return screen_offset_; }  // C
  const std::vector<int32_t>& screen_units() const { return screen_units_; }   // C
  const std::vector<uint16_t>& screen_low() const { return screen_low_; }      // C: low_c mod 2^16
  // Class c's screening list: entries [class_stump_begin()[c], class_stump_begin()[c + 1]).
  const std::vector<uint16_t>& screen_list() const { return screen_list_; }
  // Class c's checkpoints are entries [screen_check_begin()[c], screen_check_begin()[c + 1]) of
  // screen_check_low() (low_ck mod 2^16) and screen_check_add() (add_ck).
  const std::vector<int64_t>& screen_check_begin() const { return screen_check_begin_; }  // C + 1
  const std::vector<uint16_t>& screen_check_low() const { return screen_check_low_; }
  const std::vector<int32_t>& screen_check_add() const { return screen_check_add_; }

 private:
  ModelData data_;
  EmbeddingLayout layout_;
  std::vector<int32_t> used_dims_;
  std::vector<DenseStump> dense_stumps_;
  std::vector<int64_t> stump_class_begin_;
  std::vector<int32_t> stump_classes_;
  std::vector<int64_t> class_stump_begin_;
  std::vector<DenseStump> class_stumps_;
  std::vector<int32_t> class_stump_index_;
  std::vector<int32_t> word_class_begin_;
  std::vector<int32_t> word_classes_;
  std::vector<int32_t> word_used_begin_;
  std::vector<int32_t> word_used_;
  std::vector<int32_t> word_used_dims_;
  DimPlan used_plan_;
  std::vector<DimPlan> word_plans_;
  double fusion_max_ = 0.0;
  double screen_step_ = 1.0;
  std::vector<int16_t> screen_q_;
  std::vector<double> screen_offset_;
  std::vector<int32_t> screen_units_;
  std::vector<uint16_t> screen_low_;
  std::vector<uint16_t> screen_list_;
  std::vector<int64_t> screen_check_begin_;
  std::vector<uint16_t> screen_check_low_;
  std::vector<int32_t> screen_check_add_;

  void build_screen();
};

namespace detail {
// LEB128 varint gap coding of an ascending id list (first id, then differences), and its
// bounds-checked inverse (internal: not exported from the shared library): decode throws lmb::Error naming `what` when
// the bytes end early, hold extra bytes, a gap is zero after the first id, or an id exceeds max_id.
std::string encode_ascending_ids(const std::vector<int32_t>& ids);
std::vector<int32_t> decode_ascending_ids(const std::string& bytes, uint32_t count, int32_t max_id,
                                          const std::string& what);
}  // namespace detail

}  // namespace lmb
