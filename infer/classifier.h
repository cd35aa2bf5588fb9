// Landmark classification of a frame's keypoints with an inference Model.
//
// Per keypoint: the feature values of the model's used dims (common/context_embedding.h,
// FrameContext::compute_dims), then the class scores
//   dense:          all C + 1 classes, stump by stump (each stump adds a + b or b to its sharing
//                   set's classes);
//   inverted file:  only the keypoint word's candidate classes (classes whose training
//                   observations quantize to the same word) and the background, class by class
//                   over each class's own stump list; only the dims those classes read are
//                   computed.
// Both sum a class's score in training order, so the score of a class is bit-identical in both
// modes and to the trainer's BoostModel::scores.
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
  // Appends keypoint k's ranked matches given the scores of `num` classes `classes` (scores
  // aligned with them) and the background score.
  void rank(const int32_t* classes, const double* scores, int32_t num, double background,
            KeypointMatches* out);

  std::shared_ptr<const Model> model_;
  ClassifierOptions options_;
  FrameContext context_;
  std::vector<uint8_t> values_;
  std::vector<uint8_t> word_values_;
  std::vector<double> scores_;
  std::vector<int32_t> all_classes_;
  std::vector<int32_t> order_;
};

}  // namespace lmb
