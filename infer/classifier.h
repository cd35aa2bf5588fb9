// Landmark classification of a frame's keypoints with an inference Model (internal: not installed;
// apps classify through the Localizer, infer/localizer.h).
//
// Per keypoint: the feature values of the model's used dims (common/context_embedding.h), then
// the class scores
//   dense:          all C + 1 classes;
//   inverted file:  only the keypoint word's candidate classes (classes whose training
//                   observations quantize to the same word) and the background; only the dims
//                   those classes read are needed.
// The values: when the keypoints' needs cover at least 3/4 of what all used dims of all
// keypoints would be (always in dense mode; in the trained `paper` model every word needs every
// used dim), every used dim of every keypoint at once, region by region
// (FrameContext::compute_dims_columns: about twice as fast on the paper model); else keypoint by keypoint,
// only its word's dims (FrameContext::compute_dims with ScoringIndex::word_plan).
// classify() works on batches of kBatch keypoints of the same word: which stumps fire in which
// lane is tabulated once for the batch (one 32-bit mask a stump: the table stays in L1). Each
// candidate class is first screened (below), for two batches of the word at a time; a class kept
// in some lane is then summed exactly over its own stump list in the 8-lane groups of the batch
// where its screening passed (SIMD; each lane adds the stump's above or below double as its bit
// selects). The kernels are those of the process's SIMD level (infer/simd/scoring_kernels.h), all
// of which give the same bits. Every score is summed in training order with the same doubles as the trainer's
// BoostModel::scores, so a class's score is bit-identical in both modes, in dense_scores() and
// class_score(), and to the trainer's.
//
// Screening (on by default, ClassifierOptions::screening): each candidate class gets an upper
// bound of its score in every lane from one 16-bit masked addition a stump (32 lanes in one
// AVX-512 register; ScoringIndex::screen_step, infer/detail/scoring_index.h), its stumps taken by
// decreasing step, with a bound on the rest at every ScoringIndex::kScreenCheck stumps; a class
// whose bound fails the ranking tests below in every lane (most classes: their scores lie well
// below the background's) is skipped there. The bound is rigorous (scoring_index.cc), so the
// matches are exactly those of the unscreened path. When a word's first classes are nearly all
// kept (a background that rarely wins), the rest of the word is scored without screening.
//
// Descriptor-distance fusion (a model with Model::has_fusion()): a landmark class's score is its
// stump sum plus detail::fusion_term of the keypoint's descriptor (Hamming distance to the
// class's exemplars), added once after the exact sum. The screening runs twice: first with
// ScoringIndex::fusion_max() in place of the term (no distance computed), then, in the lanes a
// class kept, with its own terms, so that only classes whose fused score could pass are summed
// exactly (with a large fusion weight the first pass keeps nearly every class; the second keeps
// about as few as the screening of a model without fusion). A class with many exemplars and few
// stumps would pay more for its terms than for its exact sum: its second screening uses upper
// bounds of the terms from the distances to a few balls that cover its exemplars
// (ScoringIndex::fusion_ball_begin, hamming_ball_low_lanes), and its exact terms are computed after
// the exact sum, only in the lanes where the sum plus the bound passes. dense_scores() and
// class_score() stay the stump sums (add detail::fusion_term for the fused one).
//
// Ranking and rejection: the landmark classes (never the background) whose score exceeds the
// background's score by more than min_margin and is at least min_score, best first (ties: smaller
// class), at most top_k of them. A keypoint whose best class is the background gets no match.
//
// Threading: a Classifier holds per-frame buffers; use one per thread (the Model is shared).
#pragma once

#include <chrono>
#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "common/context_embedding.h"
#include "common/types.h"
#include "infer/classifier_options.h"
#include "infer/detail/scoring_index.h"
#include "infer/model.h"
#include "infer/simd/scoring_kernels.h"

namespace lmb {

class Classifier {
 public:
  // Keypoints scored together (one SIMD lane each).
  static constexpr int32_t kBatch = detail::kScoringBatch;

  // Throws lmb::Error for a null model or invalid options.
  Classifier(std::shared_ptr<const Model> model, const ClassifierOptions& options = {});

