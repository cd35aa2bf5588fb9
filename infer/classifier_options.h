// The classifier's options and the ranked matches it returns (infer/classifier.h, internal), as
// the Localizer takes and gives them (LocalizerOptions::classifier, LocalizeResult::matches).
#pragma once

#include <cstdint>
#include <limits>
#include <vector>

#include "common/types.h"
#include "infer/export.h"

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
  // Screening: a class is scored exactly only when an upper bound of its score from 16-bit sums
  // could pass the tests above in some keypoint of the batch. The matches are the same either way
  // (the bound is never below the exact score); false = score every class exactly (tests,
  // benchmarks).
  bool screening = true;
  // With the descriptor-distance fusion and screening: a class with many exemplars is screened again
  // with an upper bound of its terms from its fusion balls before its exact sum (infer/classifier.h).
  // The matches are the same either way; false = only the largest term bounds it (benchmarks).
  bool fusion_balls = true;
  // With the inverted file: the candidates of the keypoint's word and of its next-nearest words
  // (Hamming distance to the model's vocabulary, ties: smaller word), this many words in all
  // (multiple assignment: a descriptor near a word boundary keeps the classes across it). 1 = the
  // keypoint's word only; capped at the vocabulary's word count.
  int inverted_file_words = 1;

  // Throws lmb::Error naming the field.
  void check() const;
};

// One ranked candidate of a keypoint.
struct ClassMatch {
  int32_t cls = -1;                          // landmark class, 0..C-1
  landmark_t landmark = kInvalidLandmarkId;  // its map landmark id
  double score = 0.0;                        // its class score
  double background_score = 0.0;             // the keypoint's background score
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

}  // namespace lmb
