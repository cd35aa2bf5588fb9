// Context embeddings and feature vectors (the paper's Fig. 4), computed identically in training and
// inference.
//
// Feature vector of a keypoint k (every value a uint8 bin, see train/features/feature_matrix.h):
//   dim d <  R*W : region r = d / W, word w = d % W:
//                  bin = (255 * count_w + count_all / 2) / count_all  (integer arithmetic),
//                  0 when the region holds no keypoint; count_w = keypoints of word w in region r
//                  of k, count_all = all keypoints in it. The anchor k itself is never counted;
//                  other keypoints at the same position are.
//   dim d >= R*W : descriptor bit b = d - R*W of k's own descriptor (0/1; bit b is bit b % 8 of
//                  byte b / 8, LSB first, lmb::descriptor_bit).
//
// Geometry (one convention for map and query frames):
//   - pixel: a Keypoint's (x, y) is in COLMAP's convention (centre of the top-left pixel at
//     (0.5, 0.5)), which Camera uses; detectors that report OpenCV's KeyPoint::pt add 0.5 when
//     they make a Keypoint (see common/types.h).
//   - position p = camera.cam_from_img(pixel): normalized undistorted plane (x right, y down).
//   - scale s = |cam_from_img(pixel + (size/2, 0)) - cam_from_img(pixel - (size/2, 0))|, the detector
//     diameter mapped through the local undistortion (size / focal for a pinhole camera).
//   - gravity: ONE direction per frame, gravity_in_cam's image-plane direction at the principal ray,
//     (g_x, g_y) / |(g_x, g_y)|. Every keypoint is rotated into the gravity-aligned frame where
//     gravity points to +y:  p' = (g_y p_x - g_x p_y,  g_x p_x + g_y p_y)  (in double, then float).
//     Degenerate gravity (|(g_x, g_y)| < kMinGravityInPlane * |g|, i.e. within ~0.06 degrees of the
//     optical axis, where the direction is undefined) falls back to the image's own +y axis (no
//     rotation); a zero or non-finite gravity vector is an lmb::Error.
//   - region r of keypoint k: [p'_k.x + s_k*x0_r, p'_k.x + s_k*x1_r) x [p'_k.y + s_k*y0_r, ...),
//     each bound computed in float as lo = p'_k.x + s_k * x0_r; keypoint j is inside when
//     lo_x <= p'_j.x < hi_x and lo_y <= p'_j.y < hi_y (float comparisons). The fast path and the
//     brute-force reference evaluate exactly these expressions, so they agree bit for bit.
//
// Invariance: translating the frame, scaling it (positions and keypoint scales) and rotating it
// together with its gravity vector leave every bin unchanged whenever the transformed coordinates
// and region bounds are exact in float (powers-of-two scales, dyadic translations, multiples of 90
// degrees; region corners are multiples of 1/1024 keypoint scale for this reason). Otherwise float
// rounding of p' can move a keypoint that lies within ~1e-7 (relative) of a region border across
// it: the counts then differ by at most the keypoints at the borders.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "common/camera.h"
#include "common/context_regions.h"
#include "common/simd/embedding_kernels.h"
#include "common/simd/simd_level.h"
#include "common/types.h"

namespace lmb {

constexpr double kMinGravityInPlane = 1e-3;

// Dimension layout of a feature vector (see the file comment).
struct EmbeddingLayout {
  int32_t num_regions = 0;
  int32_t num_words = 0;
  int32_t descriptor_bytes = 0;

