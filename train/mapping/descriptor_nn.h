// Exact Hamming nearest neighbours over flat binary descriptor rows, and the aliasing figure of a
// map: how often a query keypoint's plain descriptor nearest neighbour among the map keypoints
// belongs to its true landmark. Reused by evaluation as the brute-force baseline.
#pragma once

#include <cstdint>
#include <vector>

#include "common/landmark_map.h"

namespace lmb {

// For each of `num_queries` rows in `queries` (num_queries * bytes), the index of the nearest of
// the `num_database` rows in `database` (num_database * bytes) by Hamming distance, ties to the
// smaller index, and that distance. nn_index and nn_distance hold num_queries entries; with an
// empty database they get -1 and INT32_MAX. threads >= 1 splits the queries; the result does not
// depend on it.
void hamming_nearest_neighbors(const uint8_t* database, int64_t num_database, const uint8_t* queries,
                               int64_t num_queries, int bytes, int threads, int64_t* nn_index, int32_t* nn_distance);

struct HammingNnStats {
  int64_t num_queries = 0;           // query-frame keypoints with a true landmark
  int64_t num_database = 0;          // map-frame keypoints with a landmark
  int64_t num_correct = 0;           // nearest neighbour belongs to the query's landmark
  double precision_at_1 = 0;         // num_correct / num_queries (0 without queries)
  double mean_nn_distance = 0;       // bits
  double mean_true_nn_distance = 0;  // bits, to the nearest observation of the true landmark
};

// Plain exact Hamming nearest neighbour of every query keypoint with a true landmark against all map
// keypoints that have a landmark; precision@1 = share whose neighbour carries the true landmark.
HammingNnStats evaluate_hamming_nn(const LandmarkMap& map, int threads);

}  // namespace lmb
