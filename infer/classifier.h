// Landmark classification of a frame's keypoints with an inference Model.
//
// Per keypoint: the feature values of the model's used dims (common/context_embedding.h,
// FrameContext::compute_dims), then the class scores
//   dense:          all C + 1 classes;
//   inverted file:  only the keypoint word's candidate classes (classes whose training
//                   observations quantize to the same word) and the background; only the dims
//                   those classes read are computed.
// classify() works on batches of kBatch keypoints of the same word: which stumps fire in which
// lane is tabulated once for the batch (one 32-bit mask a stump: the table stays in L1), then
// each class's score is summed over its own stump list for the whole batch at once (kBatch
// independent lanes, SIMD; each lane adds the stump's above or below double as its bit selects).
// Every score is summed in training order with the same doubles as the trainer's
// BoostModel::scores, so a class's score is bit-identical in both modes, in dense_scores() and
// class_score(), and to the trainer's.
//
// Ranking and rejection: the landmark classes (never the background) whose score exceeds the
// background's score by more than min_margin and is at least min_score, best first (ties: smaller
// class), at most top_k of them. A keypoint whose best class is the background gets no match.
//
// Threading: a Classifier holds per-frame buffers; use one per thread (the Model is shared).
#pragma once

#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "common/context_embedding.h"
#include "common/types.h"
#include "infer/export.h"
#include "infer/model.h"

namespace lmb {

struct LMB_INFER_EXPORT ClassifierOptions {
  int top_k = 1;                   // matches kept per keypoint, >= 1
  bool use_inverted_file = false;  // score only the keypoint word's candidate classes
  // A landmark class is a match only when its score exceeds the background's by more than this.
  // 0 = "better than the background"; negative values keep classes a little below the background
  // (recall for RANSAC); -inf = no background rejection.
  double min_margin = 0.0;
  // ... and is at least this (-inf = no bound).
  double min_score = -std::numeric_limits<double>::infinity();

  // Throws lmb::Error naming the field.
  void check() const;
};

// One ranked candidate of a keypoint.
struct ClassMatch {
  int32_t cls = -1;                       // landmark class, 0..C-1
  landmark_t landmark = kInvalidLandmarkId;  // its map landmark id
  double score = 0.0;                     // its class score
  double background_score = 0.0;          // the keypoint's background score
};

// The ranked matches of n keypoints in CSR form: keypoint k's matches, best first, are
// matches[begin[k] .. begin[k + 1]).
struct KeypointMatches {
  std::vector<int32_t> begin;  // n + 1 entries
  std::vector<ClassMatch> matches;

  int32_t num_keypoints() const { return begin.empty() ? 0 : static_cast<int32_t>(begin.size()) - 1; }
  int32_t count(int32_t k) const { return begin[k + 1] - begin[k]; }
  const ClassMatch* of(int32_t k) const { return matches.data() + begin[k]; }
};

class LMB_INFER_EXPORT Classifier {
 public:
  // Keypoints scored together (one SIMD lane each).
  static constexpr int32_t kBatch = 32;

  // Throws lmb::Error for a null model or invalid options.
  Classifier(std::shared_ptr<const Model> model, const ClassifierOptions& options = {});

  // Classifies every keypoint of a frame. frame: the frame's gravity-aligned keypoints with their
  // words (frame_keypoints_from_detections); descriptors: frame.size() rows of the model's
  // descriptor_bytes(). Throws lmb::Error (prefixed by `where`) when a word is out of range or the
  // geometry is invalid. embedding_ms (optional): receives the milliseconds spent building the
  // frame index and computing feature values (the rest is scoring and ranking).
  KeypointMatches classify(const FrameKeypoints& frame, const uint8_t* descriptors,
                           const std::string& where = "frame", double* embedding_ms = nullptr);

  // Lower-level steps (tests, benchmarks), valid after index_frame(frame):
  void index_frame(const FrameKeypoints& frame, const std::string& where = "frame");
  // Values of all used dims of keypoint k (model.used_dims().size() entries).
  void compute_used_values(int32_t k, const uint8_t* descriptor, uint8_t* values) const;
  // Dense scores of all C + 1 classes from the used values. scores: C + 1 entries.
  void dense_scores(const uint8_t* values, double* scores) const;
  // Score of one class from the used values (per-class stump list).
  double class_score(const uint8_t* values, int32_t cls) const;

  const Model& model() const { return *model_; }
  const ClassifierOptions& options() const { return options_; }

 private:
  // A ranked candidate while a batch is scored.
  struct Candidate {
    double score;
    int32_t cls;
  };
  // Scores one batch of keypoints `ids` (count <= kBatch) against `classes` (ascending, num of
  // them), whose stump lists follow each other from `lists`, and the background; values_ holds
  // their used-dim values. Appends every keypoint's ranked matches to pending_ as (keypoint,
  // match).
  void score_batch(const int32_t* ids, int32_t count, const int32_t* classes, int32_t num,
                   const int32_t* lists);
  // Offers class `cls` with `score` to keypoint lane j (background score bg).
  void offer(int32_t j, int32_t cls, double score, double bg);

  std::shared_ptr<const Model> model_;
  ClassifierOptions options_;
  FrameContext context_;
  std::vector<uint8_t> values_;       // used_dims().size() rows of kBatch lanes (dim-major)
  std::vector<uint8_t> word_values_;  // one keypoint's values of its word's (or all used) dims
  std::vector<uint32_t> fire_;        // per stump: bit j = the stump fires in lane j
  std::vector<double> class_out_;     // kBatch scores of one class
  std::vector<double> background_;    // kBatch background scores
  std::vector<int32_t> all_classes_;  // 0..C-1
  std::vector<std::vector<Candidate>> lanes_;  // per lane: passing candidates (pruned to top_k)
  std::vector<Candidate> cutoff_;              // per lane: worst kept once pruned
  std::vector<double> cutoff_score_;           // per lane: cutoff_[j].score
  std::vector<int32_t> order_, word_begin_;    // keypoints grouped by word
  std::vector<std::pair<int32_t, ClassMatch>> pending_;
};

namespace detail {
// The batch scoring kernels (internal; declared for tests). fire_masks: fire[s] bit j = lane j's
// value of stump s's dim is above its threshold; values holds one row of Classifier::kBatch lanes
// per used dim. accumulate_lanes: out[j] = bias + the outputs of stumps[0, count) (stump indices,
// in order) in lane j, each the stump's above or below double as fire bit j says, added in order
// (the same doubles as the scalar sum); the AVX-512 kernel where the CPU has it, else
// accumulate_lanes_generic (AVX2 or baseline clone). accumulate_two: two classes at once, each
// with the same additions as accumulate_lanes. out arrays hold kBatch doubles.
void fire_masks(const Model::DenseStump* stumps, size_t num_stumps, const uint8_t* values,
                uint32_t* fire);
void accumulate_lanes(double bias, const int32_t* stumps, int64_t count,
                      const Model::DenseStump* dense, const uint32_t* fire, double* out);
void accumulate_lanes_generic(double bias, const int32_t* stumps, int64_t count,
                              const Model::DenseStump* dense, const uint32_t* fire, double* out);
void accumulate_two(double bias0, const int32_t* stumps0, int64_t count0, double bias1,
                    const int32_t* stumps1, int64_t count1, const Model::DenseStump* dense,
                    const uint32_t* fire, double* out0, double* out1);
}  // namespace detail

}  // namespace lmb
