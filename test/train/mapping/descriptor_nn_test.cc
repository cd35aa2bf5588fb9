#include "train/mapping/descriptor_nn.h"

#include <limits>

#include <gtest/gtest.h>

#include "common/hamming.h"
#include "common/random.h"

namespace lmb {
namespace {

TEST(HammingNearestNeighbors, AgreesWithBruteForceForAnySizeAndThreads) {
  Rng rng(9);
  for (int bytes : {32, 64, 48}) {
    const int64_t nd = 700, nq = 300;
    std::vector<uint8_t> db(nd * bytes), q(nq * bytes);
    for (auto& b : db) b = static_cast<uint8_t>(rng.below(256));
    for (auto& b : q) b = static_cast<uint8_t>(rng.below(256));
    // Plant duplicates so that ties occur: the smaller index must win.
    for (int i = 0; i < bytes; ++i) db[50 * bytes + i] = db[20 * bytes + i];
    for (int i = 0; i < bytes; ++i) q[7 * bytes + i] = db[20 * bytes + i];
    std::vector<int64_t> idx1(nq), idx3(nq);
    std::vector<int32_t> d1(nq), d3(nq);
    hamming_nearest_neighbors(db.data(), nd, q.data(), nq, bytes, 1, idx1.data(), d1.data());
    hamming_nearest_neighbors(db.data(), nd, q.data(), nq, bytes, 3, idx3.data(), d3.data());
    EXPECT_EQ(idx1, idx3);
    EXPECT_EQ(d1, d3);
    EXPECT_EQ(idx1[7], 20);
    EXPECT_EQ(d1[7], 0);
    for (int64_t i = 0; i < nq; ++i) {
      int best = std::numeric_limits<int>::max();
      int64_t best_index = -1;
      for (int64_t j = 0; j < nd; ++j) {
        int d = 0;
        for (int b = 0; b < bytes; ++b) d += __builtin_popcount(q[i * bytes + b] ^ db[j * bytes + b]);
        if (d < best) {
          best = d;
          best_index = j;
        }
      }
      ASSERT_EQ(idx1[i], best_index);
      ASSERT_EQ(d1[i], best);
    }
  }
}

TEST(HammingNearestNeighbors, EmptyDatabase) {
  const uint8_t q[32] = {};
  int64_t idx = 5;
  int32_t d = 0;
  hamming_nearest_neighbors(nullptr, 0, q, 1, 32, 1, &idx, &d);
  EXPECT_EQ(idx, -1);
  EXPECT_EQ(d, std::numeric_limits<int32_t>::max());
}

// Map frame 0 has landmarks 0, 1 and a background keypoint; query frame 1 sees landmark 0 (its
// descriptor closest to landmark 1's map observation: aliased), landmark 1 (correct) and background.
TEST(EvaluateHammingNn, KnownAnswer) {
  LandmarkMap map;
  map.descriptor_bytes = 32;
  Camera c;
  c.model = CameraModel::kPinhole;
  c.width = 100;
  c.height = 100;
  c.params = {50, 50, 50, 50};
  map.cameras = {c};
  MapFrame f0, f1;
  f0.name = "map/0";
  f0.num_keypoints = 3;
  f1.name = "query/0";
  f1.is_query = true;
  f1.first_keypoint = 3;
  f1.num_keypoints = 3;
  map.frames = {f0, f1};
  map.keypoints.resize(6);
  map.descriptors.assign(6 * 32, 0);
  auto set_bits = [&](int k, int n) {
    for (int b = 0; b < n; ++b) map.descriptors[k * 32 + b / 8] |= static_cast<uint8_t>(1 << (b % 8));
  };
  set_bits(0, 0);    // landmark 0: all zero
  set_bits(1, 100);  // landmark 1: 100 ones
  set_bits(2, 50);   // background in the map: never a neighbour candidate
  set_bits(3, 60);   // query of landmark 0: 60 from lm0, 40 from lm1 -> wrong
  set_bits(4, 98);   // query of landmark 1: right
  set_bits(5, 50);   // background query: not counted
  map.keypoint_landmark = {0, 1, -1, 0, 1, -1};
  map.landmarks.resize(2);
  const HammingNnStats s = evaluate_hamming_nn(map, 1);
  EXPECT_EQ(s.num_queries, 2);
  EXPECT_EQ(s.num_database, 2);
  EXPECT_EQ(s.num_correct, 1);
  EXPECT_DOUBLE_EQ(s.precision_at_1, 0.5);
  EXPECT_DOUBLE_EQ(s.mean_nn_distance, (40 + 2) / 2.0);
  EXPECT_DOUBLE_EQ(s.mean_true_nn_distance, (60 + 2) / 2.0);
}

}  // namespace
}  // namespace lmb
