// The context-embedding kernels of every SIMD level this CPU runs (common/simd/embedding_kernels.h)
// against the generic ones, bit for bit: the rank kernels on hand-made axes (crowded cells, ties,
// bounds outside the coordinates, infinite bounds, one-cell grids), and FrameContext's plan paths
// (keypoint by keypoint and region by region, where the AVX-512 column kernel runs) at every level
// against the generic level.
#include "common/simd/embedding_kernels.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <vector>

#include <gtest/gtest.h>

#include "common/context_embedding.h"
#include "common/error.h"
#include "common/random.h"
#include "common/simd/simd_level.h"

namespace lmb {
namespace {

std::vector<SimdLevel> supported_levels() {
  std::vector<SimdLevel> out;
  for (SimdLevel l : compiled_simd_levels()) {
    if (simd_level_supported(l)) out.push_back(l);
  }
  return out;
}

// An axis over n sorted coordinates with `cells` grid cells (the layout FrameContext builds; fewer
// cells crowd them, which exercises the binary search).
struct TestAxis {
  std::vector<float> sorted;
  std::vector<uint16_t> start;
  detail::AxisView view;

  TestAxis(std::vector<float> coords, int32_t cells) {
    std::sort(coords.begin(), coords.end());
    const int32_t n = static_cast<int32_t>(coords.size());
    sorted = coords;
    sorted.resize(coords.size() + 2, std::numeric_limits<float>::infinity());
    view.lo = n > 0 ? sorted[0] : 0.f;
    const float range = n > 0 ? sorted[n - 1] - view.lo : 0.f;
    view.last = static_cast<float>(cells - 1);
    view.inv = range > 0.f ? static_cast<float>(cells) / range : 0.f;
    start.resize(static_cast<size_t>(cells) + 1);
    auto cell = [&](float v) {
      float t = (v - view.lo) * view.inv;
      t = t > 0.f ? t : 0.f;
      t = t < view.last ? t : view.last;
      return static_cast<int32_t>(t);
    };
    int32_t c = 0;
    for (int32_t i = 0; i < n; ++i) {
      const int32_t ci = cell(sorted[i]);
      while (c <= ci) start[c++] = static_cast<uint16_t>(i);
    }
    while (c <= cells) start[c++] = static_cast<uint16_t>(n);
    view.sorted = sorted.data();
    view.start = start.data();
  }
};

TEST(EmbeddingKernels, RankKernelsOfEveryLevelEqualTheGenericOnes) {
  Rng rng(21);
  const detail::EmbeddingKernels& generic = *detail::embedding_kernels(SimdLevel::kGeneric);
  int compared = 0;
  for (int32_t n : {0, 1, 2, 7, 60, 300}) {
    for (int32_t cells_per : {16, 1}) {
      for (bool ties : {false, true}) {
        std::vector<float> coords(static_cast<size_t>(n));
        for (float& c : coords) {
          c = ties ? static_cast<float>(rng.below(5)) : static_cast<float>(rng.uniform() * 200.0 - 100.0);
        }
        const TestAxis axis(coords, std::max(1, cells_per * n));
        // Corners and positions: random, exactly on coordinates, outside the range, infinite.
        constexpr int32_t kMax = detail::kMaxRankBatch;
        std::vector<float> corners(kMax), p(kMax), s(kMax);
        for (int32_t i = 0; i < kMax; ++i) {
          corners[i] = static_cast<float>(rng.uniform() * 4.0 - 2.0);
          p[i] = n > 0 && i % 3 == 0 ? coords[rng.below(static_cast<uint64_t>(n))]
                                     : static_cast<float>(rng.uniform() * 300.0 - 150.0);
          s[i] = static_cast<float>(rng.uniform() * 50.0);
        }
        corners[1] = 0.f;
        corners[2] = std::numeric_limits<float>::infinity();
        corners[3] = -std::numeric_limits<float>::infinity();
        s[4] = 0.f;
        for (int32_t m : {1, 5, 8, 13, 64}) {
          for (int32_t first : {0, 1}) {
            std::vector<int32_t> want(kMax, -7), want_k(kMax, -7);
            generic.corner_ranks(axis.view, p[first], s[first], corners.data(), m, want.data());
            generic.keypoint_ranks(axis.view, p.data(), s.data(), corners[first], m, want_k.data());
            for (int32_t i = 0; i < m; ++i) {  // the generic kernel is the axis's rank
              const float bound = p[first] + s[first] * corners[i];
              ASSERT_EQ(want[i],
                        std::lower_bound(axis.sorted.begin(), axis.sorted.begin() + n, bound) - axis.sorted.begin());
            }
            for (SimdLevel level : supported_levels()) {
              const detail::EmbeddingKernels& k = *detail::embedding_kernels(level);
              std::vector<int32_t> got(kMax, -7), got_k(kMax, -7);
              k.corner_ranks(axis.view, p[first], s[first], corners.data(), m, got.data());
              k.keypoint_ranks(axis.view, p.data(), s.data(), corners[first], m, got_k.data());
              for (int32_t i = 0; i < m; ++i) {
                ASSERT_EQ(got[i], want[i]) << simd_level_name(level) << " n " << n << " m " << m << " i " << i;
                ASSERT_EQ(got_k[i], want_k[i]) << simd_level_name(level) << " n " << n << " m " << m << " i " << i;
              }
              ++compared;
            }
          }
        }
      }
    }
  }
  EXPECT_GT(compared, 0);
}

ContextRegions test_regions(int num, uint64_t seed) {
  ContextRegionOptions o;
  o.num_regions = num;
  o.seed = seed;
  o.max_area = 256;
  o.max_offset = 12;
  return ContextRegions(o);
}

// FrameContext at every level gives the generic level's bytes: compute_dims_all with a plan (the
// rank kernels) and compute_dims_columns (also the column kernel where the level has one), on
// frames with and without the dominance structure's byte tables and with duplicate positions.
TEST(EmbeddingKernels, FrameContextOfEveryLevelEqualsTheGenericLevel) {
  constexpr int32_t kWords = 8;
  const ContextRegions regions = test_regions(120, 4);
  const int32_t bytes = 32;
  const int32_t num_dims = regions.size() * kWords + 8 * bytes;
  Rng rng(5);
  int columns_kernel_runs = 0;
  for (int32_t n : {1, 17, 300, 2100}) {
    std::vector<Eigen::Vector2d> positions;
    std::vector<double> scales;
    std::vector<uint8_t> words;
    for (int32_t i = 0; i < n; ++i) {
      // Half the keypoints on a coarse grid (ties), the rest anywhere.
      const bool coarse = i % 2 == 0;
      const double x = coarse ? static_cast<double>(rng.below(16)) / 8.0 - 1.0 : rng.uniform() * 2.0 - 1.0;
      const double y = coarse ? static_cast<double>(rng.below(16)) / 8.0 - 1.0 : rng.uniform() * 2.0 - 1.0;
      positions.emplace_back(x, y);
      scales.push_back(0.02 + rng.uniform() * 0.2);
      words.push_back(static_cast<uint8_t>(rng.below(kWords)));
    }
    const FrameKeypoints frame =
        align_frame_keypoints(positions, scales, words, Eigen::Vector2d(0.3, 0.95).normalized(), "test frame");
    std::vector<uint8_t> descriptors(static_cast<size_t>(n) * bytes);
    for (uint8_t& b : descriptors) b = static_cast<uint8_t>(rng.below(256));
    std::vector<int32_t> dims;
    for (int32_t d = 0; d < num_dims; ++d) {
      if (rng.below(10) < 3) dims.push_back(d);
    }
    const DimPlan plan(regions, EmbeddingLayout{regions.size(), kWords, bytes}, dims);
    std::vector<int32_t> ids(static_cast<size_t>(n));
    std::iota(ids.begin(), ids.end(), 0);
    std::reverse(ids.begin(), ids.end());
    const size_t stride = static_cast<size_t>(n) + 3;
    FrameContext reference(regions, kWords, SimdLevel::kGeneric);
    reference.reset(frame);
    std::vector<uint8_t> want_rows(static_cast<size_t>(n) * plan.size());
    std::vector<uint8_t> want_columns(stride * plan.size(), 0xEE);
    reference.compute_dims_all(plan, descriptors.data(), want_rows.data());
    reference.compute_dims_columns(plan, ids.data(), n, descriptors.data(), want_columns.data(), stride);
    for (SimdLevel level : supported_levels()) {
      FrameContext ctx(regions, kWords, level);
      ASSERT_EQ(ctx.simd_level(), level);
      ctx.reset(frame);
      std::vector<uint8_t> rows(want_rows.size()), columns(want_columns.size(), 0xEE);
      ctx.compute_dims_all(plan, descriptors.data(), rows.data());
      ctx.compute_dims_columns(plan, ids.data(), n, descriptors.data(), columns.data(), stride);
      ASSERT_EQ(rows, want_rows) << simd_level_name(level) << " n " << n;
      ASSERT_EQ(columns, want_columns) << simd_level_name(level) << " n " << n;
      columns_kernel_runs += detail::embedding_kernels(level)->column_bins != nullptr;
    }
  }
  if (columns_kernel_runs == 0) {
    std::printf("no level of this CPU has the column kernel (AVX-512 VPOPCNTDQ): only the rank kernels compared\n");
  }
}

TEST(EmbeddingKernels, AnUnsupportedLevelIsAnError) {
  const ContextRegions regions = test_regions(10, 1);
  for (SimdLevel level : {SimdLevel::kGeneric, SimdLevel::kAvx2, SimdLevel::kAvx512, SimdLevel::kNeon}) {
    if (simd_level_supported(level)) {
      EXPECT_NO_THROW(FrameContext(regions, 4, level));
    } else {
      EXPECT_THROW(FrameContext(regions, 4, level), Error);
    }
  }
  EXPECT_EQ(FrameContext(regions, 4).simd_level(), simd_level());
}

}  // namespace
}  // namespace lmb
