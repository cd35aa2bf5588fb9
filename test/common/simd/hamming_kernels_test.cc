// hamming_rows and hamming_min of every SIMD level this CPU runs (common/simd/hamming_kernels.h) against the
// generic kernel and the scalar hamming_distance, bit for bit: every row length from 0 to 130
// bytes (the 32- and 64-byte specializations and their neighbours), row counts 0 to 9, and the
// extremes (identical rows, complementary rows).
#include "common/simd/hamming_kernels.h"

#include <algorithm>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "common/hamming.h"
#include "common/random.h"
#include "common/simd/simd_level.h"

namespace lmb {
namespace {

TEST(HammingKernels, EveryLevelEqualsTheScalarDistance) {
  Rng rng(9);
  const detail::HammingKernels& generic = *detail::hamming_kernels(SimdLevel::kGeneric);
  int levels = 0;
  for (int32_t bytes = 0; bytes <= 130; ++bytes) {
    for (int64_t n : {0, 1, 2, 9}) {
      std::vector<uint8_t> q(static_cast<size_t>(bytes)), rows(static_cast<size_t>(n * bytes));
      for (uint8_t& b : q) b = static_cast<uint8_t>(rng.below(256));
      for (int64_t i = 0; i < n; ++i) {
        for (int32_t j = 0; j < bytes; ++j) {
          // Row 0 equals q, row 1 is its complement, the rest random.
          rows[i * bytes + j] = i == 0   ? q[j]
                                : i == 1 ? static_cast<uint8_t>(~q[j])
                                         : static_cast<uint8_t>(rng.below(256));
        }
      }
      std::vector<uint16_t> want(static_cast<size_t>(n) + 1, 0xBEEF);
      generic.rows(q.data(), rows.data(), n, bytes, want.data());
      for (int64_t i = 0; i < n; ++i) {
        ASSERT_EQ(want[i], hamming_distance(q.data(), rows.data() + i * bytes, bytes)) << bytes << " bytes, row " << i;
      }
      if (n > 1) {
        ASSERT_EQ(want[0], 0);
        ASSERT_EQ(want[1], 8 * bytes);
      }
      ASSERT_EQ(want[n], 0xBEEF);
      int32_t want_min = 8 * bytes + 1;
      for (int64_t i = 0; i < n; ++i) want_min = std::min<int32_t>(want_min, want[i]);
      ASSERT_EQ(generic.min(q.data(), rows.data(), n, bytes), want_min) << bytes << " bytes, " << n << " rows";
      for (SimdLevel level : compiled_simd_levels()) {
        const detail::HammingKernels* k = detail::hamming_kernels(level);
        if (k == nullptr) continue;
        std::vector<uint16_t> got(want.size(), 0xBEEF);
        k->rows(q.data(), rows.data(), n, bytes, got.data());
        ASSERT_EQ(got, want) << simd_level_name(level) << ", " << bytes << " bytes, " << n << " rows";
        ASSERT_EQ(k->min(q.data(), rows.data(), n, bytes), want_min) << simd_level_name(level) << ", " << bytes;
        ++levels;
      }
    }
  }
  EXPECT_GT(levels, 0);
}

// min_lanes (the least distance of each selected query to the rows) and low_lanes (the balls'
// lower bound: the least max(0, distance - radius[i])) at every level and through the public
// functions, against the brute force on the same cases; unselected lanes stay untouched, and a
// query equal to a row gets 0 from both.
TEST(HammingKernels, MinAndBallLowLanesEqualTheBruteForceAtEveryLevel) {
  Rng rng(11);
  int checked = 0;
  for (int32_t bytes : {0, 5, 8, 31, 32, 33, 64, 65}) {
    for (int64_t n : {0, 1, 3, 14}) {
      for (uint32_t lanes : {0u, 1u, 0x80000001u, 0x80000003u, 0xFFFFFFFFu, 0x0F0F00F0u}) {
        std::vector<uint8_t> queries(static_cast<size_t>(32 * bytes)), rows(static_cast<size_t>(n * bytes));
        for (uint8_t& b : queries) b = static_cast<uint8_t>(rng.below(256));
        for (uint8_t& b : rows) b = static_cast<uint8_t>(rng.below(256));
        std::vector<int32_t> radius(static_cast<size_t>(n));
        for (int32_t& r : radius) r = static_cast<int32_t>(rng.below(static_cast<uint64_t>(4 * bytes + 2)));
        // Query 0 equals the last row: distance 0, inside its ball.
        if (n > 0) std::copy_n(rows.data() + (n - 1) * bytes, bytes, queries.data());
        std::vector<int32_t> want_min(32, -7), want_low(32, -7);
        for (int32_t j = 0; j < 32; ++j) {
          if (((lanes >> j) & 1) == 0) continue;
          want_min[j] = want_low[j] = 8 * bytes + 1;
          for (int64_t i = 0; i < n; ++i) {
            const int32_t d = hamming_distance(queries.data() + j * bytes, rows.data() + i * bytes, bytes);
            want_min[j] = std::min(want_min[j], d);
            want_low[j] = std::min(want_low[j], std::max(0, d - radius[static_cast<size_t>(i)]));
          }
        }
        if ((lanes & 1) && n > 0) {
          ASSERT_EQ(want_min[0], 0);
          ASSERT_EQ(want_low[0], 0);
        }
        const auto where = [&](const char* level) {
          return std::string(level) + ", " + std::to_string(bytes) + " bytes, " + std::to_string(n) + " rows, lanes " +
                 std::to_string(lanes);
        };
        for (SimdLevel level : compiled_simd_levels()) {
          const detail::HammingKernels* k = detail::hamming_kernels(level);
          if (k == nullptr) continue;
          std::vector<int32_t> got(32, -7);
          k->min_lanes(queries.data(), lanes, rows.data(), n, bytes, got.data());
          ASSERT_EQ(got, want_min) << "min_lanes " << where(simd_level_name(level));
          got.assign(32, -7);
          k->low_lanes(queries.data(), lanes, rows.data(), radius.data(), n, bytes, got.data());
          ASSERT_EQ(got, want_low) << "low_lanes " << where(simd_level_name(level));
          ++checked;
        }
        std::vector<int32_t> got(32, -7);
        hamming_min_lanes(queries.data(), lanes, rows.data(), n, bytes, got.data());
        ASSERT_EQ(got, want_min) << where("process level");
        got.assign(32, -7);
        hamming_ball_low_lanes(queries.data(), lanes, rows.data(), radius.data(), n, bytes, got.data());
        ASSERT_EQ(got, want_low) << where("process level");
      }
    }
  }
  EXPECT_GT(checked, 0);
}

TEST(HammingKernels, HammingRowsUsesTheProcessLevel) {
  EXPECT_EQ(detail::hamming_kernels().level, simd_level());
  const std::vector<uint8_t> q(64, 0x0F), rows(128, 0xFF);
  std::vector<uint16_t> out(2);
  hamming_rows(q.data(), rows.data(), 2, 64, out.data());
  EXPECT_EQ(out[0], 256);
  EXPECT_EQ(out[1], 256);
}

}  // namespace
}  // namespace lmb