  int32_t num_context_dims() const { return num_regions * num_words; }
  int32_t num_dims() const { return num_context_dims() + 8 * descriptor_bytes; }
  bool is_context(int32_t d) const { return d < num_context_dims(); }
  int32_t region_of(int32_t d) const { return d / num_words; }
  int32_t word_of(int32_t d) const { return d % num_words; }
  int32_t bit_of(int32_t d) const { return d - num_context_dims(); }
  // Throws lmb::Error when a count is out of range.
  void check() const;
};

// The bin of a word count in a region of `total` keypoints: (255 * count + total / 2) / total,
// 0 when total is 0.
inline uint8_t context_bin(int32_t count, int32_t total) {
  return total > 0 ? static_cast<uint8_t>((255 * static_cast<int64_t>(count) + total / 2) / total) : uint8_t{0};
}

// context_bin without a division: with m = context_bin_magic(total),
// context_bin_fast(count, total, m) == context_bin(count, total) for 0 <= count <= total <= 65535.
// m = floor(2^40 / total) + 1 (0 for total 0). Why it is exact: x = 255 * count + total / 2 <
// 256 * total, and x * m / 2^40 = x / total + x * e / 2^40 with 0 < e <= 1; the error term is
// below 256 * total / 2^40 < 1 / total (total < 2^16), less than the gap between the fraction
// x / total - floor(x / total) <= 1 - 1 / total and the next integer. x * m < 2^48 + 2^24.
inline uint64_t context_bin_magic(int32_t total) {
  return total > 0 ? (uint64_t{1} << 40) / static_cast<uint64_t>(total) + 1 : 0;
}
inline uint8_t context_bin_fast(int32_t count, int32_t total, uint64_t magic) {
  const uint64_t x = 255 * static_cast<uint64_t>(count) + static_cast<uint64_t>(total / 2);
  return static_cast<uint8_t>((x * magic) >> 40);
}

// The image-plane direction of gravity (unit 2-vector), see the file comment. Sets *degenerate
// when the fallback (0, 1) was used. Throws lmb::Error for a zero or non-finite vector.
Eigen::Vector2d gravity_direction_in_image(const Eigen::Vector3d& gravity_in_cam, bool* degenerate = nullptr);

// Normalized position and scale of a detector keypoint (see the file comment). Throws lmb::Error
// when the size is not finite and > 0 or the position is not finite.
void normalize_keypoint(const Camera& camera, const Keypoint& keypoint, Eigen::Vector2d* position, double* scale);

// One frame's keypoints in the gravity-aligned normalized plane, with their visual words.
struct FrameKeypoints {
  std::vector<float> x;
  std::vector<float> y;
  std::vector<float> scale;  // > 0, normalized-plane units
  std::vector<uint8_t> word;

  int32_t size() const { return static_cast<int32_t>(x.size()); }
};

// Rotates normalized positions into the gravity-aligned frame (gravity_dir: a unit image-plane
// direction from gravity_direction_in_image). All vectors have the same length. Throws lmb::Error
// (prefixed by `where`) for non-finite positions, non-finite or non-positive scales.
FrameKeypoints align_frame_keypoints(const std::vector<Eigen::Vector2d>& positions, const std::vector<double>& scales,
                                     const std::vector<uint8_t>& words, const Eigen::Vector2d& gravity_dir,
                                     const std::string& where);

// The whole chain for detector keypoints of one frame: normalize_keypoint, gravity_direction_in_image,
// align_frame_keypoints. `words` has n entries. Throws lmb::Error prefixed by `where`.
FrameKeypoints frame_keypoints_from_detections(const Camera& camera, const Keypoint* keypoints, const uint8_t* words,
                                               int32_t n, const Eigen::Vector3d& gravity_in_cam,
                                               const std::string& where);

// A model's used dimensions, prepared once for fast per-keypoint evaluation: the used regions and
// their rectangles, each region's dims contiguous.
class DimPlan {
 public:
  DimPlan() = default;
  // dims: sorted ascending, unique, each < layout.num_dims(). Throws lmb::Error otherwise, or
  // when the layout does not match the regions.
  DimPlan(const ContextRegions& regions, const EmbeddingLayout& layout, std::vector<int32_t> dims);

