#include "infer/classifier.h"

#include <algorithm>
#include <cassert>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>

#include "common/error.h"
#include "common/hamming.h"
#include "common/vocabulary.h"
#include "infer/detail/scoring_index.h"

namespace lmb {

void ClassifierOptions::check() const {
  LMB_CHECK(top_k >= 1 && top_k <= 1000000, "classifier options: top_k = " << top_k << " must be in 1..1000000");
  LMB_CHECK(!std::isnan(min_margin) && min_margin != std::numeric_limits<double>::infinity(),
            "classifier options: min_margin = " << min_margin << " must be a number below +inf");
  LMB_CHECK(!std::isnan(min_score) && min_score != std::numeric_limits<double>::infinity(),
            "classifier options: min_score = " << min_score << " must be a number below +inf");
  LMB_CHECK(
      inverted_file_words >= 1 && inverted_file_words <= kMaxVocabularyWords,
      "classifier options: inverted_file_words = " << inverted_file_words << " must be in 1.." << kMaxVocabularyWords);
}

namespace {
const Model& checked(const std::shared_ptr<const Model>& model) {
  LMB_CHECK(model != nullptr, "classifier: null model");
  return *model;
}
}  // namespace

Classifier::Classifier(std::shared_ptr<const Model> model, const ClassifierOptions& options)
    : model_(std::move(model)),
      options_(options),
      context_(checked(model_).regions(), checked(model_).num_words()),
      kernels_(&detail::scoring_kernels()) {
  options_.check();
  const size_t U = model_->scoring().used_dims().size();
  values_.assign(U * kBatch, 0);
  word_values_.resize(U);
  class_out_.resize(2 * kBatch);
  all_classes_.resize(static_cast<size_t>(model_->num_classes()));
  for (int32_t c = 0; c < model_->num_classes(); ++c) all_classes_[c] = c;
  lanes_.resize(kBatch);
  cutoff_.resize(kBatch);
  cutoff_score_.assign(kBatch, -std::numeric_limits<double>::infinity());
}

void Classifier::use_simd_level(SimdLevel level) {
  const detail::ScoringKernels* kernels = detail::scoring_kernels(level);
  LMB_CHECK(kernels != nullptr, "classifier: SIMD level " << simd_level_name(level) << " is not available on this CPU");
  context_ = FrameContext(model_->regions(), model_->num_words(), level);
  kernels_ = kernels;
}

void Classifier::index_frame(const FrameKeypoints& frame, const std::string& where) {
  external_ = nullptr;
  context_.reset(frame, where);
}

void Classifier::compute_used_values(int32_t k, const uint8_t* descriptor, uint8_t* values) const {
  indexed().compute_dims(k, model_->scoring().used_plan(), descriptor, values);
}

void Classifier::dense_scores(const uint8_t* values, double* scores) const {
  const Model& m = *model_;
  const detail::ScoringIndex& idx = m.scoring();
  const std::vector<double>& bias = m.data().bias;
  std::copy(bias.begin(), bias.end(), scores);
  const std::vector<detail::DenseStump>& stumps = idx.dense_stumps();
  const int64_t* begin = idx.stump_class_begin().data();
  const int32_t* classes = idx.stump_classes().data();
  for (size_t s = 0; s < stumps.size(); ++s) {
    const detail::DenseStump& st = stumps[s];
    const double h = values[st.used] > st.theta ? st.above : st.below;
    for (int64_t e = begin[s]; e < begin[s + 1]; ++e) scores[classes[e]] += h;
  }
}

double Classifier::class_score(const uint8_t* values, int32_t cls) const {
  const Model& m = *model_;
  const detail::ScoringIndex& idx = m.scoring();
  double total = m.data().bias[cls];
  const detail::DenseStump* st = idx.class_stumps().data();
  const int64_t end = idx.class_stump_begin()[cls + 1];
  for (int64_t e = idx.class_stump_begin()[cls]; e < end; ++e) {
    total += values[st[e].used] > st[e].theta ? st[e].above : st[e].below;
  }
  return total;
}

namespace detail {

ScreenList screen_list(const Model& model, int32_t cls) {
  const ScoringIndex& idx = model.scoring();
  ScreenList v;
  v.q = idx.screen_q().data();
  v.list = idx.screen_list().data() + idx.class_stump_begin()[cls];
  v.count = idx.class_stump_begin()[cls + 1] - idx.class_stump_begin()[cls];
  v.check_low = idx.screen_check_low().data() + idx.screen_check_begin()[cls];
  v.check_add = idx.screen_check_add().data() + idx.screen_check_begin()[cls];
  v.end_low = idx.screen_low()[cls];
  v.units = idx.screen_units()[cls];
  return v;
}

namespace {

// One lane's goal (screen_goals).
struct GoalRule {
  // 1 / step is exact (step is a power of two), so target * per_step is target / step, bit for bit.
  double step, per_step, safe, min_margin, min_score;
  bool options_safe;
  GoalRule(const Model& model, double margin, double score)
      : step(model.scoring().screen_step()),
        per_step(1.0 / step),
        safe(step * double{ScoringIndex::kScreenUnitsLimit / 4}),  // 2^27 steps
        min_margin(margin),
        min_score(score) {
    const double inf = std::numeric_limits<double>::infinity();
    options_safe = (margin == -inf || std::fabs(margin) <= safe) && (score == -inf || std::fabs(score) <= safe);
  }
  int32_t goal(double background, double lift) const {
    const double inf = std::numeric_limits<double>::infinity();
    const double target = std::max(min_margin == -inf ? -inf : background + min_margin, min_score) - lift;
    const bool usable = options_safe && std::fabs(background) <= safe && std::fabs(lift) <= safe && target != -inf;
    return usable ? static_cast<int32_t>(std::floor(target * per_step)) : ScoringIndex::kScreenPassAll;
  }
};

}  // namespace

void screen_goals(const Model& model, const double* background, double min_margin, double min_score, int32_t* goal,
                  const double* lift) {
  const GoalRule rule(model, min_margin, min_score);
  for (int32_t j = 0; j < Classifier::kBatch; ++j) goal[j] = rule.goal(background[j], lift ? lift[j] : 0.0);
}

uint32_t screen_terms_pass(const Model& model, int32_t cls, const uint16_t* residues, const double* background,
                           double min_margin, double min_score, const double* terms, uint32_t lanes) {
  const GoalRule rule(model, min_margin, min_score);
  const int64_t shift = int64_t{model.scoring().screen_units()[cls]} + 2;
  uint32_t out = 0;
  for (uint32_t l = lanes; l != 0; l &= l - 1) {
    const int j = __builtin_ctz(l);
    const int64_t threshold = std::clamp<int64_t>(rule.goal(background[j], terms[j] + rule.step) - shift, 0, 65535);
    if (residues[j] >= threshold) out |= 1u << j;
  }
  return out;
}

}  // namespace detail

namespace {

// The ranking order: higher score first, then smaller class.
inline bool better(double s, int32_t c, double ts, int32_t tc) { return s > ts || (s == ts && c < tc); }

}  // namespace

void Classifier::offer(int32_t j, int32_t cls, double score, double bg) {
  if (!(score - bg > options_.min_margin && score >= options_.min_score)) return;
  std::vector<Candidate>& lane = lanes_[j];
  const size_t k = static_cast<size_t>(options_.top_k);
  if (lane.size() >= k && !better(score, cls, cutoff_[j].score, cutoff_[j].cls)) return;
  lane.push_back({score, cls});
  if (lane.size() >= 2 * k + 64) {  // keep the best k; later offers must beat the k-th
    const auto by_rank = [](const Candidate& x, const Candidate& y) { return better(x.score, x.cls, y.score, y.cls); };
    std::nth_element(lane.begin(), lane.begin() + static_cast<std::ptrdiff_t>(k - 1), lane.end(), by_rank);
    cutoff_[j] = lane[k - 1];
    cutoff_score_[j] = cutoff_[j].score;
    lane.resize(k);
  }
}

void Classifier::prepare_batch(int32_t b, const uint8_t* values, size_t stride) {
  const Model& m = *model_;
  const detail::ScoringIndex& idx = m.scoring();
  // Fire masks of every stump (stale value rows of lanes >= count, or of dims the word does not
  // need, give bits no scored class reads).
  const std::vector<detail::DenseStump>& stumps = idx.dense_stumps();
  const size_t M = stumps.size();
  if (fire_.size() < (b + 1) * M) fire_.resize((b + 1) * M);
  if (background_.size() < static_cast<size_t>(b + 1) * kBatch) background_.resize(static_cast<size_t>(b + 1) * kBatch);
  uint32_t* fire = fire_.data() + b * M;
  kernels_->fire_masks(stumps.data(), M, values, stride, fire);
  const int64_t* begin = idx.class_stump_begin().data();
  const int32_t C = m.num_classes();
  kernels_->accumulate_lanes(m.data().bias[C], idx.class_stump_index().data() + begin[C], begin[C + 1] - begin[C],
                             stumps.data(), fire, background_.data() + static_cast<size_t>(b) * kBatch);
  if (goal_.size() < background_.size()) goal_.resize(background_.size());
  const double* background = background_.data() + static_cast<size_t>(b) * kBatch;
  double lift[kBatch];
  if (m.has_fusion()) {
    // A fused score is fl(H + t) with a term t of at most fusion_max(): the bound of H need only
    // reach the goals lowered by that much (one screening step more covers the rounding of the
    // addition). screen_word lowers them by each class's own terms.
    std::fill(lift, lift + kBatch, idx.fusion_max() + idx.screen_step());
  }
  detail::screen_goals(m, background, options_.min_margin, options_.min_score,
                       goal_.data() + static_cast<size_t>(b) * kBatch, m.has_fusion() ? lift : nullptr);
}

namespace {

constexpr int32_t kScreenProbe = 64;

// Whether class cls's fusion terms in the lanes `bits` (two batches) cost less than the exact sums
// they may spare: lanes x exemplars x descriptor words against 2 x stumps x 8-lane groups (a
// stump's masked add costs about two popcounts of a word).
bool terms_before_sums(const Model& m, int32_t cls, uint64_t bits) {
  const int64_t exemplars = m.data().fusion.exemplar_begin[cls + 1] - m.data().fusion.exemplar_begin[cls];
  const int64_t stumps = m.scoring().class_stump_begin()[cls + 1] - m.scoring().class_stump_begin()[cls];
  int64_t groups = 0;
  for (int32_t v = 0; v < 2 * Classifier::kBatch / 8; ++v) groups += ((bits >> (8 * v)) & 0xFFu) != 0;
  return __builtin_popcountll(bits) * exemplars * ((m.descriptor_bytes() + 7) / 8) <= 2 * stumps * groups;
}

}  // namespace

void Classifier::screen_word(const int32_t* classes, int32_t num, int32_t batches, int32_t keypoints,
                             const int32_t* ids) {
  const Model& m = *model_;
  const detail::ScoringIndex& idx = m.scoring();
  const size_t M = idx.dense_stumps().size();
  const bool fusion = m.has_fusion();
  if (kept_.size() < static_cast<size_t>(batches)) kept_.resize(static_cast<size_t>(batches));
  if (kept_terms_.size() < static_cast<size_t>(batches)) kept_terms_.resize(static_cast<size_t>(batches));
  const int32_t bytes = m.descriptor_bytes();
  // With the fusion, each batch's descriptors side by side (one kernel call per class and batch,
  // here and in finish_batch).
  const size_t descriptor_rows = static_cast<size_t>(batches) * kBatch;
  if (fusion && lane_descriptors_.size() < descriptor_rows * bytes) lane_descriptors_.resize(descriptor_rows * bytes);
  for (int32_t b = 0; b < batches; ++b) {
    kept_[b].clear();
    kept_terms_[b].clear();
  }
  // Class by class over the word's batches, two at a time: a class's screening list is read once
  // for two batches. The cutoff test of offer() is left out (the cutoff starts at -inf).
  // With the fusion, a class kept by the bound lifted by fusion_max() gets its terms in the lanes
  // kept, and is screened again with the goals lowered by them, from the first screening's
  // residues (detail::screen_terms_pass; the terms are kept for finish_batch).
  for (int32_t b = 0; b < batches; b += 2) {
    int32_t kept_count = 0, probed = 0;
    const int32_t pair = std::min(2, batches - b);
    const uint32_t* fire[2] = {fire_.data() + b * M, fire_.data() + (b + pair - 1) * M};
    const int32_t* goal[2] = {goal_.data() + static_cast<size_t>(b) * kBatch,
                              goal_.data() + static_cast<size_t>(b + pair - 1) * kBatch};
    const double* background[2] = {background_.data() + static_cast<size_t>(b) * kBatch,
                                   background_.data() + static_cast<size_t>(b + pair - 1) * kBatch};
    uint32_t valid[2];
    int32_t count[2] = {0, 0};  // keypoints of each batch
    for (int32_t h = 0; h < pair; ++h) {
      count[h] = std::min(kBatch, keypoints - (b + h) * kBatch);
      valid[h] = count[h] == kBatch ? ~0u : (1u << count[h]) - 1;
    }
    const uint64_t valid_bits = valid[0] | (pair > 1 ? uint64_t{valid[1]} << 32 : 0);
    if (fusion) {
      for (int32_t h = 0; h < pair; ++h) {
        for (int32_t j = 0; j < count[h]; ++j) {
          std::memcpy(lane_descriptors_.data() + static_cast<size_t>(((b + h) * kBatch + j) * bytes),
                      descriptors_ + static_cast<int64_t>(ids[(b + h) * kBatch + j]) * bytes,
                      static_cast<size_t>(bytes));
        }
      }
    }
    for (int32_t i = 0; i < num; ++i) {
      // When the screening keeps most classes (a background that rarely wins), it only costs:
      // after kScreenProbe classes with more than 3/4 of them kept, the rest are kept unscreened.
      // Not with the fusion: there the screening also gives the residues at the end of the list,
      // which make the second screening (below) one test a lane instead of a second walk, so a
      // class it keeps everywhere still costs less than one left unscreened.
      uint64_t bits = valid_bits;
      uint16_t residues[2 * kBatch];
      bool have_residues = false;
      if (options_.screening && (fusion || probed < kScreenProbe || 4 * kept_count <= 3 * probed)) {
        bits = kernels_->screen_class(detail::screen_list(m, classes[i]), pair, fire, goal, valid,
                                      fusion ? residues : nullptr) &
               valid_bits;
        have_residues = fusion;
        ++probed;
        kept_count += bits != 0;
      }
      if (bits == 0) continue;
      double terms[2][kBatch];
      // The terms now, and the second screening, when they cost less than the exact sums they may
      // spare (terms_before_sums). Else, with the screening's residues and fusion balls, upper
      // bounds of the terms from the ball centres' distances (detail::fusion_term_bounds) screen the
      // class again; finish_batch computes the terms after the exact sums, only in the lanes where
      // H plus a bound of the term passes. Either way the same matches.
      const bool early = fusion && terms_before_sums(m, classes[i], bits);
      bool bounded = false;
      if (fusion) {
        int32_t distance[kBatch];
        for (int32_t h = 0; h < pair && (early || have_residues); ++h) {
          std::fill(terms[h], terms[h] + kBatch, early ? 0.0 : idx.fusion_max());
          const auto lanes = static_cast<uint32_t>(bits >> (32 * h));
          if (lanes == 0) continue;
          const uint8_t* lane_descriptors = lane_descriptors_.data() + static_cast<size_t>((b + h) * kBatch * bytes);
          if (early) {
            detail::fusion_terms(m, classes[i], lane_descriptors, lanes, distance, terms[h]);
          } else {
            bounded = options_.fusion_balls &&
                      detail::fusion_term_bounds(m, classes[i], lane_descriptors, lanes, distance, terms[h]);
            if (!bounded) break;
          }
        }
        if (have_residues && (early || bounded)) {
          // The second screening: the end-of-list test with the goals lowered by the terms or bounds.
          uint64_t pass = 0;
          for (int32_t h = 0; h < pair; ++h) {
            const auto lanes = static_cast<uint32_t>(bits >> (32 * h));
            if (lanes != 0) {
              pass |= uint64_t{detail::screen_terms_pass(m, classes[i], residues + kBatch * h, background[h],
                                                         options_.min_margin, options_.min_score, terms[h], lanes)}
                      << (32 * h);
            }
          }
          bits = pass;
          if (bits == 0) continue;
        }
      }
      for (int32_t h = 0; h < pair; ++h) {
        const auto lanes = static_cast<uint32_t>(bits >> (32 * h));
        if (lanes == 0) continue;
        kept_[b + h].push_back({classes[i], lanes, early, bounded});
        if (early || bounded) kept_terms_[b + h].insert(kept_terms_[b + h].end(), terms[h], terms[h] + kBatch);
      }
    }
  }
  classes_screened_ += static_cast<int64_t>(num) * batches;
  for (int32_t b = 0; b < batches; ++b) classes_scored_ += static_cast<int64_t>(kept_[b].size());
}

// H + fusion_max(), or H + the ball bound of the term, bounds the fused score from above (rounding
// is monotone): the descriptor distance is computed only in lanes where that bound passes
// offer()'s tests.
bool Classifier::add_terms_where_they_pass(int32_t cls, int32_t b, int32_t count, const double* bound, double* out) {
  const Model& m = *model_;
  const double* background = background_.data() + static_cast<size_t>(b) * kBatch;
  double lifted[kBatch];
  for (int32_t j = 0; j < kBatch; ++j) lifted[j] = out[j] + (bound != nullptr ? bound[j] : m.scoring().fusion_max());
  if (!kernels_->any_lane_passes(lifted, background, cutoff_score_.data(), options_.min_margin, options_.min_score)) {
    return false;
  }
  uint32_t pass = 0;
  for (int32_t j = 0; j < count; ++j) {
    const double s = lifted[j];
    if (s - background[j] > options_.min_margin && s >= options_.min_score && s >= cutoff_[j].score) {
      pass |= 1u << j;
    } else {
      out[j] = -std::numeric_limits<double>::infinity();
    }
  }
  // The terms of the passing lanes in one kernel call (the same values as fusion_term's).
  if (pass != 0) {  // screen_word's copy of this batch's descriptors
    int32_t distance[kBatch];
    double terms[kBatch];
    detail::fusion_terms(m, cls, lane_descriptors_.data() + static_cast<size_t>(b) * kBatch * m.descriptor_bytes(),
                         pass, distance, terms);
    for (uint32_t l = pass; l != 0; l &= l - 1) {
      const int j = __builtin_ctz(l);
      out[j] += terms[j];
    }
  }
  return true;
}

void Classifier::finish_batch(const int32_t* ids, int32_t count, int32_t b) {
  const Model& m = *model_;
  const detail::ScoringIndex& idx = m.scoring();
  const std::vector<detail::DenseStump>& stumps = idx.dense_stumps();
  const uint32_t* fire = fire_.data() + b * stumps.size();
  const double* background = background_.data() + static_cast<size_t>(b) * kBatch;
  const std::vector<double>& bias = m.data().bias;
  const int64_t* begin = idx.class_stump_begin().data();
  const int32_t* index = idx.class_stump_index().data();
  for (int32_t j = 0; j < count; ++j) {
    lanes_[j].clear();
    cutoff_[j] = {-std::numeric_limits<double>::infinity(), std::numeric_limits<int32_t>::max()};
    cutoff_score_[j] = cutoff_[j].score;
  }
  // The classes kept by the screening: their exact scores in the 8-lane groups where some lane
  // passed the screening (four groups at a time); lanes of the other groups cannot pass and get
  // -inf. Then offered in class order.
  const std::vector<Kept>& kept = kept_[b];
  const int32_t num = static_cast<int32_t>(kept.size());
  if (kept_out_.size() < static_cast<size_t>(num) * kBatch) kept_out_.resize(static_cast<size_t>(num) * kBatch);
  // Classes kept in all four groups go two at a time through accumulate_two.
  groups_.clear();
  int32_t waiting = -1;  // a class kept in all four groups, waiting for a second one
  for (int32_t i = 0; i < num; ++i) {
    const int32_t c = kept[i].cls;
    double* out = kept_out_.data() + static_cast<size_t>(i) * kBatch;
    bool all = true;
    for (int32_t v = 0; v < kBatch / 8; ++v) all = all && ((kept[i].lanes >> (8 * v)) & 0xFFu) != 0;
    if (all && waiting < 0) {
      waiting = i;
    } else if (all) {
      const int32_t c0 = kept[waiting].cls;
      kernels_->accumulate_two(bias[c0], index + begin[c0], begin[c0 + 1] - begin[c0], bias[c], index + begin[c],
                               begin[c + 1] - begin[c], stumps.data(), fire,
                               kept_out_.data() + static_cast<size_t>(waiting) * kBatch, out);
      waiting = -1;
    } else {
      for (int32_t v = 0; v < kBatch / 8; ++v) {
        if ((kept[i].lanes >> (8 * v)) & 0xFFu) {
          groups_.push_back({bias[c], index + begin[c], begin[c + 1] - begin[c], v, out + 8 * v});
        } else {
          std::fill(out + 8 * v, out + 8 * v + 8, -std::numeric_limits<double>::infinity());
        }
      }
    }
  }
  if (waiting >= 0) {
    const int32_t c0 = kept[waiting].cls;
    kernels_->accumulate_lanes(bias[c0], index + begin[c0], begin[c0 + 1] - begin[c0], stumps.data(), fire,
                               kept_out_.data() + static_cast<size_t>(waiting) * kBatch);
  }
  kernels_->accumulate_groups(groups_.data(), static_cast<int32_t>(groups_.size()), stumps.data(), fire);
  const bool fusion = m.has_fusion();
  size_t next_terms = 0;  // kept_terms_[b] holds kBatch terms of each class with terms
  for (int32_t i = 0; i < num; ++i) {
    const int32_t c = kept[i].cls;
    double* out = kept_out_.data() + static_cast<size_t>(i) * kBatch;
    const double* stored = nullptr;  // screen_word's terms or bounds of this class
    if (kept[i].terms || kept[i].bounded) {
      stored = kept_terms_[b].data() + next_terms;
      next_terms += kBatch;
    }
    if (fusion && kept[i].terms) {
      // The terms screen_word computed in the lanes it kept; the other lanes cannot pass.
      for (int32_t j = 0; j < kBatch; ++j) {
        out[j] = (kept[i].lanes >> j) & 1 ? out[j] + stored[j] : -std::numeric_limits<double>::infinity();
      }
    } else if (fusion && !add_terms_where_they_pass(c, b, count, stored, out)) {
      continue;
    }
    if (!kernels_->any_lane_passes(out, background, cutoff_score_.data(), options_.min_margin, options_.min_score)) {
      continue;
    }
    for (int32_t j = 0; j < count; ++j) {
      // offer()'s tests, the cutoff one relaxed to >= (inline: most classes fail here).
      const double s = out[j];
      if (s - background[j] > options_.min_margin && s >= options_.min_score && s >= cutoff_[j].score) {
        offer(j, c, s, background[j]);
      }
    }
  }
  const auto by_rank = [](const Candidate& x, const Candidate& y) { return better(x.score, x.cls, y.score, y.cls); };
  for (int32_t j = 0; j < count; ++j) {
    std::vector<Candidate>& lane = lanes_[j];
    const size_t keep = std::min(lane.size(), static_cast<size_t>(options_.top_k));
    std::partial_sort(lane.begin(), lane.begin() + static_cast<std::ptrdiff_t>(keep), lane.end(), by_rank);
    for (size_t i = 0; i < keep; ++i) {
      ClassMatch match;
      match.cls = lane[i].cls;
      match.landmark = m.class_landmark(match.cls);
      match.score = lane[i].score;
      match.background_score = background[j];
      pending_.emplace_back(ids[j], match);
    }
  }
}

void Classifier::assign_words(const FrameKeypoints& frame, const uint8_t* descriptors, int32_t per_keypoint) {
  const int32_t n = frame.size();
  if (per_keypoint == 1) return;  // frame.word is the only word of each keypoint
  assigned_word_.resize(static_cast<size_t>(n) * per_keypoint);
  const Vocabulary& vocabulary = model_->vocabulary();
  const int32_t W = vocabulary.num_words();
  const int bytes = vocabulary.descriptor_bytes();
  std::vector<uint16_t> distance(static_cast<size_t>(W));
  std::vector<std::pair<uint16_t, int32_t>> ranked;
  for (int32_t k = 0; k < n; ++k) {
    hamming_rows(descriptors + static_cast<int64_t>(k) * bytes, vocabulary.words().data(), W, bytes, distance.data());
    ranked.clear();
    for (int32_t w = 0; w < W; ++w) {
      if (w != frame.word[k]) ranked.emplace_back(distance[w], w);
    }
    std::partial_sort(ranked.begin(), ranked.begin() + (per_keypoint - 1), ranked.end());
    int32_t* out = assigned_word_.data() + static_cast<size_t>(k) * per_keypoint;
    out[0] = frame.word[k];
    for (int32_t i = 1; i < per_keypoint; ++i) out[i] = ranked[static_cast<size_t>(i - 1)].second;
  }
}

void Classifier::merge_pending() {
  std::stable_sort(pending_.begin(), pending_.end(), [](const auto& a, const auto& b) {
    if (a.first != b.first) return a.first < b.first;
    if (a.second.score != b.second.score) return a.second.score > b.second.score;
    return a.second.cls < b.second.cls;
  });
  size_t kept = 0;
  int32_t count = 0;
  for (size_t i = 0; i < pending_.size(); ++i) {
    const bool first_of_keypoint = kept == 0 || pending_[kept - 1].first != pending_[i].first;
    if (first_of_keypoint) count = 0;
    // The same class from two words' groups: the same score, adjacent after the sort.
    if (!first_of_keypoint && pending_[kept - 1].second.cls == pending_[i].second.cls) continue;
    if (count == options_.top_k) continue;
    pending_[kept++] = pending_[i];
    ++count;
  }
  pending_.resize(kept);
}

KeypointMatches Classifier::classify(const FrameKeypoints& frame, const uint8_t* descriptors, const std::string& where,
                                     double* embedding_ms) {
  using Clock = std::chrono::steady_clock;
  const int32_t n = frame.size();
  LMB_CHECK(n == 0 || descriptors != nullptr, where << ": null descriptors for " << n << " keypoints");
  const Clock::time_point t0 = Clock::now();
  index_frame(frame, where);
  return classify_indexed(frame, descriptors, embedding_ms, Clock::now() - t0);
}

KeypointMatches Classifier::classify(const FrameKeypoints& frame, const FrameContext& indexed,
                                     const uint8_t* descriptors, const std::string& where, double* embedding_ms) {
  const Model& m = *model_;
  const int32_t n = frame.size();
  LMB_CHECK(n == 0 || descriptors != nullptr, where << ": null descriptors for " << n << " keypoints");
  LMB_CHECK(indexed.num_keypoints() == n && indexed.num_words() == m.num_words() &&
                indexed.regions().size() == m.regions().size(),
            where << ": the frame's context index holds " << indexed.num_keypoints() << " keypoints, "
                  << indexed.num_words() << " words and " << indexed.regions().size() << " regions; the frame has " << n
                  << " keypoints and the model " << m.num_words() << " words and " << m.regions().size() << " regions");
  struct Restore {
    const FrameContext*& external;
    ~Restore() { external = nullptr; }
  } restore{external_};
  external_ = &indexed;
  return classify_indexed(frame, descriptors, embedding_ms, std::chrono::steady_clock::duration{0});
}

KeypointMatches Classifier::classify_indexed(const FrameKeypoints& frame, const uint8_t* descriptors,
                                             double* embedding_ms, std::chrono::steady_clock::duration embedding) {
  using Clock = std::chrono::steady_clock;
  const Model& m = *model_;
  const detail::ScoringIndex& idx = m.scoring();
  const int32_t n = frame.size();
  Clock::time_point t0;

  // Keypoints grouped by word (inverted file) or all in one group (dense), in keypoint order. With
  // several words a keypoint (inverted_file_words), it sits in each of its words' groups.
  const bool inverted = options_.use_inverted_file;
  const int32_t groups = inverted ? m.num_words() : 1;
  const int32_t per_keypoint = inverted ? std::min(options_.inverted_file_words, m.num_words()) : 1;
  assign_words(frame, descriptors, per_keypoint);
  const auto group_of = [&](int32_t k, int32_t i) -> int32_t {
    if (!inverted) return 0;
    return per_keypoint == 1 ? frame.word[k] : assigned_word_[static_cast<size_t>(k) * per_keypoint + i];
  };
  word_begin_.assign(static_cast<size_t>(groups) + 1, 0);
  for (int32_t k = 0; k < n; ++k) {
    for (int32_t i = 0; i < per_keypoint; ++i) ++word_begin_[group_of(k, i) + 1];
  }
  for (int32_t g = 0; g < groups; ++g) word_begin_[g + 1] += word_begin_[g];
  const int32_t slots = n * per_keypoint;  // keypoint-in-group entries
  order_.resize(static_cast<size_t>(slots));
  {
    std::vector<int32_t> fill(word_begin_.begin(), word_begin_.end() - 1);
    for (int32_t k = 0; k < n; ++k) {
      for (int32_t i = 0; i < per_keypoint; ++i) order_[fill[group_of(k, i)]++] = k;
    }
  }

  const size_t U = idx.used_dims().size();
  const int32_t bytes = m.descriptor_bytes();
  descriptors_ = descriptors;
  pending_.clear();
  // When the keypoints' plans (their word's, or all used dims) cover most of the used dims, every
  // keypoint's values of all used dims at once, region by region (compute_dims_columns), in the
  // order of order_: column u holds used dim u of every keypoint, so that batch b's lanes are
  // contiguous (frame_stride keeps kBatch readable bytes past the last keypoint).
  int64_t planned = 0;
  for (int32_t g = 0; g < groups; ++g) {
    const int64_t dims = inverted ? idx.word_plan(g).size() : static_cast<int64_t>(U);
    planned += dims * (word_begin_[g + 1] - word_begin_[g]);
  }
  const bool columns = 4 * planned >= 3 * static_cast<int64_t>(U) * slots;
  const size_t frame_stride = static_cast<size_t>(slots) + kBatch;
  if (columns) {
    if (embedding_ms) t0 = Clock::now();
    if (frame_values_.size() < U * frame_stride) frame_values_.resize(U * frame_stride);
    if (per_keypoint == 1) {
      indexed().compute_dims_columns(idx.used_plan(), order_.data(), n, descriptors, frame_values_.data(),
                                     frame_stride);
    } else {
      // Each keypoint's values once (in keypoint order), then copied to each of its slots.
      const size_t once_stride = static_cast<size_t>(n) + kBatch;
      if (once_values_.size() < U * once_stride) once_values_.resize(U * once_stride);
      keypoint_ids_.resize(static_cast<size_t>(n));
      for (int32_t k = 0; k < n; ++k) keypoint_ids_[k] = k;
      indexed().compute_dims_columns(idx.used_plan(), keypoint_ids_.data(), n, descriptors, once_values_.data(),
                                     once_stride);
      for (size_t u = 0; u < U; ++u) {
        const uint8_t* from = once_values_.data() + u * once_stride;
        uint8_t* to = frame_values_.data() + u * frame_stride;
        for (int32_t i = 0; i < slots; ++i) to[i] = from[order_[i]];
      }
    }
    if (embedding_ms) embedding += Clock::now() - t0;
  }
  for (int32_t g = 0; g < groups; ++g) {
    const int32_t* classes = all_classes_.data();
    int32_t num = m.num_classes();
    if (inverted) {
      classes = idx.word_classes().data() + idx.word_class_begin()[g];
      num = idx.word_class_begin()[g + 1] - idx.word_class_begin()[g];
    }
    // The group's batches: values, fire masks and background scores of each, then the screening
    // of every candidate class over all of them, then each batch's exact scores and ranking.
    const int32_t keypoints = word_begin_[g + 1] - word_begin_[g];
    const int32_t batches = (keypoints + kBatch - 1) / kBatch;
    for (int32_t batch = 0; batch < batches; ++batch) {
      const int32_t b = word_begin_[g] + batch * kBatch;
      const int32_t count = std::min(kBatch, word_begin_[g + 1] - b);
      if (columns) {  // the frame's values, computed above
        prepare_batch(batch, frame_values_.data() + b, frame_stride);
        continue;
      }
      // Only with the inverted file (dense mode always takes the columns): each keypoint's
      // values of only the dims this word's candidates and the background read.
      assert(inverted);
      if (embedding_ms) t0 = Clock::now();
      for (int32_t j = 0; j < count; ++j) {
        const int32_t k = order_[b + j];
        const uint8_t* desc = descriptors + static_cast<int64_t>(k) * bytes;
        uint8_t* lane = values_.data() + j;  // dim-major: value of used dim u at lane[u * kBatch]
        indexed().compute_dims(k, idx.word_plan(g), desc, word_values_.data());
        const int32_t u0 = idx.word_used_begin()[g], u1 = idx.word_used_begin()[g + 1];
        const int32_t* used = idx.word_used().data() + u0;
        for (int32_t i = 0; i < u1 - u0; ++i) lane[used[i] * kBatch] = word_values_[i];
      }
      if (embedding_ms) embedding += Clock::now() - t0;
      prepare_batch(batch, values_.data(), kBatch);
    }
    screen_word(classes, num, batches, keypoints, order_.data() + word_begin_[g]);
    for (int32_t batch = 0; batch < batches; ++batch) {
      const int32_t b = word_begin_[g] + batch * kBatch;
      finish_batch(order_.data() + b, std::min(kBatch, word_begin_[g + 1] - b), batch);
    }
  }

  // Several words a keypoint: its groups' rankings merged (a class in two lists has the same score
  // in both), best first, ties: smaller class, at most top_k.
  if (per_keypoint > 1) merge_pending();
  if (embedding_ms) *embedding_ms = std::chrono::duration<double, std::milli>(embedding).count();
  return pending_matches(n);
}

KeypointMatches Classifier::pending_matches(int32_t n) const {
  // Back to keypoint order (pending_ holds each keypoint's matches best first, contiguously).
  KeypointMatches out;
  out.begin.assign(static_cast<size_t>(n) + 1, 0);
  for (const auto& p : pending_) ++out.begin[p.first + 1];
  for (int32_t k = 0; k < n; ++k) out.begin[k + 1] += out.begin[k];
  out.matches.resize(pending_.size());
  std::vector<int32_t> fill(out.begin.begin(), out.begin.end() - 1);
  for (const auto& p : pending_) out.matches[fill[p.first]++] = p.second;
  return out;
}

}  // namespace lmb
