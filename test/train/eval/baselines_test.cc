#include "train/eval/baselines.h"

#include <algorithm>
#include <cmath>
#include <set>

#include <gtest/gtest.h>

#include "common/error.h"
#include "common/hamming.h"
#include "common/random.h"

namespace lmb {
namespace {

TrainingObservations random_observations(int64_t n, int bytes, int num_landmarks, uint64_t seed) {
  Rng rng(seed);
  TrainingObservations obs;
  obs.descriptor_bytes = bytes;
  obs.descriptors.resize(static_cast<size_t>(n * bytes));
  for (auto& b : obs.descriptors) b = static_cast<uint8_t>(rng.next() & 0xFF);
  for (int64_t i = 0; i < n; ++i) obs.landmark.push_back(static_cast<landmark_t>(rng.next() % num_landmarks));
  return obs;
}

std::vector<uint8_t> random_queries(int64_t n, int bytes, uint64_t seed) {
  Rng rng(seed);
  std::vector<uint8_t> q(static_cast<size_t>(n * bytes));
  for (auto& b : q) b = static_cast<uint8_t>(rng.next() & 0xFF);
  return q;
}

// The reference: every distance, sorted by (distance, index), the first k.
std::vector<Neighbor> reference_hamming(const TrainingObservations& obs, const uint8_t* q, int k) {
  std::vector<Neighbor> all;
  for (int64_t i = 0; i < obs.size(); ++i) {
    all.push_back(Neighbor{i, static_cast<double>(hamming_distance(q, obs.descriptor(i), obs.descriptor_bytes))});
  }
  std::sort(all.begin(), all.end(), [](const Neighbor& a, const Neighbor& b) {
    return a.distance < b.distance || (a.distance == b.distance && a.index < b.index);
  });
  all.resize(std::min<size_t>(all.size(), static_cast<size_t>(k)));
  return all;
}

class HammingSizes : public ::testing::TestWithParam<int> {};

TEST_P(HammingSizes, PopcountMatchesReference) {
  const int bytes = GetParam();
  const auto obs = random_observations(1500, bytes, 100, 7 + bytes);
  const auto queries = random_queries(20, bytes, 99);
  const BruteforceHamming bf(obs);
  for (int q = 0; q < 20; ++q) {
    for (int k : {1, 5, 40}) {
      const uint8_t* d = queries.data() + q * bytes;
      EXPECT_EQ(bf.knn(d, k), reference_hamming(obs, d, k)) << "query " << q << " k " << k;
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Bytes, HammingSizes, ::testing::Values(32, 64, 48, 13));

TEST(BruteforceHamming, FewerObservationsThanKAndExactDuplicates) {
  auto obs = random_observations(5, 64, 3, 1);
  // Observation 3 duplicates observation 1: equal distances, tie broken on the smaller index.
  std::copy(obs.descriptor(1), obs.descriptor(1) + 64, obs.descriptors.begin() + 3 * 64);
  const BruteforceHamming bf(obs);
  const auto nn = bf.knn(obs.descriptor(1), 10);
  ASSERT_EQ(nn.size(), 5u);
  EXPECT_EQ(nn[0], (Neighbor{1, 0.0}));
  EXPECT_EQ(nn[1], (Neighbor{3, 0.0}));
  EXPECT_EQ(nn, reference_hamming(obs, obs.descriptor(1), 10));
  EXPECT_THROW(bf.knn(obs.descriptor(0), 0), Error);
}

TEST(BruteforceHamming, OpenCvBackendFindsTheSameDistances) {
  const auto obs = random_observations(2000, 64, 150, 3);
  const auto queries = random_queries(30, 64, 4);
  const BruteforceHamming ocv(obs, BruteforceHamming::Backend::kOpenCv);
  const BruteforceHamming pop(obs);
  const int k = 10;
  const auto batch = ocv.query_batch(queries.data(), 30, k);
  for (int q = 0; q < 30; ++q) {
    const uint8_t* d = queries.data() + q * 64;
    const auto ref = reference_hamming(obs, d, k);
    const auto got = ocv.knn(d, k);
    ASSERT_EQ(got.size(), ref.size());
    // Same distance sequence; each reported distance is the true one; below the k-th distance the
    // neighbours are the same (OpenCV may pick a different observation among ties at the k-th).
    for (size_t i = 0; i < got.size(); ++i) {
      EXPECT_EQ(got[i].distance, ref[i].distance);
      EXPECT_EQ(got[i].distance, hamming_distance(d, obs.descriptor(got[i].index), 64));
      if (ref[i].distance < ref.back().distance) {
        EXPECT_EQ(got[i].index, ref[i].index);
      }
    }
    // Batch and single queries agree; the popcount path's landmark list starts the same way.
    EXPECT_EQ(batch[static_cast<size_t>(q)].size(), neighbors_to_candidates(got, obs.landmark).size());
    EXPECT_EQ(pop.query(d, k).front().landmark, batch[static_cast<size_t>(q)].front().landmark);
  }
}

TEST(NeighborsToCandidates, FirstOccurrencePerLandmark) {
  const std::vector<landmark_t> landmark = {7, 3, 7, 9, 3};
  const std::vector<Neighbor> nn = {{2, 1.0}, {1, 2.0}, {0, 2.0}, {4, 3.0}, {3, 5.0}};
  const auto c = neighbors_to_candidates(nn, landmark);
  ASSERT_EQ(c.size(), 3u);
  EXPECT_EQ(c[0].landmark, 7);
  EXPECT_EQ(c[1].landmark, 3);
  EXPECT_EQ(c[2].landmark, 9);
  EXPECT_DOUBLE_EQ(c[0].score, -1.0);
  EXPECT_DOUBLE_EQ(c[1].score, -2.0);
  EXPECT_DOUBLE_EQ(c[2].score, -5.0);
}

// ---------------------------------------------------------------------------------------------

std::vector<Neighbor> reference_projected(const ProjectedKdTree& tree, const float* p, int k) {
  const int dims = tree.dims();
  std::vector<std::pair<float, int64_t>> all;
  for (int64_t i = 0; i < tree.observations().size(); ++i) {
    all.push_back({ProjectedKdTree::squared_distance(p, tree.projected().data() + i * dims, dims), i});
  }
  std::sort(all.begin(), all.end());
  std::vector<Neighbor> out;
  for (size_t i = 0; i < all.size() && i < static_cast<size_t>(k); ++i) {
    out.push_back(Neighbor{all[i].second, std::sqrt(static_cast<double>(all[i].first))});
  }
  return out;
}

TEST(ProjectedKdTree, ExactAgainstBruteForce) {
  for (int leaf : {1, 8, 64}) {
    ProjectedKdTreeOptions options;
    options.leaf_size = leaf;
    const auto obs = random_observations(3000, 32, 200, 11);
    const ProjectedKdTree tree(obs, options);
    ASSERT_EQ(tree.projected().size(), 3000u * 16u);
    const auto queries = random_queries(25, 32, 12);
    for (int q = 0; q < 25; ++q) {
      const uint8_t* d = queries.data() + q * 32;
      const Eigen::VectorXf p = tree.project(d);
      for (int k : {1, 10, 50}) {
        EXPECT_EQ(tree.knn(d, k), reference_projected(tree, p.data(), k)) << "leaf " << leaf << " k " << k;
      }
    }
    // A training descriptor is its own nearest neighbour at distance 0 (ties: smaller index).
    const auto self = tree.knn(obs.descriptor(123), 1);
    EXPECT_DOUBLE_EQ(self[0].distance, 0.0);
  }
}

TEST(ProjectedKdTree, ExactWithManyDuplicates) {
  // 40 distinct descriptors, each repeated 50 times: heavy ties that pruning must not lose.
  const auto base = random_observations(40, 64, 10, 5);
  TrainingObservations obs;
  obs.descriptor_bytes = 64;
  for (int rep = 0; rep < 50; ++rep) {
    for (int64_t i = 0; i < base.size(); ++i) {
      obs.descriptors.insert(obs.descriptors.end(), base.descriptor(i), base.descriptor(i) + 64);
      obs.landmark.push_back(base.landmark[static_cast<size_t>(i)]);
    }
  }
  const ProjectedKdTree tree(obs);
  const auto queries = random_queries(10, 64, 6);
  for (int q = 0; q < 10; ++q) {
    const uint8_t* d = q < 5 ? queries.data() + q * 64 : base.descriptor(q);
    const Eigen::VectorXf p = tree.project(d);
    for (int k : {1, 7, 120}) EXPECT_EQ(tree.knn(d, k), reference_projected(tree, p.data(), k));
  }
}

TEST(ProjectedKdTree, PcaFindsTheCorrelatedBits) {
  // Bits 0..7 all equal one alternating bit per observation, bit 40 an uncorrelated (exactly, over
  // the 500 samples) alternating bit, every other bit 0: the first principal component is
  // (1, ..., 1) / sqrt(8) on bits 0..7 (eigenvalue 2), the second bit 40 (eigenvalue 0.25).
  TrainingObservations obs;
  obs.descriptor_bytes = 32;
  for (int i = 0; i < 500; ++i) {
    std::vector<uint8_t> d(32, 0);
    if (i % 2) d[0] = 0xFF;
    d[5] = static_cast<uint8_t>((i / 2) % 2);
    obs.descriptors.insert(obs.descriptors.end(), d.begin(), d.end());
    obs.landmark.push_back(i % 5);
  }
  ProjectedKdTreeOptions options;
  options.dims = 2;
  const ProjectedKdTree tree(obs, options);
  std::vector<uint8_t> ones(32, 0), zeros(32, 0);
  ones[0] = 0xFF;
  // Projections of "all 8 bits set" and "none set" differ by sqrt(8) along the first axis only.
  const Eigen::VectorXf a = tree.project(ones.data()), b = tree.project(zeros.data());
  EXPECT_NEAR(a[0] - b[0], std::sqrt(8.0), 1e-4);
  EXPECT_NEAR(a[1] - b[1], 0.0, 1e-4);
  std::vector<uint8_t> bit40(32, 0);
  bit40[5] = 1;
  const Eigen::VectorXf c = tree.project(bit40.data());
  EXPECT_NEAR(c[0] - b[0], 0.0, 1e-4);
  EXPECT_NEAR(std::abs(c[1] - b[1]), 1.0, 1e-4);
  EXPECT_THROW(ProjectedKdTree(obs, ProjectedKdTreeOptions{300, 20000, 32}), Error);
  EXPECT_THROW(ProjectedKdTree(TrainingObservations{32, {}, {}}), Error);
}

// ---------------------------------------------------------------------------------------------

TEST(CollectTrainingObservations, SkipsQueryFramesBackgroundAndUnselected) {
  LandmarkMap map;
  map.descriptor_bytes = 2;
  map.landmarks.resize(3);
  map.frames.resize(2);
  map.frames[0].first_keypoint = 0;
  map.frames[0].num_keypoints = 4;
  map.frames[1].first_keypoint = 4;
  map.frames[1].num_keypoints = 2;
  map.frames[1].is_query = true;
  map.keypoints.resize(6);
  map.keypoint_landmark = {0, kInvalidLandmarkId, 2, 1, 0, 2};
  for (int i = 0; i < 6; ++i) {
    map.descriptors.push_back(static_cast<uint8_t>(i));
    map.descriptors.push_back(static_cast<uint8_t>(10 + i));
  }
  const auto all = collect_training_observations(map, {});
  EXPECT_EQ(all.landmark, (std::vector<landmark_t>{0, 2, 1}));
  EXPECT_EQ(all.descriptors, (std::vector<uint8_t>{0, 10, 2, 12, 3, 13}));
  const auto some = collect_training_observations(map, {2, 1});
  EXPECT_EQ(some.landmark, (std::vector<landmark_t>{2, 1}));
  EXPECT_THROW(collect_training_observations(map, {3}), Error);
}

}  // namespace
}  // namespace lmb
