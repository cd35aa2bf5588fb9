#include "common/context_regions.h"

#include <cmath>
#include <cstring>

#include "common/bounded_reader.h"
#include "common/error.h"
#include "common/random.h"

namespace lmb {

void ContextRegionOptions::check() const {
  LMB_CHECK(num_regions >= 1 && num_regions <= kMaxContextRegions,
            "context regions: num_regions = " << num_regions << " must be in 1.." << kMaxContextRegions);
  LMB_CHECK(std::isfinite(min_area) && min_area > 0.0,
            "context regions: min_area = " << min_area << " must be finite and > 0");
  LMB_CHECK(std::isfinite(max_area) && max_area >= min_area,
            "context regions: max_area = " << max_area << " must be finite and >= min_area (" << min_area << ")");
  LMB_CHECK(max_area <= 1e8, "context regions: max_area = " << max_area << " exceeds 1e8");
  LMB_CHECK(std::isfinite(max_aspect) && max_aspect >= 1.0 && max_aspect <= 1e3,
            "context regions: max_aspect = " << max_aspect << " must be in [1, 1000]");
  LMB_CHECK(std::isfinite(max_offset) && max_offset >= 0.0 && max_offset <= 1e4,
            "context regions: max_offset = " << max_offset << " must be in [0, 1e4]");
}

namespace {

float snap(double v) { return static_cast<float>(std::round(v / kRegionGrid) * kRegionGrid); }

void validate_rects(const std::vector<RegionRect>& rects, const std::string& where) {
  LMB_CHECK(!rects.empty(), where << ": no regions");
  LMB_CHECK(rects.size() <= static_cast<size_t>(kMaxContextRegions),
            where << ": " << rects.size() << " regions exceed " << kMaxContextRegions);
  for (size_t r = 0; r < rects.size(); ++r) {
    const RegionRect& q = rects[r];
    LMB_CHECK(std::isfinite(q.x0) && std::isfinite(q.x1) && std::isfinite(q.y0) && std::isfinite(q.y1),
              where << ": region " << r << " has a non-finite corner");
    LMB_CHECK(q.x1 > q.x0 && q.y1 > q.y0, where << ": region " << r << " is empty ([" << q.x0 << ", " << q.x1 << ") x ["
                                                << q.y0 << ", " << q.y1 << "))");
  }
}

}  // namespace

ContextRegions::ContextRegions(const ContextRegionOptions& options) : options_(options) {
  options_.check();
  Rng rng(counter_hash(options_.seed, 0x5245474E /* "REGN" */));
  const double log_min_area = std::log(options_.min_area);
  const double log_max_area = std::log(options_.max_area);
  const double log_aspect = std::log(options_.max_aspect);
  rects_.reserve(static_cast<size_t>(options_.num_regions));
  for (int32_t r = 0; r < options_.num_regions; ++r) {
    const double area = std::exp(rng.uniform(log_min_area, log_max_area));
    const double aspect = std::exp(rng.uniform(-log_aspect, log_aspect));
    const double distance = rng.uniform(0.0, options_.max_offset);
    const double angle = rng.uniform(0.0, 2.0 * M_PI);
    const double width = std::sqrt(area * aspect);
    const double height = std::sqrt(area / aspect);
    const double cx = distance * std::cos(angle);
    const double cy = distance * std::sin(angle);
    RegionRect rect;
    rect.x0 = snap(cx - 0.5 * width);
    rect.x1 = snap(cx + 0.5 * width);
    rect.y0 = snap(cy - 0.5 * height);
    rect.y1 = snap(cy + 0.5 * height);
    // Keep every rectangle non-empty after snapping (only matters for tiny min_area).
    if (!(rect.x1 > rect.x0)) rect.x1 = rect.x0 + static_cast<float>(kRegionGrid);
    if (!(rect.y1 > rect.y0)) rect.y1 = rect.y0 + static_cast<float>(kRegionGrid);
    rects_.push_back(rect);
  }
}

ContextRegions::ContextRegions(std::vector<RegionRect> rects, ContextRegionOptions options)
    : options_(options), rects_(std::move(rects)) {
  options_.num_regions = static_cast<int32_t>(rects_.size());
  validate("context regions");
}

void ContextRegions::validate(const std::string& where) const { validate_rects(rects_, where); }

bool ContextRegions::operator==(const ContextRegions& other) const {
  return rects_.size() == other.rects_.size() &&
         (rects_.empty() || std::memcmp(rects_.data(), other.rects_.data(), rects_.size() * sizeof(RegionRect)) == 0);
}

void write_context_regions(cereal::PortableBinaryOutputArchive& ar, const ContextRegions& regions) {
  const ContextRegionOptions& o = regions.options();
  ar(o.num_regions, o.seed, o.min_area, o.max_area, o.max_aspect, o.max_offset);
  ar(static_cast<uint64_t>(regions.size()));
  for (const RegionRect& r : regions.rects()) ar(r.x0, r.y0, r.x1, r.y1);
}

ContextRegions read_context_regions(BoundedReader& reader) {
  ContextRegionOptions o;
  reader.value(o.num_regions);
  reader.value(o.seed);
  reader.value(o.min_area);
  reader.value(o.max_area);
  reader.value(o.max_aspect);
  reader.value(o.max_offset);
  const uint64_t n = reader.count(4 * sizeof(float), "regions");
  LMB_CHECK(n >= 1 && n <= static_cast<uint64_t>(kMaxContextRegions),
            reader.what() << ": regions: count " << n << " outside 1.." << kMaxContextRegions);
  std::vector<RegionRect> rects(n);
  for (RegionRect& q : rects) {
    reader.value(q.x0);
    reader.value(q.y0);
    reader.value(q.x1);
    reader.value(q.y1);
  }
  // Validated here first, so that the error names the file (the constructor's would not).
  validate_rects(rects, reader.what() + ": regions");
  return ContextRegions(std::move(rects), o);
}

}  // namespace lmb