  const std::vector<int32_t>& dims() const { return dims_; }
  int32_t size() const { return static_cast<int32_t>(dims_.size()); }
  const EmbeddingLayout& layout() const { return layout_; }
  int32_t num_used_regions() const { return static_cast<int32_t>(used_regions_.size()); }

 private:
  friend class FrameContext;
  EmbeddingLayout layout_;
  std::vector<int32_t> dims_;
  std::vector<int32_t> used_regions_;  // region ids, ascending
  // Their rectangles' corners, one array each (x0, x1, y0, y1), padded to a multiple of 8.
  std::vector<float> corners_[4];
  std::vector<int32_t> dim_begin_;  // dims of used region u: [dim_begin_[u], dim_begin_[u+1])
  std::vector<uint8_t> dim_word_;   // the word of each context dim
  int32_t num_context_ = 0;         // dims_[0, num_context_) are context dims
};

// Per-frame spatial index answering "how many keypoints of word w lie in region r of keypoint k" in
// O(1) expected time: keypoints sorted by x and by y, and per word a coordinate-compressed 2D
// prefix-count table over its own points ((n_w + 1)^2 uint16 entries, about n^2 / W in all). A
// region bound p + s * c is ranked (keypoints below it along the axis) through a uniform grid over
// the axis's sorted coordinates: the grid cell of a coordinate is a monotone function of it, so
// the cell's first rank and the next cell's bracket the answer exactly, and the keypoints of the
// cell are compared with the bound directly (16 cells a keypoint: most hold none or one; a binary
// search when there are more than two, or with AVX2 more than one). Then 4 table reads per word; count_all is the sum
// over the words. The anchor is removed by comparing its own ranks with the region's rank ranges. (A table over all
// keypoints for count_all was measured slower: at (n+1)^2 entries it does not stay in cache.) The DimPlan overloads
// read only the plan's words of a region and take count_all from a blocked dominance structure of ~n^2 / 6 bytes
// (48-keypoint bitmasks packed with block prefix counts): 4 reads and popcounts instead of one table lookup per word;
// bins divide by multiplying with a per-frame table of context_bin_magic. The DimPlan paths run the
// rank and column kernels of the SIMD level (common/simd/embedding_kernels.h: AVX2 gathers for the
// ranks, AVX-512 for 16 keypoints' bins of a region), which give the same values at every level.
//
// Usage: construct once per thread (buffers are reused), reset() per frame, then query from one
// thread; the const query methods are safe to call concurrently after reset().
class FrameContext {
 public:
  // The most values one rank kernel call ranks (a stack batch).
  static constexpr int32_t kMaxRankBatch = detail::kMaxRankBatch;

  // Counts are stored as uint16: a frame may hold at most this many keypoints.
  static constexpr int32_t kMaxFrameKeypoints = 65535;
  // Frames up to this size get the dominance structure of the DimPlan path (11 MB at the limit).
  static constexpr int32_t kMaxDominanceKeypoints = 8192;

  // regions must outlive this object. num_words in 1..256. The kernels are those of the process's
  // SIMD level (common/simd/simd_level.h), or of `level` (tests; throws lmb::Error when this CPU
  // cannot run it): every level gives the same values.
  FrameContext(const ContextRegions& regions, int32_t num_words);
  FrameContext(const ContextRegions& regions, int32_t num_words, SimdLevel level);
  SimdLevel simd_level() const { return kernels_->level; }

  // Builds the index for a frame. Throws lmb::Error (prefixed by `where`) when a word is >=
  // num_words, a scale is not finite and > 0, a coordinate is not finite, or the frame has more
  // than kMaxFrameKeypoints keypoints. An empty frame is valid (nothing to query).
  void reset(const FrameKeypoints& frame, const std::string& where = "frame");

  int32_t num_keypoints() const { return n_; }
  int32_t num_words() const { return num_words_; }
  const ContextRegions& regions() const { return *regions_; }