  // Classifies every keypoint of a frame. frame: the frame's gravity-aligned keypoints with their
  // words (frame_keypoints_from_detections); descriptors: frame.size() rows of the model's
  // descriptor_bytes(). Throws lmb::Error (prefixed by `where`) when a word is out of range or the
  // geometry is invalid. embedding_ms (optional): receives the milliseconds spent building the
  // frame index and computing feature values (the rest is scoring and ranking).
  KeypointMatches classify(const FrameKeypoints& frame, const uint8_t* descriptors, const std::string& where = "frame",
                           double* embedding_ms = nullptr);
  // The same matches for a frame whose context index the caller built (indexed.reset(frame), as
  // PreparedFrame does once for every model of one vocabulary): the index is read, not rebuilt.
  // Throws lmb::Error when `indexed` holds another keypoint count, word count or region count.
  KeypointMatches classify(const FrameKeypoints& frame, const FrameContext& indexed, const uint8_t* descriptors,
                           const std::string& where = "frame", double* embedding_ms = nullptr);

  // Lower-level steps (tests, benchmarks), valid after index_frame(frame):
  void index_frame(const FrameKeypoints& frame, const std::string& where = "frame");
  // Values of all used dims of keypoint k (model.scoring().used_dims().size() entries).
  void compute_used_values(int32_t k, const uint8_t* descriptor, uint8_t* values) const;
  // Dense scores of all C + 1 classes from the used values (the stump sums, without the fusion
  // term). scores: C + 1 entries.
  void dense_scores(const uint8_t* values, double* scores) const;
  // Score of one class from the used values (per-class stump list).
  double class_score(const uint8_t* values, int32_t cls) const;

  const Model& model() const { return *model_; }
  const ClassifierOptions& options() const { return options_; }
  // Runs the kernels of `level` (common/simd/simd_level.h) instead of the process's level (tests:
  // every level gives the same matches). Throws lmb::Error when this CPU cannot run it.
  void use_simd_level(SimdLevel level);
  SimdLevel simd_level() const { return kernels_->level; }
  // Candidate classes offered to batches since construction (one per class and batch), and how
  // many of them were scored exactly (the rest were skipped by the screening).
  int64_t classes_screened() const { return classes_screened_; }
  int64_t classes_scored() const { return classes_scored_; }

 private:
  // A ranked candidate while a batch is scored.
  struct Candidate {
    double score;
    int32_t cls;
  };
  // The steps of one group of keypoints (a word's, or all): prepare_batch(b, values, stride)
  // computes batch b's fire masks (its kBatch lanes of used dim u at values[u * stride], in
  // values_ or frame_values_), background scores and screening goals; screen_word lists in kept_[b] the classes
  // (of `classes`, ascending, num of them) that pass the screening in some lane of batch b
  // (`batches` batches, `keypoints` keypoints); finish_batch scores batch b's kept classes
  // exactly and appends its keypoints' (`ids`, count of them) ranked matches to pending_ as
  // (keypoint, match).
  void prepare_batch(int32_t b, const uint8_t* values, size_t stride);
  void screen_word(const int32_t* classes, int32_t num, int32_t batches, int32_t keypoints, const int32_t* ids);
  void finish_batch(const int32_t* ids, int32_t count, int32_t b);
  // finish_batch's terms after the exact sums: class cls's sums `out` (batch b's lanes, `count` of
  // them keypoints) get their fusion terms in the lanes where the sum plus `bound` (per lane, an
  // upper bound of the term; null: fusion_max()) passes offer()'s tests, -inf in the others; false
  // (nothing computed) when no lane can pass.
  bool add_terms_where_they_pass(int32_t cls, int32_t b, int32_t count, const double* bound, double* out);
  // Offers class `cls` with `score` to keypoint lane j (background score bg).
  void offer(int32_t j, int32_t cls, double score, double bg);
  // With per_keypoint > 1, assigned_word_[k * per_keypoint + i]: keypoint k's i-th word (its own
  // first, then the nearest others; options_.inverted_file_words); with 1, nothing (frame.word).
  void assign_words(const FrameKeypoints& frame, const uint8_t* descriptors, int32_t per_keypoint);
  // pending_ in keypoint order, each keypoint's matches from its several words' groups merged: best
  // first (ties: smaller class), each class once, at most top_k.
  void merge_pending();
  // pending_'s matches of keypoints 0..n-1 in keypoint order, each keypoint's best first.
  KeypointMatches pending_matches(int32_t n) const;

