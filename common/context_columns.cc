// FrameContext::compute_dims_columns: the dims of many keypoints at once, region by region (the
// inverted-file path of the classifier), with the column kernel of the SIMD level where it has one
// (common/simd/embedding_kernels.h). The same integer arithmetic as FrameContext::compute_dims
// (common/context_embedding.cc), so the same bytes.
#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>
#include <numeric>

#include "common/context_embedding.h"
#include "common/context_embedding_inl.h"
#include "common/cpu_dispatch.h"
#include "common/error.h"
#include "common/hamming.h"

namespace lmb {

LMB_CLONES_AVX2 void FrameContext::compute_dims_columns(const DimPlan& plan, const int32_t* ids, int32_t count,
                                                        const uint8_t* descriptors, uint8_t* out, size_t stride) const {
  check_plan(plan, descriptors, count);
  LMB_CHECK(count >= 0 && count <= n_ && stride >= static_cast<size_t>(count),
            "compute_dims_columns: " << count << " keypoints of " << n_ << ", stride " << stride);
  if (count == 0) return;
  // The keypoints in x order (ties: by position), with their output position.
  std::vector<std::pair<int32_t, int32_t>> visit(static_cast<size_t>(count));
  for (int32_t i = 0; i < count; ++i) {
    assert(ids[i] >= 0 && ids[i] < n_);
    visit[i] = {rank_x_[ids[i]], i};
  }
  std::sort(visit.begin(), visit.end());
  const size_t padded = (static_cast<size_t>(count) + 7) / 8 * 8;
  std::vector<float> px(padded, 0.f), py(padded, 0.f), ps(padded, 1.f);
  std::vector<int32_t> key(static_cast<size_t>(count)), pos(static_cast<size_t>(count));
  std::vector<int32_t> own_rx(padded), own_ry(padded), own_word(padded);
  for (int32_t i = 0; i < count; ++i) {
    const int32_t k = ids[visit[i].second];
    key[i] = k;
    pos[i] = visit[i].second;
    own_rx[i] = rank_x_[k];
    own_ry[i] = rank_y_[k];
    own_word[i] = word_[k];
    px[i] = x_[k];
    py[i] = y_[k];
    ps[i] = scale_[k];
  }
  const int32_t U = plan.num_used_regions();
  const int32_t* dim_begin = plan.dim_begin_.data();
  const uint8_t* dim_word = plan.dim_word_.data();
  constexpr int32_t kChunk = kMaxRankBatch;
  alignas(32) int32_t ranks[4][kChunk];
  const BinTables tables = bin_tables();
  // 16 keypoints at a time with the level's column kernel (AVX-512) where it has one, for frames
  // with the dominance structure and byte tables (the rest, and other levels, one keypoint at a
  // time).
  const bool vector_columns = kernels_->column_bins != nullptr && tables.dom != nullptr && tables.tables8 != nullptr;
  detail::ColumnTables columns;
  columns.dom = tables.dom;
  columns.dom_stride = n_ + 1;
  columns.bin_magic = tables.bin_magic;
  columns.row8_x = tables.row8_x;
  columns.local8_y = tables.local8_y;
  columns.tables8 = tables.tables8;
  columns.num_words = num_words_;
  const detail::AxisView ax = axis_x_.view(), ay = axis_y_.view();
  for (int32_t u = 0; u < U; ++u) {
    const float x0 = plan.corners_[0][u], x1 = plan.corners_[1][u];
    const float y0 = plan.corners_[2][u], y1 = plan.corners_[3][u];
    const int32_t begin = dim_begin[u], end = dim_begin[u + 1];
    for (int32_t i0 = 0; i0 < count; i0 += kChunk) {
      const int32_t m = std::min(kChunk, count - i0);
      kernels_->keypoint_ranks(ax, px.data() + i0, ps.data() + i0, x0, m, ranks[0]);
      kernels_->keypoint_ranks(ax, px.data() + i0, ps.data() + i0, x1, m, ranks[1]);
      kernels_->keypoint_ranks(ay, py.data() + i0, ps.data() + i0, y0, m, ranks[2]);
      kernels_->keypoint_ranks(ay, py.data() + i0, ps.data() + i0, y1, m, ranks[3]);
      int32_t i = 0;
      if (vector_columns) {
        alignas(64) uint8_t bins[16 * 256];
        for (; i + 16 <= m; i += 16) {
          const int32_t v = i0 + i;
          detail::ColumnLanes lanes;
          lanes.ix0 = ranks[0] + i;
          lanes.ix1 = ranks[1] + i;
          lanes.iy0 = ranks[2] + i;
          lanes.iy1 = ranks[3] + i;
          lanes.rx = own_rx.data() + v;
          lanes.ry = own_ry.data() + v;
          lanes.word = own_word.data() + v;
          kernels_->column_bins(columns, lanes, dim_word + begin, end - begin, bins);
          for (int32_t j = begin; j < end; ++j) {
            uint8_t* o = out + static_cast<size_t>(j) * stride;
            const uint8_t* b = bins + 16 * (j - begin);
            for (int32_t l = 0; l < 16; ++l) o[pos[v + l]] = b[l];
          }
        }
      }
      for (; i < m; ++i) {
        region_bins(tables, key[i0 + i], ranks[0][i], ranks[1][i], ranks[2][i], ranks[3][i], dim_word, begin, end,
                    out + pos[i0 + i], stride);
      }
    }
  }
  const int32_t* dims = plan.dims_.data();
  const int32_t context_dims = plan.layout_.num_context_dims();
  const int32_t bytes = plan.layout_.descriptor_bytes;
  for (int32_t j = plan.num_context_; j < plan.size(); ++j) {
    const int32_t bit = dims[j] - context_dims;
    uint8_t* o = out + static_cast<size_t>(j) * stride;
    for (int32_t i = 0; i < count; ++i) {
      o[i] = static_cast<uint8_t>(descriptor_bit(descriptors + static_cast<size_t>(ids[i]) * bytes, bit));
    }
  }
}

}  // namespace lmb
