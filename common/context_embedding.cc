#include "common/context_embedding.h"
#include "common/context_embedding_inl.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>
#include <numeric>

#include "common/cpu_dispatch.h"
#include "common/error.h"
#include "common/hamming.h"

namespace lmb {

void EmbeddingLayout::check() const {
  LMB_CHECK(num_regions >= 1 && num_regions <= kMaxContextRegions,
            "embedding layout: num_regions = " << num_regions << " out of range");
  LMB_CHECK(num_words >= 1 && num_words <= 256, "embedding layout: num_words = " << num_words << " must be in 1..256");
  LMB_CHECK(descriptor_bytes >= 0 && descriptor_bytes <= 1024,
            "embedding layout: descriptor_bytes = " << descriptor_bytes << " must be in 0..1024");
  LMB_CHECK(static_cast<int64_t>(num_regions) * num_words + 8 * descriptor_bytes < (int64_t{1} << 31),
            "embedding layout: " << num_regions << " regions x " << num_words << " words exceed 2^31 dimensions");
}

Eigen::Vector2d gravity_direction_in_image(const Eigen::Vector3d& gravity_in_cam, bool* degenerate) {
  LMB_CHECK(gravity_in_cam.allFinite(), "gravity_in_cam = (" << gravity_in_cam.transpose() << ") is not finite");
  const double norm = gravity_in_cam.norm();
  LMB_CHECK(norm > 0.0, "gravity_in_cam is the zero vector");
  const double in_plane = std::hypot(gravity_in_cam.x(), gravity_in_cam.y());
  const bool is_degenerate = !(in_plane >= kMinGravityInPlane * norm);
  if (degenerate) *degenerate = is_degenerate;
  if (is_degenerate) return Eigen::Vector2d(0.0, 1.0);
  return Eigen::Vector2d(gravity_in_cam.x() / in_plane, gravity_in_cam.y() / in_plane);
}

void normalize_keypoint(const Camera& camera, const Keypoint& keypoint, Eigen::Vector2d* position, double* scale) {
  LMB_CHECK(std::isfinite(keypoint.x) && std::isfinite(keypoint.y),
            "keypoint position (" << keypoint.x << ", " << keypoint.y << ") is not finite");
  LMB_CHECK(std::isfinite(keypoint.scale) && keypoint.scale > 0.f,
            "keypoint scale " << keypoint.scale << " must be finite and > 0");
  const Eigen::Vector2d pixel(keypoint.x, keypoint.y);
  const Eigen::Vector2d half(0.5 * keypoint.scale, 0.0);
  *position = camera.cam_from_img(pixel);
  *scale = (camera.cam_from_img(pixel + half) - camera.cam_from_img(pixel - half)).norm();
  LMB_CHECK(position->allFinite() && std::isfinite(*scale) && *scale > 0.0,
            "keypoint at pixel (" << keypoint.x << ", " << keypoint.y << ") size " << keypoint.scale
                                  << " does not map to a finite normalized position and scale");
}

FrameKeypoints align_frame_keypoints(const std::vector<Eigen::Vector2d>& positions, const std::vector<double>& scales,
                                     const std::vector<uint8_t>& words, const Eigen::Vector2d& gravity_dir,
                                     const std::string& where) {
  LMB_CHECK(
      positions.size() == scales.size() && positions.size() == words.size(),
      where << ": " << positions.size() << " positions, " << scales.size() << " scales, " << words.size() << " words");
  LMB_CHECK(gravity_dir.allFinite() && std::abs(gravity_dir.norm() - 1.0) < 1e-6,
            where << ": gravity direction (" << gravity_dir.transpose() << ") is not a unit vector");
  const double gx = gravity_dir.x(), gy = gravity_dir.y();
  FrameKeypoints f;
  const size_t n = positions.size();
  f.x.resize(n);
  f.y.resize(n);
  f.scale.resize(n);
  f.word = words;
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector2d& p = positions[i];
    LMB_CHECK(p.allFinite(), where << ": keypoint " << i << " position is not finite");
    LMB_CHECK(std::isfinite(scales[i]) && scales[i] > 0.0,
              where << ": keypoint " << i << " scale " << scales[i] << " must be finite and > 0");
    f.x[i] = static_cast<float>(gy * p.x() - gx * p.y());
    f.y[i] = static_cast<float>(gx * p.x() + gy * p.y());
    f.scale[i] = static_cast<float>(scales[i]);
    LMB_CHECK(std::isfinite(f.x[i]) && std::isfinite(f.y[i]) && f.scale[i] > 0.f && std::isfinite(f.scale[i]),
              where << ": keypoint " << i << " is out of float range");
  }
  return f;
}

