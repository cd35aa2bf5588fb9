// The descriptor baselines as matchers against a brute-force reference computed here: Hamming
// 1-NN with Lowe's ratio test (the 2nd neighbour another landmark, or the 2nd observation), with
// both Hamming backends and faiss's binary HNSW (exhaustive on a small problem), including the
// case where every searched neighbour is the best landmark again (the exact fallback).
#include "train/eval/descriptor_matchers.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>

#include <gtest/gtest.h>

#include "common/error.h"
#include "common/hamming.h"
#include "common/random.h"
#include "train/eval/faiss_index.h"

namespace lmb {
namespace {

constexpr int kBytes = 32;
constexpr int kLandmarks = 40;

// Observations of kLandmarks landmarks: each landmark a random centre, its observations the
// centre with a few bits flipped; landmark 0 has 30 observations (more than the searched k),
// the others 1..8. Queries: observations' centres with a few flips, twins of landmark pairs
// (ambiguous), and random descriptors.
struct Problem {
  TrainingObservations obs;
  std::vector<uint8_t> queries;
  int64_t num_queries = 0;
  std::vector<Eigen::Vector3d> positions;
};

void flip_bits(uint8_t* d, int flips, Rng& rng) {
  for (int i = 0; i < flips; ++i) {
    const uint64_t bit = rng.below(kBytes * 8);
    d[bit / 8] ^= static_cast<uint8_t>(1u << (bit % 8));
  }
}

Problem make_problem(uint64_t seed) {
  Rng rng(seed);
  Problem p;
  p.obs.descriptor_bytes = kBytes;
  std::vector<std::vector<uint8_t>> centre(kLandmarks, std::vector<uint8_t>(kBytes));
  for (auto& c : centre) {
    for (auto& b : c) b = static_cast<uint8_t>(rng.below(256));
  }
  // Landmark 1 is a near twin of landmark 2 (the ratio test must reject between them).
  centre[2] = centre[1];
  flip_bits(centre[2].data(), 6, rng);
  for (int l = 0; l < kLandmarks; ++l) {
    const int count = l == 0 ? 30 : 1 + static_cast<int>(rng.below(8));
    for (int i = 0; i < count; ++i) {
      std::vector<uint8_t> d = centre[l];
      flip_bits(d.data(), static_cast<int>(rng.below(12)), rng);
      p.obs.descriptors.insert(p.obs.descriptors.end(), d.begin(), d.end());
      p.obs.landmark.push_back(l);
    }
    p.positions.emplace_back(l, 2.0 * l, 1.0);
  }
  for (int q = 0; q < 90; ++q) {
    std::vector<uint8_t> d(kBytes);
    if (q < 60) {
      d = centre[static_cast<size_t>(q % kLandmarks)];
      flip_bits(d.data(), static_cast<int>(rng.below(30)), rng);
    } else {
      for (auto& b : d) b = static_cast<uint8_t>(rng.below(256));
    }
    p.queries.insert(p.queries.end(), d.begin(), d.end());
  }
  p.num_queries = 90;
  return p;
}

// The reference for one query: exact distances to every observation.
struct Reference {
  double d1 = 0;
  landmark_t l1 = kInvalidLandmarkId;  // landmark of the nearest observation (smallest index)
  double d2_other = 0;                 // nearest observation of another landmark
  double d2_second = 0;                // 2nd nearest observation
};

Reference reference(const TrainingObservations& obs, const uint8_t* q) {
  std::vector<std::pair<double, int64_t>> all;
  for (int64_t i = 0; i < obs.size(); ++i) {
    all.emplace_back(hamming_distance(q, obs.descriptor(i), kBytes), i);
  }
  std::sort(all.begin(), all.end());
  Reference r;
  r.d1 = all[0].first;
  r.l1 = obs.landmark[static_cast<size_t>(all[0].second)];
  r.d2_second = all[1].first;
  r.d2_other = std::numeric_limits<double>::infinity();
  for (const auto& [d, i] : all) {
    if (obs.landmark[static_cast<size_t>(i)] != r.l1) {
      r.d2_other = d;
      break;
    }
  }
  return r;
}

EvalQuery query_of(const Problem& p) {
  EvalQuery q;
  q.keypoints.resize(static_cast<size_t>(p.num_queries));
  q.descriptors = p.queries.data();
  return q;
}

// The matcher's accepted matches equal the reference's: keypoint k accepted with landmark l1
// exactly when d1 < ratio * d2.
void expect_reference(const Problem& p, const Matcher& matcher, RatioNeighbor neighbor, double ratio,
                      int* accepted_count = nullptr) {
  const FrameMatches m = matcher.match(query_of(p));
  ASSERT_EQ(m.ranking.size(), static_cast<size_t>(p.num_queries));
  size_t next = 0;
  int accepted = 0;
  for (int64_t k = 0; k < p.num_queries; ++k) {
    SCOPED_TRACE(testing::Message() << "query " << k);
    const Reference r = reference(p.obs, p.queries.data() + k * kBytes);
    EXPECT_EQ(m.ranking[static_cast<size_t>(k)][0].score, -r.d1);
    const double d2 = neighbor == RatioNeighbor::kOtherLandmark ? r.d2_other : r.d2_second;
    const bool accept = r.d1 < ratio * d2;
    const bool got = next < m.accepted.size() && m.accepted[next].keypoint == k;
    EXPECT_EQ(got, accept) << "d1 " << r.d1 << " d2 " << d2;
    if (got) {
      EXPECT_EQ(m.accepted[next].landmark, r.l1);
      EXPECT_EQ(m.accepted[next].point_world, p.positions[static_cast<size_t>(r.l1)]);
      EXPECT_EQ(m.accepted[next].confidence, -r.d1);
      ++next;
      ++accepted;
    }
  }
  EXPECT_EQ(next, m.accepted.size());
  if (accepted_count != nullptr) *accepted_count = accepted;
}

DescriptorMatcherOptions ratio_options(int knn_k, RatioNeighbor neighbor, double ratio = 0.8) {
  DescriptorMatcherOptions o;
  o.top_k = 2;
  o.knn_k = knn_k;
  o.ratio_test = true;
  o.ratio = ratio;
  o.ratio_neighbor = neighbor;
  return o;
}

TEST(DescriptorMatcherTest, HammingRatioTestEqualsBruteForce) {
  const Problem p = make_problem(11);
  for (auto backend : {BruteforceHamming::Backend::kPopcount, BruteforceHamming::Backend::kOpenCv}) {
    for (RatioNeighbor neighbor : {RatioNeighbor::kOtherLandmark, RatioNeighbor::kSecondObservation}) {
      // knn_k 4 < landmark 0's 30 observations: queries near landmark 0 need the exact fallback.
      for (int knn_k : {4, 64}) {
        for (double ratio : {0.8, 0.6}) {
          SCOPED_TRACE(testing::Message() << "backend " << static_cast<int>(backend) << " neighbour "
                                          << static_cast<int>(neighbor) << " knn_k " << knn_k << " ratio " << ratio);
          const DescriptorMatcher matcher(std::make_unique<HammingKnnIndex>(p.obs, backend), p.positions,
                                          ratio_options(knn_k, neighbor, ratio));
          int accepted = 0;
          expect_reference(p, matcher, neighbor, ratio, &accepted);
          // The problem has both outcomes.
          EXPECT_GT(accepted, 10);
          EXPECT_LT(accepted, 80);
        }
      }
    }
  }
}

// accepted_without against a brute force over the observations of the landmarks not excluded
// (the nearest of the knn_k nearest observations that is not excluded; the 2nd nearest for
// kSecondObservation among those; the exact nearest other landmark for kOtherLandmark).
TEST(DescriptorMatcherTest, AcceptedWithoutEqualsBruteForceWithoutTheExcludedLandmarks) {
  const Problem p = make_problem(11);
  // Landmark 0 (30 observations) and landmark 2 (landmark 1's near twin) are excluded.
  const auto excluded = [](landmark_t l) { return l % 2 == 0; };
  for (int variant = 0; variant < 3; ++variant) {
    for (int knn_k : {4, 64}) {
      SCOPED_TRACE(testing::Message() << "variant " << variant << " knn_k " << knn_k);
      DescriptorMatcherOptions o =
          ratio_options(knn_k, variant == 1 ? RatioNeighbor::kSecondObservation : RatioNeighbor::kOtherLandmark);
      o.ratio_test = variant != 2;
      const DescriptorMatcher matcher(std::make_unique<HammingKnnIndex>(p.obs, BruteforceHamming::Backend::kPopcount),
                                      p.positions, o);
      const std::vector<Correspondence> got = matcher.accepted_without(query_of(p), excluded);
      size_t next = 0;
      int accepted = 0, ambiguous_before = 0;
      for (int64_t k = 0; k < p.num_queries; ++k) {
        const uint8_t* d = p.queries.data() + k * kBytes;
        std::vector<std::pair<double, int64_t>> all;
        for (int64_t i = 0; i < p.obs.size(); ++i)
          all.emplace_back(hamming_distance(d, p.obs.descriptor(i), kBytes), i);
        std::sort(all.begin(), all.end());
        std::vector<std::pair<double, int64_t>> kept;
        for (int i = 0; i < knn_k; ++i) {
          if (!excluded(p.obs.landmark[static_cast<size_t>(all[i].second)])) kept.push_back(all[i]);
        }
        bool accept = !kept.empty();
        landmark_t l1 = kInvalidLandmarkId;
        if (accept) {
          l1 = p.obs.landmark[static_cast<size_t>(kept[0].second)];
          double d2 = std::numeric_limits<double>::infinity();
          if (variant == 1 && kept.size() >= 2) d2 = kept[1].first;
          if (variant == 0) {
            for (const auto& [dist, i] : all) {
              const landmark_t l = p.obs.landmark[static_cast<size_t>(i)];
              if (l != l1 && !excluded(l)) {
                d2 = dist;
                break;
              }
            }
          }
          if (variant != 2) accept = std::isinf(d2) || kept[0].first < o.ratio * d2;
        }
        ambiguous_before += reference(p.obs, d).l1 == 2;
        const bool has = next < got.size() && got[next].keypoint == k;
        EXPECT_EQ(has, accept) << "query " << k;
        if (!has) continue;
        EXPECT_EQ(got[next].landmark, l1) << "query " << k;
        EXPECT_EQ(got[next].point_world, p.positions[static_cast<size_t>(l1)]);
        EXPECT_EQ(got[next].confidence, -kept[0].first);
        ++next;
        ++accepted;
      }
      EXPECT_EQ(next, got.size());
      EXPECT_GT(accepted, 10);
      EXPECT_GT(ambiguous_before, 0);
    }
  }
}

TEST(DescriptorMatcherTest, OtherLandmarkKeepsMatchesTheSecondObservationRejects) {
  // Landmark 0 observed twice with the same descriptor, queried with it: the 2nd observation is
  // landmark 0 again at the same distance, so the plain 2-NN test rejects the match while the
  // other-landmark test accepts it.
  Problem p = make_problem(11);
  std::copy(p.obs.descriptor(0), p.obs.descriptor(0) + kBytes, p.obs.descriptors.begin() + kBytes);
  ASSERT_EQ(p.obs.landmark[1], 0);
  Problem one = p;
  one.queries.assign(p.obs.descriptor(0), p.obs.descriptor(0) + kBytes);
  one.num_queries = 1;
  const auto other = DescriptorMatcher(std::make_unique<HammingKnnIndex>(p.obs, BruteforceHamming::Backend::kPopcount),
                                       p.positions, ratio_options(4, RatioNeighbor::kOtherLandmark))
                         .match(query_of(one));
  const auto second = DescriptorMatcher(std::make_unique<HammingKnnIndex>(p.obs, BruteforceHamming::Backend::kPopcount),
                                        p.positions, ratio_options(4, RatioNeighbor::kSecondObservation))
                          .match(query_of(one));
  ASSERT_EQ(other.accepted.size(), 1u);
  EXPECT_EQ(other.accepted[0].landmark, 0);
  EXPECT_TRUE(second.accepted.empty());
}

TEST(DescriptorMatcherTest, WithoutRatioTestEveryKeypointIsAccepted) {
  const Problem p = make_problem(5);
  DescriptorMatcherOptions o;
  o.top_k = 3;
  o.knn_k = 12;
  const DescriptorMatcher matcher(std::make_unique<HammingKnnIndex>(p.obs, BruteforceHamming::Backend::kPopcount),
                                  p.positions, o);
  const FrameMatches m = matcher.match(query_of(p));
  ASSERT_EQ(m.accepted.size(), static_cast<size_t>(p.num_queries));
  for (int64_t k = 0; k < p.num_queries; ++k) {
    EXPECT_EQ(m.accepted[static_cast<size_t>(k)].landmark, reference(p.obs, p.queries.data() + k * kBytes).l1);
    EXPECT_LE(m.ranking[static_cast<size_t>(k)].size(), 3u);
  }
}

TEST(DescriptorMatcherTest, EdgeCasesAndOptions) {
  Problem p = make_problem(3);
  // Only one landmark in the index: no competitor, the best match is accepted.
  TrainingObservations single;
  single.descriptor_bytes = kBytes;
  single.descriptors.assign(p.obs.descriptor(0), p.obs.descriptor(0) + 3 * kBytes);
  single.landmark = {0, 0, 0};
  const HammingKnnIndex index(single, BruteforceHamming::Backend::kPopcount);
  const auto opts = ratio_options(2, RatioNeighbor::kOtherLandmark);
  EXPECT_TRUE(passes_ratio_test(index.search(p.queries.data(), 1, 2)[0], p.queries.data(), index, opts));
  // d1 = d2 = 0 (two landmarks with the same descriptor) rejects.
  TrainingObservations twins = single;
  twins.landmark = {0, 1, 1};
  std::copy(twins.descriptor(0), twins.descriptor(0) + kBytes, twins.descriptors.begin() + kBytes);
  const HammingKnnIndex twin_index(twins, BruteforceHamming::Backend::kPopcount);
  EXPECT_FALSE(
      passes_ratio_test(twin_index.search(twins.descriptor(0), 1, 2)[0], twins.descriptor(0), twin_index, opts));
  EXPECT_FALSE(passes_ratio_test({}, p.queries.data(), index, opts));

  DescriptorMatcherOptions bad;
  bad.knn_k = 5;  // < top_k 20
  EXPECT_THROW(bad.check(), Error);
  bad = ratio_options(1, RatioNeighbor::kOtherLandmark);
  bad.top_k = 1;
  EXPECT_THROW(bad.check(), Error);  // the ratio test needs 2 neighbours
  bad = ratio_options(4, RatioNeighbor::kOtherLandmark, 1.5);
  EXPECT_THROW(bad.check(), Error);
  EXPECT_THROW(DescriptorMatcher(nullptr, p.positions, ratio_options(4, RatioNeighbor::kOtherLandmark)), Error);
  EXPECT_THROW(DescriptorMatcher(std::make_unique<HammingKnnIndex>(p.obs, BruteforceHamming::Backend::kPopcount),
                                 {Eigen::Vector3d::Zero()}, ratio_options(4, RatioNeighbor::kOtherLandmark)),
               Error);  // observations of landmarks without a position
}

// faiss's binary HNSW with its default degree (M = 32, 64 links a node on level 0) over ~200
// observations, searched with ef_search above the number of observations, visits every node it
// can reach, here all: its neighbours' distances are the exact ones, and its ratio-test matcher
// equals the reference when knn_k exceeds every landmark's observation count. (With M = 8 the
// pruned graph leaves some nodes unreachable and a far query misses one.)
TEST(FaissHnswIndexTest, ExhaustiveSearchEqualsBruteForce) {
  const Problem p = make_problem(17);
  FaissHnswOptions o;
  o.ef_search = 1024;
  const FaissHnswIndex faiss(p.obs, o);
  const HammingKnnIndex exact(p.obs, BruteforceHamming::Backend::kPopcount);
  const auto got = faiss.search(p.queries.data(), p.num_queries, 10);
  const auto want = exact.search(p.queries.data(), p.num_queries, 10);
  ASSERT_EQ(got.size(), want.size());
  for (size_t q = 0; q < got.size(); ++q) {
    ASSERT_EQ(got[q].size(), want[q].size());
    for (size_t j = 0; j < got[q].size(); ++j) EXPECT_EQ(got[q][j].distance, want[q][j].distance) << q << " " << j;
  }
  const DescriptorMatcher matcher(std::make_unique<FaissHnswIndex>(p.obs, o), p.positions,
                                  ratio_options(64, RatioNeighbor::kOtherLandmark));
  expect_reference(p, matcher, RatioNeighbor::kOtherLandmark, 0.8);
  EXPECT_EQ(matcher.parameters().at("ef_search"), 1024);
  EXPECT_EQ(matcher.parameters().at("ratio"), 0.8);
}

TEST(FaissHnswIndexTest, DeterministicAndValidated) {
  const Problem p = make_problem(23);
  const FaissHnswIndex a(p.obs), b(p.obs);
  const auto ra = a.search(p.queries.data(), p.num_queries, 5);
  const auto rb = b.search(p.queries.data(), p.num_queries, 5);
  EXPECT_EQ(ra, rb);
  FaissHnswOptions bad;
  bad.m = 1;
  EXPECT_THROW(FaissHnswIndex(p.obs, bad), Error);
  EXPECT_THROW(FaissHnswIndex(TrainingObservations{}), Error);
  EXPECT_THROW(a.search(p.queries.data(), 1, 0), Error);
}

}  // namespace
}  // namespace lmb