  std::shared_ptr<const Model> model_;
  ClassifierOptions options_;
  FrameContext context_;
  // The caller's index during classify(frame, indexed, ...), else null (context_ is read).
  const FrameContext* external_ = nullptr;
  const FrameContext& indexed() const { return external_ != nullptr ? *external_ : context_; }
  // classify() once the index is built; `embedding`: the time already spent building it.
  KeypointMatches classify_indexed(const FrameKeypoints& frame, const uint8_t* descriptors, double* embedding_ms,
                                   std::chrono::steady_clock::duration embedding);
  std::vector<uint8_t> values_;        // used_dims().size() rows of kBatch lanes (dim-major)
  std::vector<uint8_t> word_values_;   // one keypoint's values of its word's (or all used) dims
  std::vector<uint8_t> frame_values_;  // or all used dims of the frame's keypoints (dim-major)
  std::vector<uint32_t> fire_;         // per batch of the group, per stump: bit j = fires in lane j
  std::vector<double> class_out_;      // kBatch scores of one class
  struct Kept {
    int32_t cls;
    uint32_t lanes;  // lanes where its screening bound passed
    bool terms;      // with the fusion: its terms are in kept_terms_ (else finish_batch computes them)
    bool bounded;    // with the fusion: upper bounds of its terms are in kept_terms_ (fusion balls)
  };
  std::vector<std::vector<Kept>> kept_;          // per batch of the group: classes kept by screening
  std::vector<std::vector<double>> kept_terms_;  // with the fusion: kBatch terms or bounds of such a kept class
  std::vector<uint8_t> lane_descriptors_;        // with the fusion: each batch's kBatch descriptors (rows)
  std::vector<double> kept_out_;                 // kBatch exact scores of each kept class of a batch
  std::vector<detail::GroupItem> groups_;
  std::vector<double> background_;             // per batch of the group: kBatch background scores
  std::vector<int32_t> goal_;                  // per batch of the group: kBatch screening goals
  std::vector<int32_t> all_classes_;           // 0..C-1
  std::vector<std::vector<Candidate>> lanes_;  // per lane: passing candidates (pruned to top_k)
  std::vector<Candidate> cutoff_;              // per lane: worst kept once pruned
  std::vector<double> cutoff_score_;           // per lane: cutoff_[j].score
  std::vector<int32_t> order_, word_begin_;    // keypoints grouped by word
  std::vector<int32_t> assigned_word_;         // each keypoint's words (assign_words)
  std::vector<uint8_t> once_values_;           // several words a keypoint: its values once
  std::vector<int32_t> keypoint_ids_;          // 0..n-1
  std::vector<std::pair<int32_t, ClassMatch>> pending_;
  const uint8_t* descriptors_ = nullptr;  // the frame's, during classify()
  int64_t classes_screened_ = 0, classes_scored_ = 0;
  const detail::ScoringKernels* kernels_;
};

namespace detail {
// Class cls's screening data (ScoringIndex::screen_step and the screen_* accessors) for the
// kernels.
ScreenList screen_list(const Model& model, int32_t cls);
// The screening goals of kBatch lanes from their background scores and offer()'s min_margin and
// min_score (see ScoringIndex::kScreenCheck): a lane whose tests could pass never gets a goal its
// integer bound fails.
// With `lift` (kBatch values, or null for 0): the goals of lanes whose score gets lift[j] added
// before the tests (target - lift[j]).
void screen_goals(const Model& model, const double* background, double min_margin, double min_score, int32_t* goal,
                  const double* lift = nullptr);
// The lanes of `lanes` where class cls, whose screening (ScoringKernels::screen_class) passed
// there with residues `residues` at the end of its list, still passes with each lane's score
// lifted by terms[j] (the goals screen_goals gives with lift[j] = terms[j] + screen_step()): the
// test screen_class makes at the end of the list, without walking it again. A lane that passes
// it passes every checkpoint before (a checkpoint's bound is never below the final one), so while
// these goals are at least those that produced the residues, this is screen_class's answer.
uint32_t screen_terms_pass(const Model& model, int32_t cls, const uint16_t* residues, const double* background,
                           double min_margin, double min_score, const double* terms, uint32_t lanes);
}  // namespace detail

}  // namespace lmb
