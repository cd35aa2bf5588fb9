// Context regions (the paper's "Modeling visual context"): R axis-aligned rectangles, common to
// all landmarks, expressed relative to a keypoint in the gravity-aligned normalized image plane, in
// multiples of the keypoint's scale. For keypoint k at gravity-aligned position p'_k with scale s_k
// (both in normalized-plane units, see common/context_embedding.h), region r covers
//   [p'_k.x + s_k * x0_r, p'_k.x + s_k * x1_r) x [p'_k.y + s_k * y0_r, p'_k.y + s_k * y1_r).
// In the gravity-aligned frame +y points down (along gravity) and +x to the right.
//
// Generation from a seed (lmb::Rng, so the same seed gives the same set on every platform):
//   area   = exp(U(log min_area, log max_area))         so that Pr(area) is proportional to 1/area
//   aspect = exp(U(-log max_aspect, log max_aspect))     width / height, log-uniform
//   centre = d * (cos t, sin t), d = U(0, max_offset), t = U(0, 2 pi)
// The centre distance is uniform along the radius, so per unit of plane area the centres are denser
// near the keypoint (density falls as 1/distance) while still reaching max_offset keypoint scales
// away: near and far context. Corners are rounded to multiples of kRegionGrid (1/1024 of a keypoint
// scale), which makes region borders exact dyadic numbers (see the invariance tests).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace cereal {
class PortableBinaryOutputArchive;
}

namespace lmb {

class BoundedReader;  // common/bounded_reader.h

// Corner resolution of generated regions, in keypoint scales.
constexpr double kRegionGrid = 1.0 / 1024.0;
// Upper bound on the region count accepted by options and by deserialization.
constexpr int32_t kMaxContextRegions = 1 << 20;

struct ContextRegionOptions {
  int32_t num_regions = 1000;  // R
  uint64_t seed = 1;
  // Region area, in squared keypoint scales (the keypoint scale is the detector diameter mapped to
  // the normalized plane). A BRISK keypoint of 12-20 px makes the largest default region 380-640 px
  // on a side at aspect 1: a good fraction of a VGA image.
  double min_area = 1.0;
  double max_area = 1024.0;
  double max_aspect = 4.0;   // width/height in [1/max_aspect, max_aspect]
  double max_offset = 24.0;  // largest centre distance from the keypoint, in keypoint scales

  // Throws lmb::Error naming the field: num_regions outside 1..kMaxContextRegions, non-finite or
  // non-positive areas, min_area > max_area, max_aspect < 1, negative max_offset.
  void check() const;
};

// One region in keypoint-scale units, relative to the keypoint, half-open: [x0, x1) x [y0, y1).
struct RegionRect {
  float x0 = 0.f;
  float y0 = 0.f;
  float x1 = 0.f;
  float y1 = 0.f;

  double area() const { return (static_cast<double>(x1) - x0) * (static_cast<double>(y1) - y0); }
};

class ContextRegions {
 public:
  ContextRegions() = default;
  // Generates options.num_regions regions (options.check() first).
  explicit ContextRegions(const ContextRegionOptions& options);
  // Takes explicit rectangles (tests, hand-made sets). Throws lmb::Error when empty, too many, or a
  // rectangle is not finite or has x1 <= x0 or y1 <= y0.
  explicit ContextRegions(std::vector<RegionRect> rects, ContextRegionOptions options = {});

  int32_t size() const { return static_cast<int32_t>(rects_.size()); }
  const RegionRect& operator[](int32_t r) const { return rects_[r]; }
  const std::vector<RegionRect>& rects() const { return rects_; }
  // The options the set was generated from (informative for hand-made sets).
  const ContextRegionOptions& options() const { return options_; }

  // Throws lmb::Error (prefixed by `where`) for an invalid set; called after deserialization.
  void validate(const std::string& where) const;

  bool operator==(const ContextRegions& other) const;

 private:
  ContextRegionOptions options_;
  std::vector<RegionRect> rects_;
};

// The one serialization of a region set (model.lbm, model.bin, checkpoints), cereal portable binary:
// the options (int32 num_regions, uint64 seed, double min_area, max_area, max_aspect, max_offset),
// a uint64 count, then count x (float x0, y0, x1, y1).
void write_context_regions(cereal::PortableBinaryOutputArchive& ar, const ContextRegions& regions);
// Reads it back. Throws lmb::Error "<reader.what()>: regions: <reason>" for a count outside
// 1..kMaxContextRegions (checked before allocating) or an invalid rectangle; a read past the end
// throws cereal::Exception.
ContextRegions read_context_regions(BoundedReader& reader);

}  // namespace lmb