  // counts[w] for w < num_words: keypoints of each word in region r of keypoint k (anchor
  // excluded); returns count_all.
  int32_t region_counts(int32_t k, int32_t r, int32_t* counts) const;
  // The R*W context bins of keypoint k, region-major (out[r * W + w]).
  void embed_context(int32_t k, uint8_t* out) const;
  // Values of the given dims (sorted ascending, each < layout().num_dims()) of keypoint k, whose
  // own descriptor is `descriptor` (descriptor_bytes bytes; may be null when no dim is a bit).
  // out[i] is the value of dims[i].
  void compute_dims(int32_t k, const int32_t* dims, int32_t num_dims, const uint8_t* descriptor,
                    int32_t descriptor_bytes, uint8_t* out) const;
  // compute_dims for every keypoint of the frame: out is n x num_dims, row-major (keypoint rows).
  // descriptors: n rows of descriptor_bytes bytes, in frame order.
  void compute_dims_all(const int32_t* dims, int32_t num_dims, const uint8_t* descriptors, int32_t descriptor_bytes,
                        uint8_t* out) const;
  // The same with a prepared plan (faster: the regions' bounds are ranked 8 at a time, only the
  // plan's words of a region are counted, and count_all comes from the dominance structure). out
  // has plan.size() bytes; descriptor has plan.layout().descriptor_bytes bytes. The plan must come
  // from this context's regions and word count (asserted).
  void compute_dims(int32_t k, const DimPlan& plan, const uint8_t* descriptor, uint8_t* out) const;
  // For every keypoint: out is n x plan.size(), row-major. Throws lmb::Error when the plan's
  // layout does not match this context.
  void compute_dims_all(const DimPlan& plan, const uint8_t* descriptors, uint8_t* out) const;
  // The same values for the keypoints ids[0, count) (distinct frame indices), column-major:
  // out[u * stride + i] is plan dim u of keypoint ids[i] (stride >= count). descriptors: the
  // frame's n rows, in frame order. Region by region over the keypoints in x order (not
  // keypoint by keypoint), so that the table rows a region's corners read stay in L1 from one
  // keypoint to the next: faster when most of a frame's keypoints need the same dims.
  void compute_dims_columns(const DimPlan& plan, const int32_t* ids, int32_t count, const uint8_t* descriptors,
                            uint8_t* out, size_t stride) const;

 private:
  struct Bounds {
    int32_t ix0, ix1, iy0, iy1;  // global rank ranges [ix0, ix1), [iy0, iy1)
    bool anchor_inside;
  };
  // Ranks along one axis: sorted coordinates (plus two +inf sentinels at n and n + 1) and a
  // uniform grid of `cells` cells over [lo, lo + cells / inv); start[c] = the first rank whose
  // coordinate's cell is >= c (cells + 1 entries; ranks fit uint16, see kMaxFrameKeypoints).
  struct Axis {
    static constexpr int32_t kCellsPerKeypoint = 16;
    std::vector<float> sorted;
    float lo = 0.f, inv = 0.f;
    int32_t cells = 1;
    float last = 0.f;  // cells - 1
    std::vector<uint16_t> start;