FrameKeypoints frame_keypoints_from_detections(const Camera& camera, const Keypoint* keypoints, const uint8_t* words,
                                               int32_t n, const Eigen::Vector3d& gravity_in_cam,
                                               const std::string& where) {
  Eigen::Vector2d gravity_dir;
  try {
    gravity_dir = gravity_direction_in_image(gravity_in_cam);
  } catch (const Error& e) {
    LMB_FAIL(where << ": " << e.what());
  }
  std::vector<Eigen::Vector2d> positions(static_cast<size_t>(n));
  std::vector<double> scales(static_cast<size_t>(n));
  for (int32_t i = 0; i < n; ++i) {
    try {
      normalize_keypoint(camera, keypoints[i], &positions[i], &scales[i]);
    } catch (const Error& e) {
      LMB_FAIL(where << ": keypoint " << i << ": " << e.what());
    }
  }
  return align_frame_keypoints(positions, scales, std::vector<uint8_t>(words, words + n), gravity_dir, where);
}

// ---------------------------------------------------------------------------------------------
// FrameContext

FrameContext::FrameContext(const ContextRegions& regions, int32_t num_words)
    : regions_(&regions), num_words_(num_words), kernels_(&detail::embedding_kernels()) {
  LMB_CHECK(num_words >= 1 && num_words <= 256, "frame context: num_words = " << num_words << " must be in 1..256");
  LMB_CHECK(regions.size() >= 1, "frame context: no context regions");
}

FrameContext::FrameContext(const ContextRegions& regions, int32_t num_words, SimdLevel level)
    : FrameContext(regions, num_words) {
  kernels_ = detail::embedding_kernels(level);
  LMB_CHECK(kernels_ != nullptr, "frame context: this CPU cannot run the SIMD level " << simd_level_name(level));
}

void FrameContext::Axis::build(int32_t n) {
  // kCellsPerKeypoint cells a keypoint: most cells hold at most one keypoint.
  cells = std::max(1, kCellsPerKeypoint * n);
  lo = n > 0 ? sorted[0] : 0.f;
  const float range = n > 0 ? sorted[n - 1] - lo : 0.f;
  last = static_cast<float>(cells - 1);
  inv = range > 0.f ? static_cast<float>(cells) / range : 0.f;
  if (!std::isfinite(inv)) inv = 0.f;                                                 // one cell: correct, only slower
  sorted.resize(static_cast<size_t>(n) + 2, std::numeric_limits<float>::infinity());  // sentinels
  start.resize(static_cast<size_t>(cells) + 1);
  int32_t c = 0;
  for (int32_t i = 0; i < n; ++i) {
    const int32_t ci = cell(sorted[i]);
    while (c <= ci) start[c++] = static_cast<uint16_t>(i);
  }
  while (c <= cells) start[c++] = static_cast<uint16_t>(n);
}

// (v - lo) * inv rounds monotonically in v, and the clamp and truncation are monotone: v <= w
// implies cell(v) <= cell(w). Hence every coordinate at a rank below start[cell(v)] is < v and
// every one at or above start[cell(v) + 1] is > v.
inline int32_t FrameContext::Axis::cell(float v) const {
  float t = (v - lo) * inv;
  // Branch-free clamp to [0, cells - 1] (max / min instructions; NaN, impossible here, gives 0).
  t = t > 0.f ? t : 0.f;
  t = t < last ? t : last;
  return static_cast<int32_t>(t);
}

