// Classifier: feature values against the brute-force embedding, dense and inverted-file scores
// against a reference sum, ranking and background rejection.
#include "infer/classifier.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <vector>

#include <gtest/gtest.h>

#include "common/context_embedding.h"
#include "common/error.h"
#include "common/hamming.h"
#include "common/random.h"
#include "infer/detail/scoring_index.h"
#include "test/infer/test_models.h"

namespace lmb {
namespace {

// A random model: random stumps on random dims (context and bits), random sharing sets (some with
// the background), random biases, random inverted file.
ModelData random_model_data(int32_t C, int32_t M, uint64_t seed) {
  Rng rng(seed);
  ModelData d;
  d.descriptor_bytes = test::kCodeDescriptorBytes;
  d.regions = test::test_regions();
  d.vocabulary = test::test_vocabulary(seed);
  d.num_classes = C;
  for (int32_t c = 0; c < C; ++c) {
    d.class_landmark.push_back(10 * c + 1);
    d.class_position.emplace_back(rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(2, 5));
  }
  for (int32_t c = 0; c <= C; ++c) d.bias.push_back(rng.uniform(-1, 1));
  const int32_t num_dims = detail::layout_of(d).num_dims();
  for (int32_t m = 0; m < M; ++m) {
    SharedStump s;
    s.dim = static_cast<int32_t>(rng.below(static_cast<uint64_t>(num_dims)));
    s.theta = detail::layout_of(d).is_context(s.dim) ? static_cast<uint8_t>(rng.below(255)) : 0;
    s.a = rng.uniform(-1, 1);
    s.b = rng.uniform(-0.5, 0.5);
    for (int32_t c = 0; c <= C; ++c) {
      if (rng.uniform() < 0.3) s.classes.push_back(c);
    }
    if (s.classes.empty()) s.classes.push_back(static_cast<int32_t>(rng.below(static_cast<uint64_t>(C) + 1)));
    d.stumps.push_back(s);
  }
  d.inverted_file.assign(static_cast<size_t>(d.vocabulary.num_words()), {});
  for (auto& list : d.inverted_file) {
    for (int32_t c = 0; c < C; ++c) {
      if (rng.uniform() < 0.4) list.push_back(c);
    }
  }
  return d;
}

// Reference: the dense feature vector of keypoint k (brute-force context + descriptor bits).
std::vector<uint8_t> reference_vector(const Model& m, const FrameKeypoints& frame, int32_t k, const uint8_t* desc) {
  const EmbeddingLayout l = m.scoring().layout();
  std::vector<uint8_t> v(static_cast<size_t>(l.num_dims()));
  embed_context_brute_force(m.regions(), l.num_words, frame, k, v.data());
  for (int32_t b = 0; b < 8 * l.descriptor_bytes; ++b)
    v[l.num_context_dims() + b] = static_cast<uint8_t>(descriptor_bit(desc, b));
  return v;
}

// Reference score: bias + stumps in training order, BoostModel's expression.
double reference_score(const ModelData& d, const std::vector<uint8_t>& v, int32_t c) {
  double total = d.bias[c];
  for (const SharedStump& s : d.stumps) {
    if (std::binary_search(s.classes.begin(), s.classes.end(), c)) {
      total += (v[s.dim] > s.theta ? s.a : 0.0) + s.b;
    }
  }
  return total;
}

// Reference fusion term: the table at the smallest distance to the class's exemplars, by a plain
// loop (0 without fusion).
double reference_fusion(const ModelData& d, const uint8_t* desc, int32_t c) {
  if (!d.fusion.enabled() || c >= d.num_classes) return 0.0;
  int best = 1 << 30;
  for (int64_t r = d.fusion.exemplar_begin[c]; r < d.fusion.exemplar_begin[c + 1]; ++r) {
    best =
        std::min(best, hamming_distance(desc, d.fusion.exemplars.data() + r * d.descriptor_bytes, d.descriptor_bytes));
  }
  return d.fusion.distance_score[best];
}

// A random fusion: 1..max_rows exemplars a class, some of them copies of the frame's descriptors
// with a few bits flipped (so that small distances occur), a table falling from about +3 to -2.
// Each class gets 1..max_rows exemplars: near copies (at most 11 bits flipped) of frame descriptors
// or random rows; clustered: near copies of 3 random descriptors only (tight fusion balls far from
// the frame's descriptors).
void add_random_fusion(ModelData* d, const test::TestFrame& frame, uint64_t seed, int max_rows = 4,
                       bool clustered = false) {
  Rng rng(seed);
  const int32_t bytes = d->descriptor_bytes;
  const int64_t n = static_cast<int64_t>(frame.keypoints.size());
  DescriptorFusion& f = d->fusion;
  f.exemplar_begin = {0};
  for (int32_t c = 0; c < d->num_classes; ++c) {
    const int rows = 1 + static_cast<int>(rng.below(static_cast<uint64_t>(max_rows)));
    std::vector<uint8_t> prototypes(static_cast<size_t>(3 * bytes));
    for (auto& b : prototypes) b = static_cast<uint8_t>(rng.below(256));
    for (int r = 0; r < rows; ++r) {
      std::vector<uint8_t> e(static_cast<size_t>(bytes));
      if (clustered || rng.uniform() < 0.6) {
        const uint8_t* src =
            clustered ? prototypes.data() + static_cast<int64_t>(rng.below(3)) * bytes
                      : frame.descriptors.data() + static_cast<int64_t>(rng.below(static_cast<uint64_t>(n))) * bytes;
        std::copy(src, src + bytes, e.begin());
        const int flips = static_cast<int>(rng.below(12));
        for (int i = 0; i < flips; ++i) {
          const int bit = static_cast<int>(rng.below(static_cast<uint64_t>(8 * bytes)));
          e[bit / 8] ^= static_cast<uint8_t>(1 << (bit % 8));
        }
      } else {
        for (auto& b : e) b = static_cast<uint8_t>(rng.below(256));
      }
      f.exemplars.insert(f.exemplars.end(), e.begin(), e.end());
    }
    f.exemplar_begin.push_back(f.exemplar_begin.back() + rows);
  }
  double v = 3.0;
  for (int32_t dist = 0; dist <= 8 * bytes; ++dist) {
    f.distance_score.push_back(v);
    v -= rng.uniform(0.0, 10.0 / (8 * bytes));
  }
}

FrameKeypoints frame_of(const test::TestFrame& f, const Vocabulary& vocab, std::vector<uint8_t>* words) {
  words->resize(f.keypoints.size());
  vocab.quantize(f.descriptors.data(), static_cast<int64_t>(f.keypoints.size()), words->data());
  return frame_keypoints_from_detections(f.camera, f.keypoints.data(), words->data(),
                                         static_cast<int32_t>(f.keypoints.size()), f.gravity_in_cam, "test");
}

TEST(ClassifierTest, ValuesAndScoresEqualTheReference) {
  const auto model = std::make_shared<const Model>(random_model_data(9, 60, 11));
  const ModelData& d = model->data();
  const test::TestWorld world = test::make_test_world(40, 40, 60, 4);
  std::vector<uint8_t> words;
  const FrameKeypoints frame = frame_of(world.frame, model->vocabulary(), &words);
  Classifier classifier(model);
  classifier.index_frame(frame);
  std::vector<uint8_t> values(model->scoring().used_dims().size());
  std::vector<double> scores(static_cast<size_t>(d.num_classes) + 1);
  int nonzero_context = 0;
  for (int32_t k = 0; k < frame.size(); ++k) {
    const uint8_t* desc = world.frame.descriptors.data() + k * d.descriptor_bytes;
    const std::vector<uint8_t> v = reference_vector(*model, frame, k, desc);
    classifier.compute_used_values(k, desc, values.data());
    for (size_t u = 0; u < values.size(); ++u) {
      ASSERT_EQ(values[u], v[model->scoring().used_dims()[u]])
          << "keypoint " << k << " dim " << model->scoring().used_dims()[u];
      if (model->scoring().layout().is_context(model->scoring().used_dims()[u]) && values[u] > 0) ++nonzero_context;
    }
    classifier.dense_scores(values.data(), scores.data());
    for (int32_t c = 0; c <= d.num_classes; ++c) {
      const double ref = reference_score(d, v, c);
      EXPECT_EQ(scores[c], ref) << "dense, keypoint " << k << " class " << c;  // bit-identical
      EXPECT_EQ(classifier.class_score(values.data(), c), ref) << "per class, keypoint " << k;
    }
  }
  EXPECT_GT(nonzero_context, 50);  // the context path was exercised
}

// classify() against the reference: every keypoint's matches are the classes (its word's
// candidates with the inverted file) whose reference score beats the background's by more than
// the margin, best first (ties: smaller class), at most top_k. Returns the keypoints matched.
int expect_classify_matches_reference(const std::shared_ptr<const Model>& model, const test::TestFrame& tf,
                                      const ClassifierOptions& o) {
  const ModelData& d = model->data();
  std::vector<uint8_t> words;
  const FrameKeypoints frame = frame_of(tf, model->vocabulary(), &words);
  Classifier classifier(model, o);
  const KeypointMatches got = classifier.classify(frame, tf.descriptors.data());
  EXPECT_EQ(got.num_keypoints(), frame.size());
  int matched = 0;
  for (int32_t k = 0; k < frame.size(); ++k) {
    const uint8_t* desc = tf.descriptors.data() + k * d.descriptor_bytes;
    const std::vector<uint8_t> v = reference_vector(*model, frame, k, desc);
    const double bg = reference_score(d, v, d.num_classes);
    // Candidate words: the keypoint's own, then the nearest others by a bit-by-bit Hamming
    // distance (ties: smaller word), inverted_file_words in all.
    std::vector<int32_t> candidate_words = {frame.word[k]};
    if (o.use_inverted_file && o.inverted_file_words > 1) {
      std::vector<std::pair<int, int32_t>> others;
      for (int32_t w = 0; w < d.vocabulary.num_words(); ++w) {
        if (w == frame.word[k]) continue;
        int bits = 0;
        for (int b = 0; b < 8 * d.descriptor_bytes; ++b) {
          bits += ((desc[b / 8] >> (b % 8)) & 1) != ((d.vocabulary.word(w)[b / 8] >> (b % 8)) & 1);
        }
        others.emplace_back(bits, w);
      }
      std::sort(others.begin(), others.end());
      for (int32_t i = 0; i + 1 < o.inverted_file_words && i < static_cast<int32_t>(others.size()); ++i) {
        candidate_words.push_back(others[static_cast<size_t>(i)].second);
      }
    }
    std::vector<std::pair<double, int32_t>> expected;  // (-score, class)
    for (int32_t c = 0; c < d.num_classes; ++c) {
      if (o.use_inverted_file) {
        bool listed = false;
        for (int32_t w : candidate_words) {
          const auto& list = d.inverted_file[w];
          listed = listed || std::binary_search(list.begin(), list.end(), c);
        }
        if (!listed) continue;
      }
      const double s = reference_score(d, v, c) + reference_fusion(d, desc, c);
      if (s - bg > o.min_margin) expected.emplace_back(-s, c);
    }
    std::sort(expected.begin(), expected.end());
    if (static_cast<int>(expected.size()) > o.top_k) expected.resize(static_cast<size_t>(o.top_k));
    EXPECT_EQ(got.count(k), static_cast<int32_t>(expected.size())) << "keypoint " << k;
    if (got.count(k) != static_cast<int32_t>(expected.size())) return matched;
    for (int32_t j = 0; j < got.count(k); ++j) {
      const ClassMatch& m = got.of(k)[j];
      EXPECT_EQ(m.cls, expected[j].second);
      EXPECT_EQ(m.score, -expected[j].first);
      EXPECT_EQ(m.background_score, bg);
      EXPECT_EQ(m.landmark, d.class_landmark[m.cls]);
    }
    matched += got.count(k) > 0;
  }
  return matched;
}

TEST(ClassifierTest, RankingTopKAndBackgroundRejection) {
  ModelData data = random_model_data(12, 80, 12);
  data.bias[12] += 3.0;  // a stronger background, so that some keypoints are rejected
  const auto model = std::make_shared<const Model>(std::move(data));
  const test::TestWorld world = test::make_test_world(30, 30, 30, 5);
  for (int top_k : {1, 3}) {
    for (double margin : {0.0, 0.3}) {
      for (bool inverted : {false, true}) {
        ClassifierOptions o;
        o.top_k = top_k;
        o.min_margin = margin;
        o.use_inverted_file = inverted;
        const int matched = expect_classify_matches_reference(model, world.frame, o);
        EXPECT_GT(matched, 0);
        EXPECT_LT(matched, static_cast<int>(world.frame.keypoints.size()));  // some rejected as background
      }
    }
  }
}

// Many classes and keypoints: several batches of Classifier::kBatch keypoints per word, and
// more passing classes than the ranking keeps (its pruning to the best top_k).
TEST(ClassifierTest, ManyClassesAndKeypointsEqualTheReference) {
  const auto model = std::make_shared<const Model>(random_model_data(260, 120, 15));
  const test::TestWorld world = test::make_test_world(260, 150, 150, 6);
  ASSERT_GT(world.frame.keypoints.size(), static_cast<size_t>(4 * Classifier::kBatch));
  for (int top_k : {1, 7, 300}) {
    for (double margin : {-std::numeric_limits<double>::infinity(), 0.0}) {
      for (bool inverted : {false, true}) {
        ClassifierOptions o;
        o.top_k = top_k;
        o.min_margin = margin;
        o.use_inverted_file = inverted;
        EXPECT_GT(expect_classify_matches_reference(model, world.frame, o), 0);
      }
    }
  }
}

// Multiple assignment (inverted_file_words > 1): a keypoint's candidates are the union of its
// nearest words' lists, its rankings from their groups merged (a class in two lists once), as the
// reference says; more words than the vocabulary holds (256) means every word.
TEST(ClassifierTest, SeveralWordsAKeypointEqualTheReference) {
  const auto model = std::make_shared<const Model>(random_model_data(260, 120, 15));
  const test::TestWorld world = test::make_test_world(260, 150, 150, 6);
  for (int words : {2, 3, 256}) {
    for (int top_k : {1, 7, 300}) {
      for (double margin : {-std::numeric_limits<double>::infinity(), 0.0}) {
        ClassifierOptions o;
        o.top_k = top_k;
        o.min_margin = margin;
        o.use_inverted_file = true;
        o.inverted_file_words = words;
        EXPECT_GT(expect_classify_matches_reference(model, world.frame, o), 0) << words << " " << top_k;
      }
    }
  }
}

// A model whose words need few of the used dims (each class owns its stumps and sits in one
// word's list; the background has a few stumps): classify() computes each keypoint's word's dims
// only, keypoint by keypoint (not the frame's columns of every used dim), and still gives the
// reference's matches.
TEST(ClassifierTest, SmallWordPlansTakeThePerKeypointPathAndEqualTheReference) {
  ModelData data = random_model_data(64, 240, 17);
  const int32_t C = data.num_classes;
  for (size_t m = 0; m < data.stumps.size(); ++m) {
    data.stumps[m].classes = {m % 40 == 0 ? C : static_cast<int32_t>(m % static_cast<size_t>(C))};
  }
  const int32_t W = data.vocabulary.num_words();
  for (int32_t w = 0; w < W; ++w) {
    data.inverted_file[w].clear();
    for (int32_t c = w; c < C; c += W) data.inverted_file[w].push_back(c);
  }
  const auto model = std::make_shared<const Model>(std::move(data));
  const test::TestWorld world = test::make_test_world(64, 120, 120, 8);
  std::vector<uint8_t> words;
  const FrameKeypoints frame = frame_of(world.frame, model->vocabulary(), &words);
  // classify()'s rule: the frame's columns only when the words' dims are >= 3/4 of all used dims.
  int64_t planned = 0;
  for (uint8_t w : words) planned += model->scoring().word_plan(w).size();
  const int64_t all = static_cast<int64_t>(model->scoring().used_dims().size()) * frame.size();
  ASSERT_LT(4 * planned, 3 * all) << "the words' plans should be small";
  for (int top_k : {1, 4}) {
    for (double margin : {-std::numeric_limits<double>::infinity(), 0.0}) {
      for (int per_keypoint : {1, 2}) {  // two words a keypoint: still the per-keypoint path here
        ClassifierOptions o;
        o.top_k = top_k;
        o.min_margin = margin;
        o.use_inverted_file = true;
        o.inverted_file_words = per_keypoint;
        EXPECT_GT(expect_classify_matches_reference(model, world.frame, o), 0);
      }
    }
  }
}

// The SIMD levels this CPU can run (common/simd/simd_level.h), generic first.
std::vector<SimdLevel> supported_levels() {
  std::vector<SimdLevel> levels;
  for (SimdLevel l : compiled_simd_levels()) {
    if (simd_level_supported(l)) levels.push_back(l);
  }
  return levels;
}

// Screening bounds (Model::build_screen, the screen_class kernels) on models of ordinary and of
// adversarial scales (outputs from 1e-9 to 1e6 mixed, large biases; lists longer than several
// checkpoints): with each lane's background just below the class's exact score (so the exact
// score passes the margin test by the smallest step), the screening must keep every valid lane,
// through every checkpoint; with the background well above, it must drop the class (the bound is
// tight enough to matter); every level's kernel returns the generic kernel's bits, for a pair of
// batches and for each batch alone.
TEST(Screening, BoundIsNeverBelowTheExactScoreAndKernelsAgree) {
  constexpr int32_t B = Classifier::kBatch;
  const detail::ScoringKernels& generic = *detail::scoring_kernels(SimdLevel::kGeneric);
  for (int scale = 0; scale < 4; ++scale) {
    ModelData data = random_model_data(40, 700, 30 + scale);
    Rng rng(40 + scale);
    if (scale == 1) {
      for (SharedStump& s : data.stumps) {
        const double magnitude = std::pow(10.0, rng.uniform(-9, 6));
        s.a *= magnitude;
        s.b *= magnitude;
      }
      for (double& b : data.bias) b *= 1e6;
    } else if (scale == 2) {
      for (SharedStump& s : data.stumps) s.a = 1e-3 * std::nearbyint(1000 * s.a);  // ties of q rounding
      // A huge background-only stump: not screened, so it must not coarsen the step.
      SharedStump huge = data.stumps.front();
      huge.a = 1e300;
      huge.classes = {data.num_classes};
      data.stumps.push_back(huge);
    } else if (scale == 3) {
      // Outputs and biases on a grid of 1/64, coarser than the screening step: every q_m is
      // exact, so the bound exceeds the exact score by its rounding slack only, and the integer
      // test must keep a lane whose score passes by one ulp.
      for (SharedStump& s : data.stumps) {
        s.a = std::nearbyint(64 * s.a) / 64;
        s.b = std::nearbyint(64 * s.b) / 64;
      }
      for (double& b : data.bias) b = std::nearbyint(64 * b) / 64;
    }
    const Model model(std::move(data));
    if (scale == 2) {
      EXPECT_LT(model.scoring().screen_step(), 1e-2);
    }
    if (scale == 3) {
      ASSERT_LE(model.scoring().screen_step(), 1.0 / 64);
    }
    ASSERT_GT(model.scoring().screen_check_low().size(), 0u) << "scale " << scale << ": no checkpoints";
    const size_t M = model.scoring().dense_stumps().size();
    std::vector<uint32_t> fire0(M), fire1(M);
    const double inf = std::numeric_limits<double>::infinity();
    int dropped = 0, trials = 0;
    for (int trial = 0; trial < 20; ++trial) {
      for (uint32_t& f : fire0) f = static_cast<uint32_t>(rng.next());
      for (uint32_t& f : fire1) f = static_cast<uint32_t>(rng.next());
      const uint32_t valid[2] = {~0u, trial % 4 == 0 ? (1u << (1 + trial % 31)) - 1 : ~0u};
      const uint64_t valid2 = valid[0] | static_cast<uint64_t>(valid[1]) << 32;
      const uint32_t* fire[2] = {fire0.data(), fire1.data()};
      for (int32_t c = 0; c < model.num_classes(); ++c) {
        const int32_t* list = model.scoring().class_stump_index().data() + model.scoring().class_stump_begin()[c];
        const int64_t n = model.scoring().class_stump_begin()[c + 1] - model.scoring().class_stump_begin()[c];
        std::vector<double> below(2 * B), above(2 * B), exact(2 * B);
        for (int32_t b = 0; b < 2; ++b) {
          generic.accumulate_lanes(model.data().bias[c], list, n, model.scoring().dense_stumps().data(), fire[b],
                                   exact.data() + b * B);
        }
        for (int32_t j = 0; j < 2 * B; ++j) {
          below[j] = std::nextafter(exact[j], -inf);
          above[j] = exact[j] + 1.0 + 1e-3 * std::fabs(exact[j]);
        }
        std::vector<int32_t> low_goals(2 * B), high_goals(2 * B), score_goals(B);
        for (int32_t b = 0; b < 2; ++b) {
          detail::screen_goals(model, below.data() + b * B, 0.0, -inf, low_goals.data() + b * B);
          detail::screen_goals(model, above.data() + b * B, 0.0, -inf, high_goals.data() + b * B);
        }
        const int32_t* low_bg[2] = {low_goals.data(), low_goals.data() + B};
        const int32_t* high_bg[2] = {high_goals.data(), high_goals.data() + B};
        const detail::ScreenList screen = detail::screen_list(model, c);
        detail::screen_goals(model, below.data(), -inf, exact[0], score_goals.data());
        const int32_t* score_goal = score_goals.data();
        const uint32_t one = 1;
        const uint64_t high = generic.screen_class(screen, 1, fire, high_bg, valid, nullptr) |
                              generic.screen_class(screen, 1, fire + 1, high_bg + 1, valid + 1, nullptr) << 32;
        for (SimdLevel level : supported_levels()) {
          const detail::ScoringKernels& k = *detail::scoring_kernels(level);
          // Kept in every valid lane of both batches, and of each batch alone.
          ASSERT_EQ(k.screen_class(screen, 2, fire, low_bg, valid, nullptr), valid2)
              << simd_level_name(level) << " scale " << scale << " class " << c << " trial " << trial;
          for (int32_t b = 0; b < 2; ++b) {
            ASSERT_EQ(k.screen_class(screen, 1, fire + b, low_bg + b, valid + b, nullptr), valid[b])
                << simd_level_name(level);
          }
          // min_score: the exact score itself passes score >= min_score (no margin test).
          ASSERT_EQ(k.screen_class(screen, 1, fire, &score_goal, &one, nullptr), 1u) << simd_level_name(level);
          // (A batch's bound only falls from checkpoint to checkpoint: the pair gives each
          // batch's own bits.)
          ASSERT_EQ(k.screen_class(screen, 2, fire, high_bg, valid, nullptr), high) << simd_level_name(level);
        }
        dropped += high == 0;
        ++trials;
      }
    }
    if (scale != 1) {
      EXPECT_GT(dropped, trials * 9 / 10) << "scale " << scale;
    }
  }
}

// The fused second screening from the first one's residues (detail::screen_terms_pass) equals a
// second screen_class walk with the goals lowered by each lane's term (screen_goals with lift =
// term + step), at every SIMD level: the first screening lifted by the largest term, random terms
// up to it, backgrounds around the exact scores so that both screenings keep some lanes and drop
// others.
TEST(Screening, SecondScreeningFromResiduesEqualsASecondWalk) {
  constexpr int32_t B = Classifier::kBatch;
  const Model model(random_model_data(60, 900, 44));
  const detail::ScoringIndex& idx = model.scoring();
  const size_t M = idx.dense_stumps().size();
  const detail::ScoringKernels& generic = *detail::scoring_kernels(SimdLevel::kGeneric);
  Rng rng(45);
  const double term_max = 2.0;
  const double inf = std::numeric_limits<double>::infinity();
  std::vector<uint32_t> fire0(M), fire1(M);
  int64_t first_kept = 0, second_kept = 0, second_dropped = 0;
  for (int trial = 0; trial < 30; ++trial) {
    for (uint32_t& f : fire0) f = static_cast<uint32_t>(rng.next());
    for (uint32_t& f : fire1) f = static_cast<uint32_t>(rng.next());
    const uint32_t valid[2] = {~0u, trial % 3 == 0 ? (1u << (1 + trial % 31)) - 1 : ~0u};
    const uint32_t* fire[2] = {fire0.data(), fire1.data()};
    for (int32_t c = 0; c < model.num_classes(); ++c) {
      const int32_t* list = idx.class_stump_index().data() + idx.class_stump_begin()[c];
      const int64_t n = idx.class_stump_begin()[c + 1] - idx.class_stump_begin()[c];
      double exact[2 * B], background[2 * B], lift[2 * B], terms[2 * B], term_lift[2 * B];
      for (int32_t b = 0; b < 2; ++b) {
        generic.accumulate_lanes(model.data().bias[c], list, n, idx.dense_stumps().data(), fire[b], exact + b * B);
      }
      for (int32_t j = 0; j < 2 * B; ++j) {
        background[j] = exact[j] + rng.uniform(-1.0, 3.0);
        lift[j] = term_max + idx.screen_step();
        terms[j] = rng.uniform(-4.0, term_max);
        term_lift[j] = terms[j] + idx.screen_step();
      }
      int32_t goal[2 * B], term_goal[2 * B];
      for (int32_t b = 0; b < 2; ++b) {
        detail::screen_goals(model, background + b * B, 0.0, -inf, goal + b * B, lift + b * B);
        detail::screen_goals(model, background + b * B, 0.0, -inf, term_goal + b * B, term_lift + b * B);
      }
      const int32_t* goals[2] = {goal, goal + B};
      const int32_t* term_goals[2] = {term_goal, term_goal + B};
      const detail::ScreenList screen = detail::screen_list(model, c);
      const uint64_t second_walk = generic.screen_class(screen, 2, fire, goals, valid, nullptr) &
                                   generic.screen_class(screen, 2, fire, term_goals, valid, nullptr);
      for (SimdLevel level : supported_levels()) {
        const detail::ScoringKernels& k = *detail::scoring_kernels(level);
        uint16_t residues[2 * B];
        const uint64_t first = k.screen_class(screen, 2, fire, goals, valid, residues);
        uint64_t second = 0;
        for (int32_t b = 0; b < 2; ++b) {
          const auto lanes = static_cast<uint32_t>(first >> (32 * b));
          if (lanes != 0) {
            second |= uint64_t{detail::screen_terms_pass(model, c, residues + b * B, background + b * B, 0.0, -inf,
                                                         terms + b * B, lanes)}
                      << (32 * b);
          }
        }
        ASSERT_EQ(second, second_walk) << simd_level_name(level) << " class " << c << " trial " << trial;
        if (level == SimdLevel::kGeneric) {
          first_kept += __builtin_popcountll(first);
          second_kept += __builtin_popcountll(second);
          second_dropped += __builtin_popcountll(first & ~second);
        }
      }
    }
  }
  // Both screenings matter: the first keeps lanes, and the second drops some of them.
  EXPECT_GT(first_kept, 0);
  EXPECT_GT(second_kept, 0);
  EXPECT_GT(second_dropped, 0);
}

// classify() with screening equals classify() without, match for match, on a model where the
// background outscores most classes (so that the screening skips most of them) and on one where
// it rarely wins (the screening stops after its probe and keeps nearly everything).
TEST(Screening, ClassifyEqualsTheUnscreenedPath) {
  for (double shift : {16.0, -16.0}) {
    ModelData data = random_model_data(300, 400, 31);
    data.bias[300] += shift;
    const auto model = std::make_shared<const Model>(std::move(data));
    const test::TestWorld world = test::make_test_world(300, 150, 150, 7);
    std::vector<uint8_t> words;
    const FrameKeypoints frame = frame_of(world.frame, model->vocabulary(), &words);
    for (int top_k : {1, 5}) {
      for (double margin : {0.0, -6.0, -std::numeric_limits<double>::infinity()}) {
        for (bool inverted : {false, true}) {
          ClassifierOptions o;
          o.top_k = top_k;
          o.min_margin = margin;
          o.use_inverted_file = inverted;
          Classifier screened(model, o);
          o.screening = false;
          Classifier plain(model, o);
          const KeypointMatches a = screened.classify(frame, world.frame.descriptors.data());
          const KeypointMatches b = plain.classify(frame, world.frame.descriptors.data());
          ASSERT_EQ(a.begin, b.begin);
          for (size_t i = 0; i < a.matches.size(); ++i) {
            EXPECT_EQ(a.matches[i].cls, b.matches[i].cls);
            EXPECT_EQ(a.matches[i].score, b.matches[i].score);
            EXPECT_EQ(a.matches[i].background_score, b.matches[i].background_score);
          }
          EXPECT_GT(a.matches.size(), 0u) << "top_k " << top_k << " margin " << margin;
          EXPECT_EQ(plain.classes_scored(), plain.classes_screened());
          EXPECT_GT(screened.classes_scored(), 0);
          if (margin == 0.0 && shift > 0) {
            EXPECT_LT(screened.classes_scored(), screened.classes_screened() / 2) << "top_k " << top_k;
          }
          if (shift < 0) {
            EXPECT_GT(4 * screened.classes_scored(), 3 * screened.classes_screened());
          }
        }
      }
    }
    EXPECT_GT(expect_classify_matches_reference(model, world.frame, ClassifierOptions{}), 0);
  }
}

// The descriptor-distance fusion: classify() ranks by stump sum + the table at the nearest
// exemplar's distance (the reference's plain loops), with and without screening (the same matches),
// dense and through the inverted file; the term itself equals the reference. With a table 8 times
// larger (and mostly negative), the bound lifted by fusion_max() keeps nearly every class (1,999 of
// 2,000); the second screening, with each class's own terms, still skips most of them. With up to
// 60 exemplars a class the terms cost more than the exact sums: computed after them (Classifier's
// other path), the same matches.
TEST(Fusion, ClassifyEqualsTheReferenceWithAndWithoutScreening) {
  struct Case {
    double shift, scale;
    int max_rows;
    bool clustered;
  };
  for (const Case& cs : {Case{16.0, 1.0, 4, false}, Case{-16.0, 1.0, 4, false}, Case{16.0, 8.0, 4, false},
                         Case{16.0, 8.0, 60, false}, Case{16.0, 8.0, 60, true}}) {
    const double shift = cs.shift, scale = cs.scale;
    const test::TestWorld world = test::make_test_world(200, 150, 150, 9);
    ModelData data = random_model_data(200, 300, 33);
    data.bias[200] += shift;
    add_random_fusion(&data, world.frame, 34, cs.max_rows, cs.clustered);
    for (double& v : data.fusion.distance_score) v = scale > 1.0 ? scale * (v - 1.0) : v;
    const auto model = std::make_shared<const Model>(std::move(data));
    ASSERT_TRUE(model->has_fusion());
    const ModelData& d = model->data();
    EXPECT_EQ(model->scoring().fusion_max(),
              *std::max_element(d.fusion.distance_score.begin(), d.fusion.distance_score.end()));
    for (size_t k = 0; k < world.frame.keypoints.size(); ++k) {
      const uint8_t* desc = world.frame.descriptors.data() + k * d.descriptor_bytes;
      for (int32_t c = 0; c < d.num_classes; c += 7) {
        ASSERT_EQ(detail::fusion_term(*model, c, desc), reference_fusion(d, desc, c));
      }
    }
    std::vector<uint8_t> words;
    const FrameKeypoints frame = frame_of(world.frame, model->vocabulary(), &words);
    int near = 0;  // matches whose term is large: the fusion decided something
    for (int top_k : {1, 5}) {
      for (double margin : {0.0, -std::numeric_limits<double>::infinity()}) {
        for (bool inverted : {false, true}) {
          ClassifierOptions o;
          o.top_k = top_k;
          o.min_margin = margin;
          o.use_inverted_file = inverted;
          if (top_k > 1) {
            EXPECT_GT(expect_classify_matches_reference(model, world.frame, o), 0);
          }
          Classifier screened(model, o);
          o.fusion_balls = false;
          Classifier without_balls(model, o);
          o.screening = false;
          Classifier plain(model, o);
          const KeypointMatches a = screened.classify(frame, world.frame.descriptors.data());
          const KeypointMatches b = plain.classify(frame, world.frame.descriptors.data());
          const KeypointMatches c = without_balls.classify(frame, world.frame.descriptors.data());
          ASSERT_EQ(a.begin, b.begin);
          ASSERT_EQ(c.begin, b.begin);
          for (size_t i = 0; i < a.matches.size(); ++i) {
            EXPECT_EQ(a.matches[i].cls, b.matches[i].cls);
            EXPECT_EQ(a.matches[i].score, b.matches[i].score);
            EXPECT_EQ(c.matches[i].cls, b.matches[i].cls);
            EXPECT_EQ(c.matches[i].score, b.matches[i].score);
          }
          for (int32_t k = 0; k < a.num_keypoints(); ++k) {
            if (a.count(k) == 0) continue;
            near += detail::fusion_term(*model, a.of(k)[0].cls,
                                        world.frame.descriptors.data() + k * d.descriptor_bytes) > 1.0;
          }
          if (margin == 0.0 && shift > 0) {  // the lifted bounds still skip classes
            EXPECT_LT(screened.classes_scored(), screened.classes_screened()) << "top_k " << top_k;
          }
          if (margin == 0.0 && scale > 1.0 && cs.max_rows == 4) {
            EXPECT_LT(2 * screened.classes_scored(), screened.classes_screened()) << "top_k " << top_k;
          }
          if (margin == 0.0 && scale > 1.0 && cs.max_rows == 60 && !cs.clustered) {
            // Many exemplars, spread out: the terms come after the exact sums and the balls are
            // too wide to screen again.
            EXPECT_GT(2 * screened.classes_scored(), screened.classes_screened()) << "top_k " << top_k;
          }
          if (margin == 0.0 && scale > 1.0 && cs.clustered) {  // the tight balls screen again
            EXPECT_LT(2 * screened.classes_scored(), screened.classes_screened()) << "top_k " << top_k;
            EXPECT_LT(2 * screened.classes_scored(), without_balls.classes_scored()) << "top_k " << top_k;
          }
        }
      }
    }
    EXPECT_GT(near, 0);
  }
}

// The fusion balls: ceil(sqrt(2 n)) a class with at least kMinBallExemplars exemplars, none below;
// each exemplar within its nearest centre's radius; the bound at least the term for any
// descriptor; and, for a class whose exemplars are one descriptor repeated (radius 0) and a
// non-increasing table, the term itself.
TEST(Fusion, BallBoundsCoverTheExemplarsAndBoundTheTerm) {
  const test::TestWorld world = test::make_test_world(200, 150, 150, 9);
  ModelData data = random_model_data(60, 80, 35);
  add_random_fusion(&data, world.frame, 36, 40, true);
  DescriptorFusion& f = data.fusion;
  const int32_t bytes = data.descriptor_bytes;
  const int64_t last = f.exemplar_begin[59];  // class 59: its first exemplar, 9 times
  const std::vector<uint8_t> one(f.exemplars.begin() + last * bytes, f.exemplars.begin() + (last + 1) * bytes);
  f.exemplars.resize(static_cast<size_t>(last) * bytes);
  for (int r = 0; r < 9; ++r) f.exemplars.insert(f.exemplars.end(), one.begin(), one.end());
  f.exemplar_begin[60] = last + 9;
  const auto model = std::make_shared<const Model>(std::move(data));
  const ModelData& d = model->data();
  const detail::ScoringIndex& idx = model->scoring();
  ASSERT_EQ(idx.fusion_ball_begin().size(), 61u);
  int with_balls = 0;
  for (int32_t c = 0; c < 60; ++c) {
    const int64_t first = d.fusion.exemplar_begin[c], n = d.fusion.exemplar_begin[c + 1] - first;
    const int64_t b0 = idx.fusion_ball_begin()[c], b1 = idx.fusion_ball_begin()[c + 1];
    const int64_t want = n < detail::ScoringIndex::kMinBallExemplars
                             ? 0
                             : static_cast<int64_t>(std::ceil(std::sqrt(2.0 * static_cast<double>(n))));
    ASSERT_EQ(b1 - b0, want) << "class " << c << " with " << n << " exemplars";
    with_balls += b1 > b0;
    for (int64_t i = 0; i < n && b1 > b0; ++i) {
      const uint8_t* row = d.fusion.exemplars.data() + (first + i) * bytes;
      bool covered = false;
      for (int64_t b = b0; b < b1; ++b) {
        covered = covered || hamming_distance(row, idx.fusion_ball_centres().data() + b * bytes, bytes) <=
                                 idx.fusion_ball_radius()[b];
      }
      EXPECT_TRUE(covered) << "class " << c << " exemplar " << i;
    }
  }
  EXPECT_GT(with_balls, 20);
  Rng rng(37);
  std::vector<uint8_t> queries(static_cast<size_t>(32) * bytes);
  for (int trial = 0; trial < 20; ++trial) {
    for (int32_t j = 0; j < 32; ++j) {  // half near an exemplar (up to 31 bits flipped), half random
      uint8_t* q = queries.data() + static_cast<size_t>(j) * bytes;
      if (j % 2 == 0) {
        const uint8_t* src =
            d.fusion.exemplars.data() +
            static_cast<int64_t>(rng.below(static_cast<uint64_t>(d.fusion.exemplar_begin[60]))) * bytes;
        std::copy(src, src + bytes, q);
        for (uint64_t flips = rng.below(32); flips > 0; --flips) {
          const auto bit = static_cast<int32_t>(rng.below(static_cast<uint64_t>(8 * bytes)));
          q[bit / 8] ^= static_cast<uint8_t>(1 << (bit % 8));
        }
      } else {
        for (int32_t k = 0; k < bytes; ++k) q[k] = static_cast<uint8_t>(rng.below(256));
      }
    }
    const auto lanes = static_cast<uint32_t>(rng.below(1ull << 32)) | 1u;
    for (int32_t c = 0; c < 60; ++c) {
      double bound[32], term[32];
      int32_t distance[32];
      if (!detail::fusion_term_bounds(*model, c, queries.data(), lanes, distance, bound)) {
        EXPECT_EQ(idx.fusion_ball_begin()[c], idx.fusion_ball_begin()[c + 1]);
        continue;
      }
      detail::fusion_terms(*model, c, queries.data(), lanes, distance, term);
      for (uint32_t l = lanes; l != 0; l &= l - 1) {
        const int j = __builtin_ctz(l);
        EXPECT_GE(bound[j], term[j]) << "class " << c << " lane " << j;
        if (c == 59) {  // one point, radius 0
          EXPECT_EQ(bound[j], term[j]) << "lane " << j;
        }
      }
    }
  }
}

// Every SIMD level classifies like the generic kernels, match for match and score for score, with
// and without screening, the inverted file and the descriptor-distance fusion, on frames whose keypoint counts leave
// partial batches, column chunks and 16-lane tails.
TEST(ClassifierTest, EverySimdLevelGivesTheGenericMatches) {
  for (bool fusion : {false, true}) {
    for (int32_t keypoints : {1, 37, 150}) {
      const test::TestWorld world = test::make_test_world(300, keypoints, keypoints, 9);
      ModelData data = random_model_data(300, 400, 33);
      data.bias[300] += 8.0;
      if (fusion) add_random_fusion(&data, world.frame, 34);
      const auto model = std::make_shared<const Model>(std::move(data));
      std::vector<uint8_t> words;
      const FrameKeypoints frame = frame_of(world.frame, model->vocabulary(), &words);
      for (bool inverted : {false, true}) {
        for (bool screening : {true, false}) {
          ClassifierOptions o;
          o.top_k = 3;
          o.min_margin = -4.0;
          o.use_inverted_file = inverted;
          o.screening = screening;
          Classifier reference(model, o);
          reference.use_simd_level(SimdLevel::kGeneric);
          const KeypointMatches want = reference.classify(frame, world.frame.descriptors.data());
          EXPECT_GT(want.matches.size(), 0u);
          for (SimdLevel level : supported_levels()) {
            Classifier c(model, o);
            c.use_simd_level(level);
            ASSERT_EQ(c.simd_level(), level);
            const KeypointMatches got = c.classify(frame, world.frame.descriptors.data());
            ASSERT_EQ(got.begin, want.begin) << simd_level_name(level);
            for (size_t i = 0; i < got.matches.size(); ++i) {
              ASSERT_EQ(got.matches[i].cls, want.matches[i].cls) << simd_level_name(level);
              ASSERT_EQ(got.matches[i].score, want.matches[i].score) << simd_level_name(level);
              ASSERT_EQ(got.matches[i].background_score, want.matches[i].background_score) << simd_level_name(level);
            }
            EXPECT_EQ(c.classes_scored(), reference.classes_scored()) << simd_level_name(level);
          }
        }
      }
    }
  }
}

TEST(ClassifierTest, InvertedFileComputesOnlyTheWordsDims) {
  const Model model(random_model_data(20, 100, 13));
  for (int32_t w = 0; w < model.num_words(); ++w) {
    std::vector<int32_t> expected;
    std::vector<int32_t> classes = model.data().inverted_file[w];
    classes.push_back(model.background_class());
    for (size_t u = 0; u < model.scoring().used_dims().size(); ++u) {
      bool needed = false;
      for (int32_t c : classes) {
        for (int64_t e = model.scoring().class_stump_begin()[c]; e < model.scoring().class_stump_begin()[c + 1]; ++e) {
          needed |= model.scoring().class_stumps()[e].used == static_cast<int32_t>(u);
        }
      }
      if (needed) expected.push_back(static_cast<int32_t>(u));
    }
    const std::vector<int32_t> got(model.scoring().word_used().begin() + model.scoring().word_used_begin()[w],
                                   model.scoring().word_used().begin() + model.scoring().word_used_begin()[w + 1]);
    EXPECT_EQ(got, expected) << "word " << w;
    EXPECT_LE(got.size(), model.scoring().used_dims().size());
  }
}

TEST(ClassifierTest, RejectsBadOptionsAndInput) {
  const auto model = std::make_shared<const Model>(random_model_data(3, 10, 14));
  ClassifierOptions o;
  o.top_k = 0;
  EXPECT_THROW(Classifier(model, o), Error);
  o = {};
  o.min_margin = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(Classifier(model, o), Error);
  for (int words : {0, 257}) {
    o = {};
    o.inverted_file_words = words;
    try {
      Classifier c(model, o);
      ADD_FAILURE() << words;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("inverted_file_words = " + std::to_string(words) + " must be in 1..256"),
                std::string::npos)
          << e.what();
    }
  }
  EXPECT_THROW(Classifier(nullptr), Error);
  Classifier classifier(model);
  FrameKeypoints frame;
  frame.x = {0.f};
  frame.y = {0.f};
  frame.scale = {0.01f};
  frame.word = {static_cast<uint8_t>(model->num_words())};  // out of range
  const std::vector<uint8_t> desc(8, 0);
  EXPECT_THROW(classifier.classify(frame, desc.data()), Error);
  frame.word = {0};
  EXPECT_THROW(classifier.classify(frame, nullptr), Error);
  EXPECT_EQ(classifier.classify(frame, desc.data()).num_keypoints(), 1);
}

}  // namespace
}  // namespace lmb