    void build(int32_t n);  // from sorted[0, n)
    int32_t cell(float v) const;
    // Number of coordinates < v.
    int32_t rank(float v) const;
    // The axis for the rank kernels (detail::EmbeddingKernels, the same ranks as rank()).
    detail::AxisView view() const;
  };
  // The frame's tables as plain pointers, for region_bins (dom null without the dominance
  // structure, tables8 null without the byte word tables).
  struct BinTables {
    const int32_t* rank_x = nullptr;
    const int32_t* rank_y = nullptr;
    const uint8_t* word = nullptr;
    const uint64_t* bin_magic = nullptr;
    const uint64_t* dom = nullptr;
    const int32_t* dom_row = nullptr;
    const uint64_t* dom_below = nullptr;
    const uint8_t* tables8 = nullptr;
    const int32_t* row8_x = nullptr;
    const uint8_t* local8_y = nullptr;
    int32_t num_words = 0;
    // Keypoints (of any word) with x rank < ix and y rank < iy (needs dom).
    int32_t dominance(int32_t ix, int32_t iy) const;
  };
  BinTables bin_tables() const;
  void region_bins(const BinTables& t, int32_t k, int32_t ix0, int32_t ix1, int32_t iy0, int32_t iy1,
                   const uint8_t* dim_word, int32_t begin, int32_t end, uint8_t* out, size_t stride) const;
  // Throws lmb::Error when the plan's layout does not match this context, or when it has
  // descriptor dims and descriptors is null (with count > 0 keypoints to compute).
  void check_plan(const DimPlan& plan, const uint8_t* descriptors, int32_t count) const;
  // The region rectangle q of keypoint k as rank ranges.
  Bounds bounds(int32_t k, const RegionRect& q) const;
  // reset()'s last steps: the byte word tables (small_words_) and the dominance structure (dom_).
  void build_byte_tables();
  void build_dominance();
  void counts_from_bounds(int32_t k, const Bounds& b, int32_t* counts, int32_t* total) const;
  // Keypoints of word w with x rank < ix and y rank < iy.
  int32_t word_dominance(int32_t w, int32_t ix, int32_t iy) const;

  const ContextRegions* regions_;
  int32_t num_words_;
  int32_t n_ = 0;
  std::vector<float> x_, y_, scale_;
  std::vector<uint8_t> word_;
  Axis axis_x_, axis_y_;
  std::vector<int32_t> rank_x_, rank_y_;  // each keypoint's position in x (y) order
  // local_rank_x_[ix * W + w]: points of word w among the first ix points in x order.
  std::vector<uint16_t> local_rank_x_, local_rank_y_;
  // Per word: table of (n_w + 1)^2 prefix counts, row a = local x rank, column b = local y rank.
  std::vector<int32_t> word_side_;
  std::vector<int64_t> table_offset_;
  std::vector<uint16_t> tables_;
  // All keypoints' dominance counts for count_all in the DimPlan path (which reads only the
  // plan's words of a region), one 64-bit read each: x order cut into blocks of kDomBlock;
  // dom_[b * (n + 1) + iy] = (keypoints in blocks < b with y rank < iy) << 48 | bit i set when
  // the i-th keypoint of block b has y rank < iy. About n^2 / 6 bytes: stays in L2.
  static constexpr int32_t kDomBlock = detail::kDomBlock;
  std::vector<uint64_t> dom_;
  std::vector<int32_t> dom_row_;     // per x rank ix: (ix / kDomBlock) * (n + 1)
  std::vector<uint64_t> dom_below_;  // per x rank ix: the low ix % kDomBlock bits set
  // When every word has at most 255 keypoints (and the frame gets dom_): the word tables as bytes,
  // word w's at offset8_[w] with rows of stride8_[w] bytes; the local y ranks as bytes.
  bool small_words_ = false;
  // row8_x_[ix * W + w]: offset in tables8_ of word w's row for x rank ix.
  std::vector<uint8_t> tables8_, local8_y_;
  std::vector<int32_t> row8_x_;
  std::vector<int32_t> offset8_, stride8_;
  std::vector<uint64_t> bin_magic_;  // context_bin_magic(t) for t in 0..n
  std::vector<int32_t> order_;       // scratch
  const detail::EmbeddingKernels* kernels_;
};

// Reference implementation: the naive loop over every other keypoint of the frame, region by
// region, with the same float expressions as FrameContext. out has R*W bytes.
void embed_context_brute_force(const ContextRegions& regions, int32_t num_words, const FrameKeypoints& frame, int32_t k,
                               uint8_t* out);
// Brute-force counts of one region (anchor excluded); returns count_all.
int32_t region_counts_brute_force(const ContextRegions& regions, int32_t num_words, const FrameKeypoints& frame,
                                  int32_t k, int32_t r, int32_t* counts);

}  // namespace lmb