inline int32_t FrameContext::Axis::rank(float v) const {
  const int32_t c = cell(v);
  const int32_t i = start[c], e = start[c + 1];
  if (e - i <= 2) {  // branch-free (the sentinels make sorted[i + 1] readable)
    return i + static_cast<int32_t>((i < e) & (sorted[i] < v)) +
           static_cast<int32_t>((i + 1 < e) & (sorted[i + 1] < v));
  }
  return static_cast<int32_t>(std::lower_bound(sorted.data() + i, sorted.data() + e, v) - sorted.data());
}

detail::AxisView FrameContext::Axis::view() const {
  detail::AxisView v;
  v.sorted = sorted.data();
  v.start = start.data();
  v.lo = lo;
  v.inv = inv;
  v.last = last;
  return v;
}

namespace {

// Sorts indices by (value, index) and returns the sorted values.
void sort_by(const std::vector<float>& v, std::vector<int32_t>& order, std::vector<float>& sorted) {
  const int32_t n = static_cast<int32_t>(v.size());
  order.resize(static_cast<size_t>(n));
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&v](int32_t a, int32_t b) { return v[a] < v[b] || (v[a] == v[b] && a < b); });
  sorted.resize(static_cast<size_t>(n));
  for (int32_t i = 0; i < n; ++i) sorted[i] = v[order[i]];
}

// In-place 2D prefix sums of a side x side table whose cells hold 0/1 marks.
void prefix_sum_2d(uint16_t* t, int64_t side) {
  for (int64_t a = 1; a < side; ++a) {
    uint16_t* row = t + a * side;
    const uint16_t* prev = row - side;
    uint16_t run = 0;  // prefix sum of this row's marks
    for (int64_t b = 1; b < side; ++b) {
      run = static_cast<uint16_t>(run + row[b]);
      row[b] = static_cast<uint16_t>(prev[b] + run);
    }
  }
}

}  // namespace

void FrameContext::reset(const FrameKeypoints& frame, const std::string& where) {
  const int32_t n = frame.size();
  LMB_CHECK(
      frame.y.size() == frame.x.size() && frame.scale.size() == frame.x.size() && frame.word.size() == frame.x.size(),
      where << ": keypoint arrays of different lengths (x " << frame.x.size() << ", y " << frame.y.size() << ", scale "
            << frame.scale.size() << ", word " << frame.word.size() << ")");
  LMB_CHECK(n <= kMaxFrameKeypoints, where << ": " << n << " keypoints exceed the limit of " << kMaxFrameKeypoints);
  for (int32_t i = 0; i < n; ++i) {
    LMB_CHECK(std::isfinite(frame.x[i]) && std::isfinite(frame.y[i]),
              where << ": keypoint " << i << " position is not finite");
    LMB_CHECK(std::isfinite(frame.scale[i]) && frame.scale[i] > 0.f,
              where << ": keypoint " << i << " scale " << frame.scale[i] << " must be finite and > 0");
    LMB_CHECK(frame.word[i] < num_words_,
              where << ": keypoint " << i << " word " << int(frame.word[i]) << " >= vocabulary size " << num_words_);
  }
  n_ = n;
  x_ = frame.x;
  y_ = frame.y;
  scale_ = frame.scale;
  word_ = frame.word;
  const int32_t W = num_words_;

  // Global ranks along x and y, word-local ranks, and the per-word local rank tables.
  std::vector<int32_t> local_x(static_cast<size_t>(n)), local_y(static_cast<size_t>(n));
  rank_x_.resize(static_cast<size_t>(n));
  rank_y_.resize(static_cast<size_t>(n));
  auto build_ranks = [&](const std::vector<float>& v, std::vector<float>& sorted, std::vector<uint16_t>& table,
                         std::vector<int32_t>& local, std::vector<int32_t>& rank) {
    sort_by(v, order_, sorted);
    table.assign(static_cast<size_t>(n + 1) * W, 0);
    for (int32_t i = 0; i < n; ++i) {
      const int32_t j = order_[i];
      rank[j] = i;
      const uint16_t* row = table.data() + static_cast<size_t>(i) * W;
      uint16_t* next = table.data() + static_cast<size_t>(i + 1) * W;
      std::copy_n(row, W, next);
      local[j] = row[word_[j]];
      ++next[word_[j]];
    }
  };
  build_ranks(x_, axis_x_.sorted, local_rank_x_, local_x, rank_x_);
  build_ranks(y_, axis_y_.sorted, local_rank_y_, local_y, rank_y_);
  axis_x_.build(n);
  axis_y_.build(n);
  bin_magic_.resize(static_cast<size_t>(n) + 1);
  for (int32_t t = 0; t <= n; ++t) bin_magic_[t] = context_bin_magic(t);

  // Per-word prefix tables.
  word_side_.assign(static_cast<size_t>(W), 1);
  for (int32_t i = 0; i < n; ++i) ++word_side_[word_[i]];
  table_offset_.assign(static_cast<size_t>(W) + 1, 0);
  for (int32_t w = 0; w < W; ++w) {
    const int64_t side = word_side_[w];
    table_offset_[w + 1] = table_offset_[w] + side * side;
  }
  LMB_CHECK(table_offset_[W] <= (int64_t{1} << 30), where << ": the per-word tables would need " << table_offset_[W]
                                                          << " entries (too many keypoints of one visual word)");
  tables_.assign(static_cast<size_t>(table_offset_[W]), 0);
  for (int32_t i = 0; i < n; ++i) {
    const int32_t w = word_[i];
    const int64_t side = word_side_[w];
    tables_[table_offset_[w] + (local_x[i] + 1) * side + (local_y[i] + 1)] = 1;
  }
  for (int32_t w = 0; w < W; ++w) prefix_sum_2d(tables_.data() + table_offset_[w], word_side_[w]);

  build_byte_tables();
  build_dominance();
}

