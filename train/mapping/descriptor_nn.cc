#include "train/mapping/descriptor_nn.h"

#include <algorithm>
#include <limits>
#include <thread>
#include <vector>

#include "common/error.h"
#include "common/hamming.h"

namespace lmb {

namespace {

// Nearest database row of queries [begin, end): distances a block of rows at a time
// (hamming_rows: the popcnt instruction where the CPU has it), first minimum wins.
void nn_range(const uint8_t* database, int64_t num_database, const uint8_t* queries, int64_t begin, int64_t end,
              int bytes, int64_t* nn_index, int32_t* nn_distance) {
  constexpr int64_t kBlock = 4096;
  std::vector<uint16_t> dist(static_cast<size_t>(std::min(kBlock, num_database)));
  for (int64_t q = begin; q < end; ++q) {
    const uint8_t* query = queries + q * bytes;
    int best = std::numeric_limits<int32_t>::max();
    int64_t best_index = -1;
    for (int64_t d0 = 0; d0 < num_database; d0 += kBlock) {
      const int64_t n = std::min(kBlock, num_database - d0);
      hamming_rows(query, database + d0 * bytes, n, bytes, dist.data());
      for (int64_t i = 0; i < n; ++i) {
        if (dist[i] < best) {
          best = dist[i];
          best_index = d0 + i;
        }
      }
    }
    nn_index[q] = best_index;
    nn_distance[q] = best;
  }
}

}  // namespace

void hamming_nearest_neighbors(const uint8_t* database, int64_t num_database, const uint8_t* queries,
                               int64_t num_queries, int bytes, int threads, int64_t* nn_index, int32_t* nn_distance) {
  LMB_CHECK(bytes > 0, "hamming_nearest_neighbors: descriptor bytes must be positive");
  threads = std::max(1, threads);
  auto run = [&](int64_t begin, int64_t end) {
    nn_range(database, num_database, queries, begin, end, bytes, nn_index, nn_distance);
  };
  if (threads == 1 || num_queries < 64) {
    run(0, num_queries);
    return;
  }
  std::vector<std::thread> workers;
  const int64_t chunk = (num_queries + threads - 1) / threads;
  for (int t = 0; t < threads; ++t) {
    const int64_t begin = t * chunk, end = std::min(num_queries, begin + chunk);
    if (begin < end) workers.emplace_back(run, begin, end);
  }
  for (auto& w : workers) w.join();
}

HammingNnStats evaluate_hamming_nn(const LandmarkMap& map, int threads) {
  const int bytes = map.descriptor_bytes;
  std::vector<uint8_t> database, queries;
  std::vector<landmark_t> database_landmark, query_landmark;
  for (const MapFrame& frame : map.frames) {
    for (int64_t k = frame.first_keypoint; k < frame.first_keypoint + frame.num_keypoints; ++k) {
      const landmark_t l = map.keypoint_landmark[k];
      if (l == kInvalidLandmarkId) continue;
      auto& rows = frame.is_query ? queries : database;
      rows.insert(rows.end(), map.descriptor(k), map.descriptor(k) + bytes);
      (frame.is_query ? query_landmark : database_landmark).push_back(l);
    }
  }
  HammingNnStats stats;
  stats.num_queries = static_cast<int64_t>(query_landmark.size());
  stats.num_database = static_cast<int64_t>(database_landmark.size());
  if (stats.num_queries == 0 || stats.num_database == 0 || bytes == 0) return stats;
  std::vector<int64_t> nn(stats.num_queries);
  std::vector<int32_t> dist(stats.num_queries);
  hamming_nearest_neighbors(database.data(), stats.num_database, queries.data(), stats.num_queries, bytes, threads,
                            nn.data(), dist.data());
  double dist_sum = 0, true_sum = 0;
  int64_t true_count = 0;
  // Nearest observation of the true landmark (for the mean distance figure).
  std::vector<std::vector<int64_t>> rows_of_landmark(map.landmarks.size());
  for (int64_t d = 0; d < stats.num_database; ++d) rows_of_landmark[database_landmark[d]].push_back(d);
  for (int64_t q = 0; q < stats.num_queries; ++q) {
    if (database_landmark[nn[q]] == query_landmark[q]) ++stats.num_correct;
    dist_sum += dist[q];
    int best = std::numeric_limits<int>::max();
    for (int64_t d : rows_of_landmark[query_landmark[q]]) {
      best = std::min(best, hamming_distance(queries.data() + q * bytes, database.data() + d * bytes, bytes));
    }
    if (!rows_of_landmark[query_landmark[q]].empty()) {
      true_sum += best;
      ++true_count;
    }
  }
  stats.precision_at_1 = static_cast<double>(stats.num_correct) / static_cast<double>(stats.num_queries);
  stats.mean_nn_distance = dist_sum / static_cast<double>(stats.num_queries);
  stats.mean_true_nn_distance = true_count > 0 ? true_sum / static_cast<double>(true_count) : 0.0;
  return stats;
}

}  // namespace lmb
