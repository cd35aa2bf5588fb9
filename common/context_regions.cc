#include "common/context_regions.h"

#include <cmath>
#include <cstring>

#include "common/error.h"
#include "common/random.h"

namespace lmb {

void ContextRegionOptions::check() const {
  LMB_CHECK(num_regions >= 1 && num_regions <= kMaxContextRegions,
            "context regions: num_regions = " << num_regions << " must be in 1.."
                                              << kMaxContextRegions);
  LMB_CHECK(std::isfinite(min_area) && min_area > 0.0,
            "context regions: min_area = " << min_area << " must be finite and > 0");
  LMB_CHECK(std::isfinite(max_area) && max_area >= min_area,
            "context regions: max_area = " << max_area << " must be finite and >= min_area ("
                                           << min_area << ")");
  LMB_CHECK(max_area <= 1e8, "context regions: max_area = " << max_area << " exceeds 1e8");
  LMB_CHECK(std::isfinite(max_aspect) && max_aspect >= 1.0 && max_aspect <= 1e3,
            "context regions: max_aspect = " << max_aspect << " must be in [1, 1000]");
  LMB_CHECK(std::isfinite(max_offset) && max_offset >= 0.0 && max_offset <= 1e4,
            "context regions: max_offset = " << max_offset << " must be in [0, 1e4]");
}

namespace {

float snap(double v) { return static_cast<float>(std::round(v / kRegionGrid) * kRegionGrid); }

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

void ContextRegions::check_loaded_count(int32_t n) {
  LMB_CHECK(n >= 1 && n <= kMaxContextRegions,
            "context regions: stored region count " << n << " is outside 1.."
                                                    << kMaxContextRegions);
}

void ContextRegions::validate(const std::string& where) const {
  LMB_CHECK(!rects_.empty(), where << ": no regions");
  LMB_CHECK(rects_.size() <= static_cast<size_t>(kMaxContextRegions),
            where << ": " << rects_.size() << " regions exceed " << kMaxContextRegions);
  for (size_t r = 0; r < rects_.size(); ++r) {
    const RegionRect& q = rects_[r];
    LMB_CHECK(std::isfinite(q.x0) && std::isfinite(q.x1) && std::isfinite(q.y0) &&
                  std::isfinite(q.y1),
              where << ": region " << r << " has a non-finite corner");
    LMB_CHECK(q.x1 > q.x0 && q.y1 > q.y0,
              where << ": region " << r << " is empty ([" << q.x0 << ", " << q.x1 << ") x ["
                    << q.y0 << ", " << q.y1 << "))");
  }
}

bool ContextRegions::operator==(const ContextRegions& other) const {
  return rects_.size() == other.rects_.size() &&
         (rects_.empty() ||
          std::memcmp(rects_.data(), other.rects_.data(), rects_.size() * sizeof(RegionRect)) == 0);
}

}  // namespace lmb