// Byte copies of the word tables and local ranks for the DimPlan path when every word has at
// most 255 keypoints: half the bytes, rows padded to 16 bytes (a 64-byte line for up to 63
// keypoints), so more of them stay in L1.
void FrameContext::build_byte_tables() {
  const int32_t n = n_, W = num_words_;
  small_words_ = n <= kMaxDominanceKeypoints && *std::max_element(word_side_.begin(), word_side_.end()) <= 256;
  if (small_words_) {
    offset8_.resize(static_cast<size_t>(W));
    stride8_.resize(static_cast<size_t>(W));
    int32_t size = 0;
    for (int32_t w = 0; w < W; ++w) {
      offset8_[w] = size;
      stride8_[w] = (word_side_[w] + 15) / 16 * 16;
      size += word_side_[w] * stride8_[w];
    }
    tables8_.assign(static_cast<size_t>(size) + 3, 0);  // + 3: read as 32-bit words
    for (int32_t w = 0; w < W; ++w) {
      const int32_t side = word_side_[w];
      for (int32_t a = 0; a < side; ++a) {
        for (int32_t b = 0; b < side; ++b) {
          tables8_[offset8_[w] + a * stride8_[w] + b] = static_cast<uint8_t>(tables_[table_offset_[w] + a * side + b]);
        }
      }
    }
    // Row offsets by x rank: word w's table row for local x rank local_rank_x_[ix * W + w].
    row8_x_.resize(local_rank_x_.size());
    for (size_t i = 0; i < local_rank_x_.size(); ++i) {
      const int32_t w = static_cast<int32_t>(i % static_cast<size_t>(W));
      row8_x_[i] = offset8_[w] + local_rank_x_[i] * stride8_[w];
    }
    local8_y_.assign(local_rank_y_.begin(), local_rank_y_.end());
    local8_y_.resize(local8_y_.size() + 3, 0);  // read as 32-bit words
  }
}

