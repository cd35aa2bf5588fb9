// Inline members of FrameContext shared by the scalar path (common/context_embedding.cc) and the
// column path (common/context_columns.cc): the dominance lookups and the bins of one region. Not
// installed; include only from those two files.
#pragma once

#include <cstdint>

#include "common/context_embedding.h"

namespace lmb {

namespace detail {

// One region bound: p + s * c, rounded to float after the product and after the sum. Two
// statements, so that no compiler contracts them into a fused multiply-add in one translation unit
// and not in another (the fast path and the reference must agree bit for bit).
inline float region_bound(float p, float s, float c) {
  const float offset = s * c;
  const float bound = p + offset;
  return bound;
}

// Bit count without the libgcc call the baseline x86-64 ISA (no POPCNT) would make.
inline int32_t bit_count(uint64_t x) {
  x = x - ((x >> 1) & 0x5555555555555555ull);
  x = (x & 0x3333333333333333ull) + ((x >> 2) & 0x3333333333333333ull);
  x = (x + (x >> 4)) & 0x0F0F0F0F0F0F0F0Full;
  return static_cast<int32_t>((x * 0x0101010101010101ull) >> 56);
}
}  // namespace detail

inline int32_t FrameContext::BinTables::dominance(int32_t ix, int32_t iy) const {
  const uint64_t e = dom[dom_row[ix] + iy];
  return static_cast<int32_t>(e >> 48) + detail::bit_count(e & dom_below[ix]);
}

inline int32_t FrameContext::word_dominance(int32_t w, int32_t ix, int32_t iy) const {
  const int32_t W = num_words_;
  if (small_words_) {
    return tables8_[row8_x_[static_cast<size_t>(ix) * W + w] + local8_y_[static_cast<size_t>(iy) * W + w]];
  }
  const int64_t side = word_side_[w];
  return tables_[table_offset_[w] + local_rank_x_[static_cast<size_t>(ix) * W + w] * side +
                 local_rank_y_[static_cast<size_t>(iy) * W + w]];
}

inline FrameContext::Bounds FrameContext::bounds(int32_t k, const RegionRect& q) const {
  const float px = x_[k], py = y_[k], s = scale_[k];
  Bounds b;
  b.ix0 = axis_x_.rank(detail::region_bound(px, s, q.x0));
  b.ix1 = axis_x_.rank(detail::region_bound(px, s, q.x1));
  b.iy0 = axis_y_.rank(detail::region_bound(py, s, q.y0));
  b.iy1 = axis_y_.rank(detail::region_bound(py, s, q.y1));
  // lo <= x_k  <=>  ix0 <= rank_x(k), and x_k < hi  <=>  rank_x(k) < ix1 (ties included).
  // (& rather than &&: no branches, see compute_dims.)
  const int32_t rx = rank_x_[k], ry = rank_y_[k];
  b.anchor_inside = (b.ix0 <= rx) & (rx < b.ix1) & (b.iy0 <= ry) & (ry < b.iy1);
  return b;
}

// The bins of one region (rank ranges ix0..iy1) of keypoint k for the plan's dims [begin, end)
// (their words in dim_word), written to out[j * stride]. The tables come through t's local
// pointers: the byte stores may alias any member, which would make the compiler reload them.
inline void FrameContext::region_bins(const BinTables& t, int32_t k, int32_t ix0, int32_t ix1, int32_t iy0, int32_t iy1,
                                      const uint8_t* dim_word, int32_t begin, int32_t end, uint8_t* out,
                                      size_t stride) const {
  if (ix0 == ix1 || iy0 == iy1) {  // empty (the anchor cannot be inside)
    for (int32_t j = begin; j < end; ++j) out[j * stride] = 0;
    return;
  }
  const int32_t rx = t.rank_x[k], ry = t.rank_y[k];
  const int32_t inside = (ix0 <= rx) & (rx < ix1) & (iy0 <= ry) & (ry < iy1);
  if (t.dom == nullptr) {  // a large frame: all words' counts
    Bounds b{ix0, ix1, iy0, iy1, inside != 0};
    int32_t counts[256];
    int32_t total = 0;
    counts_from_bounds(k, b, counts, &total);
    for (int32_t j = begin; j < end; ++j) out[j * stride] = context_bin(counts[dim_word[j]], total);
    return;
  }
  // Only the plan's words of the region; count_all from the dominance structure.
  const int32_t W = t.num_words;
  const auto word_dom = [&](int32_t w, int32_t ix, int32_t iy) {
    if (t.tables8 != nullptr) return static_cast<int32_t>(t.tables8[t.row8_x[ix * W + w] + t.local8_y[iy * W + w]]);
    return word_dominance(w, ix, iy);
  };
  const int32_t total =
      t.dominance(ix1, iy1) - t.dominance(ix0, iy1) - t.dominance(ix1, iy0) + t.dominance(ix0, iy0) - inside;
  const uint64_t magic = t.bin_magic[total];
  const int32_t word_k = t.word[k];
  for (int32_t j = begin; j < end; ++j) {
    const int32_t w = dim_word[j];
    const int32_t count = word_dom(w, ix1, iy1) - word_dom(w, ix0, iy1) - word_dom(w, ix1, iy0) +
                          word_dom(w, ix0, iy0) - (inside & (word_k == w));
    out[j * stride] = context_bin_fast(count, total, magic);
  }
}

}  // namespace lmb