// Blocked dominance counts over all keypoints (see dom_ in the header); for frames up to
// kMaxDominanceKeypoints (larger ones take count_all from the word tables).
void FrameContext::build_dominance() {
  const int32_t n = n_;
  dom_.clear();
  if (n > kMaxDominanceKeypoints) return;
  const int32_t blocks = n / kDomBlock + 1;
  const size_t stride = static_cast<size_t>(n) + 1;
  dom_.assign(static_cast<size_t>(blocks) * stride, 0);
  // Per x rank: the start of its block's row and the mask of the block's keypoints before it.
  dom_row_.resize(stride);
  dom_below_.resize(stride);
  for (int32_t ix = 0; ix <= n; ++ix) {
    dom_row_[ix] = static_cast<int32_t>(static_cast<size_t>(ix / kDomBlock) * stride);
    dom_below_[ix] = (uint64_t{1} << (ix % kDomBlock)) - 1;
  }
  std::vector<int32_t> by_y(static_cast<size_t>(n));  // keypoint of each y rank
  for (int32_t i = 0; i < n; ++i) by_y[rank_y_[i]] = i;
  for (int32_t iy = 1; iy <= n; ++iy) {
    const int32_t rx = rank_x_[by_y[iy - 1]];  // the keypoint with y rank iy - 1
    for (int32_t b = 0; b < blocks; ++b) {
      const size_t at = static_cast<size_t>(b) * stride + iy;
      const uint64_t coarse = rx < kDomBlock * b ? uint64_t{1} << 48 : 0;
      const uint64_t bit = rx / kDomBlock == b ? uint64_t{1} << (rx % kDomBlock) : 0;
      dom_[at] = dom_[at - 1] + coarse + bit;  // no carry into the count: bits are set once
    }
  }
}

void FrameContext::counts_from_bounds(int32_t k, const Bounds& b, int32_t* counts, int32_t* total) const {
  const int32_t W = num_words_;
  int32_t sum = 0;
  if (b.ix0 == b.ix1 || b.iy0 == b.iy1) {
    std::fill_n(counts, W, 0);
  } else {
    const uint16_t* lx0 = local_rank_x_.data() + static_cast<size_t>(b.ix0) * W;
    const uint16_t* lx1 = local_rank_x_.data() + static_cast<size_t>(b.ix1) * W;
    const uint16_t* ly0 = local_rank_y_.data() + static_cast<size_t>(b.iy0) * W;
    const uint16_t* ly1 = local_rank_y_.data() + static_cast<size_t>(b.iy1) * W;
    const uint16_t* tables = tables_.data();
    for (int32_t w = 0; w < W; ++w) {
      const int64_t side = word_side_[w];
      const uint16_t* t = tables + table_offset_[w];
      const int64_t r0 = lx0[w] * side, r1 = lx1[w] * side;
      const int64_t c0 = ly0[w], c1 = ly1[w];
      const int32_t c = static_cast<int32_t>(t[r1 + c1]) - t[r0 + c1] - t[r1 + c0] + t[r0 + c0];
      counts[w] = c;
      sum += c;
    }
  }
  if (b.anchor_inside) {
    --counts[word_[k]];
    --sum;
  }
  *total = sum;
}

int32_t FrameContext::region_counts(int32_t k, int32_t r, int32_t* counts) const {
  assert(k >= 0 && k < n_ && r >= 0 && r < regions_->size());
  int32_t total = 0;
  counts_from_bounds(k, bounds(k, (*regions_)[r]), counts, &total);
  return total;
}

void FrameContext::embed_context(int32_t k, uint8_t* out) const {
  assert(k >= 0 && k < n_);
  const int32_t W = num_words_;
  const int32_t R = regions_->size();
  int32_t counts[256];
  for (int32_t r = 0; r < R; ++r) {
    int32_t total = 0;
    counts_from_bounds(k, bounds(k, (*regions_)[r]), counts, &total);
    uint8_t* o = out + static_cast<size_t>(r) * W;
    if (total == 0) {
      std::fill_n(o, W, uint8_t{0});
      continue;
    }
    const uint64_t magic = bin_magic_[total];
    for (int32_t w = 0; w < W; ++w) o[w] = context_bin_fast(counts[w], total, magic);
  }
}

void FrameContext::compute_dims(int32_t k, const int32_t* dims, int32_t num_dims, const uint8_t* descriptor,
                                int32_t descriptor_bytes, uint8_t* out) const {
  assert(k >= 0 && k < n_);
  const int32_t W = num_words_;
  const int32_t context_dims = regions_->size() * W;
  int32_t i = 0;
  int32_t counts[256];
  while (i < num_dims && dims[i] < context_dims) {
    const int32_t r = dims[i] / W;
    int32_t end = i + 1;
    while (end < num_dims && dims[end] < (r + 1) * W) ++end;
    const Bounds b = bounds(k, (*regions_)[r]);
    int32_t total = 0;
    counts_from_bounds(k, b, counts, &total);
    for (int32_t j = i; j < end; ++j) out[j] = context_bin(counts[dims[j] - r * W], total);
    i = end;
  }
  for (; i < num_dims; ++i) {
    const int32_t bit = dims[i] - context_dims;
    assert(descriptor != nullptr && bit < 8 * descriptor_bytes);
    out[i] = static_cast<uint8_t>(descriptor_bit(descriptor, bit));
  }
}

void FrameContext::compute_dims_all(const int32_t* dims, int32_t num_dims, const uint8_t* descriptors,
                                    int32_t descriptor_bytes, uint8_t* out) const {
  for (int32_t k = 0; k < n_; ++k) {
    compute_dims(k, dims, num_dims, descriptors ? descriptors + static_cast<size_t>(k) * descriptor_bytes : nullptr,
                 descriptor_bytes, out + static_cast<size_t>(k) * num_dims);
  }
}

DimPlan::DimPlan(const ContextRegions& regions, const EmbeddingLayout& layout, std::vector<int32_t> dims)
    : layout_(layout), dims_(std::move(dims)) {
  layout_.check();
  LMB_CHECK(layout_.num_regions == regions.size(),
            "dim plan: layout has " << layout_.num_regions << " regions, the region set " << regions.size());
  for (size_t i = 0; i < dims_.size(); ++i) {
    LMB_CHECK(dims_[i] >= 0 && dims_[i] < layout_.num_dims(),
              "dim plan: dims[" << i << "] = " << dims_[i] << " is outside 0.." << layout_.num_dims() - 1);
    LMB_CHECK(i == 0 || dims_[i] > dims_[i - 1],
              "dim plan: dims must be sorted ascending without repeats (dims[" << i << "] = " << dims_[i] << ")");
  }
  const int32_t n = static_cast<int32_t>(dims_.size());
  int32_t i = 0;
  while (i < n && layout_.is_context(dims_[i])) {
    const int32_t r = layout_.region_of(dims_[i]);
    used_regions_.push_back(r);
    corners_[0].push_back(regions[r].x0);
    corners_[1].push_back(regions[r].x1);
    corners_[2].push_back(regions[r].y0);
    corners_[3].push_back(regions[r].y1);
    dim_begin_.push_back(i);
    while (i < n && layout_.is_context(dims_[i]) && layout_.region_of(dims_[i]) == r) {
      dim_word_.push_back(static_cast<uint8_t>(layout_.word_of(dims_[i])));
      ++i;
    }
  }
  dim_begin_.push_back(i);
  num_context_ = i;
  for (std::vector<float>& c : corners_) c.resize((c.size() + 7) / 8 * 8, 0.f);
}

FrameContext::BinTables FrameContext::bin_tables() const {
  BinTables t;
  t.rank_x = rank_x_.data();
  t.rank_y = rank_y_.data();
  t.word = word_.data();
  t.bin_magic = bin_magic_.data();
  if (!dom_.empty()) {
    t.dom = dom_.data();
    t.dom_row = dom_row_.data();
    t.dom_below = dom_below_.data();
  }
  if (small_words_) {
    t.tables8 = tables8_.data();
    t.row8_x = row8_x_.data();
    t.local8_y = local8_y_.data();
  }
  t.num_words = num_words_;
  return t;
}

// Cloned for AVX2: the popcounts of dominance() become single instructions.
LMB_CLONES_AVX2 void FrameContext::compute_dims(int32_t k, const DimPlan& plan, const uint8_t* descriptor,
                                                uint8_t* out) const {
  assert(k >= 0 && k < n_);
  assert(plan.layout_.num_words == num_words_ && plan.layout_.num_regions == regions_->size());
  const int32_t U = plan.num_used_regions();
  const int32_t* dim_begin = plan.dim_begin_.data();
  const uint8_t* dim_word = plan.dim_word_.data();
  const BinTables tables = bin_tables();
  // Regions in chunks: first every region's rank bounds (independent chains of reads, 8 regions
  // a step with AVX2 gathers), then the counts, where the test for an empty region no longer
  // waits on them.
  constexpr int32_t kChunk = kMaxRankBatch;
  alignas(32) int32_t ranks[4][kChunk];  // ix0, ix1, iy0, iy1 of the chunk's regions
  const float px = x_[k], py = y_[k], s = scale_[k];
  const detail::AxisView ax = axis_x_.view(), ay = axis_y_.view();
  for (int32_t u0 = 0; u0 < U; u0 += kChunk) {
    const int32_t m = std::min(kChunk, U - u0);
    kernels_->corner_ranks(ax, px, s, plan.corners_[0].data() + u0, m, ranks[0]);
    kernels_->corner_ranks(ax, px, s, plan.corners_[1].data() + u0, m, ranks[1]);
    kernels_->corner_ranks(ay, py, s, plan.corners_[2].data() + u0, m, ranks[2]);
    kernels_->corner_ranks(ay, py, s, plan.corners_[3].data() + u0, m, ranks[3]);
    for (int32_t i = 0; i < m; ++i) {
      const int32_t begin = dim_begin[u0 + i], end = dim_begin[u0 + i + 1];
      region_bins(tables, k, ranks[0][i], ranks[1][i], ranks[2][i], ranks[3][i], dim_word, begin, end, out, 1);
    }
  }
  const int32_t* dims = plan.dims_.data();
  const int32_t context_dims = plan.layout_.num_context_dims();
  for (int32_t j = plan.num_context_; j < plan.size(); ++j) {
    out[j] = static_cast<uint8_t>(descriptor_bit(descriptor, dims[j] - context_dims));
  }
}

void FrameContext::check_plan(const DimPlan& plan, const uint8_t* descriptors, int32_t count) const {
  LMB_CHECK(plan.layout().num_words == num_words_ && plan.layout().num_regions == regions_->size(),
            "dim plan: made for " << plan.layout().num_regions << " regions x " << plan.layout().num_words
                                  << " words, the frame context has " << regions_->size() << " x " << num_words_);
  LMB_CHECK(
      descriptors != nullptr || plan.size() == 0 || count == 0 || plan.dims().back() < plan.layout().num_context_dims(),
      "dim plan: descriptor dims requested without descriptors");
}

void FrameContext::compute_dims_all(const DimPlan& plan, const uint8_t* descriptors, uint8_t* out) const {
  check_plan(plan, descriptors, n_);
  const int32_t bytes = plan.layout().descriptor_bytes;
  for (int32_t k = 0; k < n_; ++k) {
    compute_dims(k, plan, descriptors ? descriptors + static_cast<size_t>(k) * bytes : nullptr,
                 out + static_cast<size_t>(k) * plan.size());
  }
}

// ---------------------------------------------------------------------------------------------
// Reference

int32_t region_counts_brute_force(const ContextRegions& regions, int32_t num_words, const FrameKeypoints& frame,
                                  int32_t k, int32_t r, int32_t* counts) {
  const RegionRect& q = regions[r];
  const float px = frame.x[k], py = frame.y[k], s = frame.scale[k];
  const float lo_x = detail::region_bound(px, s, q.x0);
  const float hi_x = detail::region_bound(px, s, q.x1);
  const float lo_y = detail::region_bound(py, s, q.y0);
  const float hi_y = detail::region_bound(py, s, q.y1);
  std::fill_n(counts, num_words, 0);
  int32_t total = 0;
  for (int32_t j = 0; j < frame.size(); ++j) {
    if (j == k) continue;
    const float x = frame.x[j], y = frame.y[j];
    if (lo_x <= x && x < hi_x && lo_y <= y && y < hi_y) {
      ++counts[frame.word[j]];
      ++total;
    }
  }
  return total;
}

void embed_context_brute_force(const ContextRegions& regions, int32_t num_words, const FrameKeypoints& frame, int32_t k,
                               uint8_t* out) {
  std::vector<int32_t> counts(static_cast<size_t>(num_words));
  for (int32_t r = 0; r < regions.size(); ++r) {
    const int32_t total = region_counts_brute_force(regions, num_words, frame, k, r, counts.data());
    for (int32_t w = 0; w < num_words; ++w) {
      out[static_cast<size_t>(r) * num_words + w] = context_bin(counts[w], total);
    }
  }
}

}  // namespace lmb
