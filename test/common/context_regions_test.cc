#include "common/context_regions.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <sstream>

#include <gtest/gtest.h>
#include <cereal/archives/portable_binary.hpp>

#include "common/bounded_reader.h"
#include "common/error.h"

namespace lmb {
namespace {

// Kolmogorov-Smirnov statistic of samples against the uniform distribution on [lo, hi].
double ks_uniform(std::vector<double> v, double lo, double hi) {
  std::sort(v.begin(), v.end());
  const double n = static_cast<double>(v.size());
  double d = 0;
  for (size_t i = 0; i < v.size(); ++i) {
    const double f = std::clamp((v[i] - lo) / (hi - lo), 0.0, 1.0);
    d = std::max({d, f - i / n, (i + 1) / n - f});
  }
  return d;
}

// KS critical value at significance 0.001 for large n: 1.9495 / sqrt(n).
double ks_critical_001(size_t n) { return 1.9495 / std::sqrt(static_cast<double>(n)); }

ContextRegionOptions many_regions() {
  ContextRegionOptions o;
  o.num_regions = 20000;
  o.seed = 11;
  return o;
}

TEST(ContextRegions, AreaFollowsOneOverAreaKolmogorovSmirnovAtSignificance0001) {
  // Pr(area) ~ 1/area on [min, max]  <=>  log(area) uniform on [log min, log max].
  const ContextRegionOptions o = many_regions();
  const ContextRegions regions(o);
  ASSERT_EQ(regions.size(), o.num_regions);
  std::vector<double> log_area, area;
  for (const RegionRect& r : regions.rects()) {
    log_area.push_back(std::log(r.area()));
    area.push_back(r.area());
  }
  const double d = ks_uniform(log_area, std::log(o.min_area), std::log(o.max_area));
  EXPECT_LT(d, ks_critical_001(log_area.size())) << "log-area is not uniform";
  // The test has power: the same areas are far from uniform in area itself.
  EXPECT_GT(ks_uniform(area, o.min_area, o.max_area), 10 * ks_critical_001(area.size()));
}

TEST(ContextRegions, AreaChiSquareOverLogBinsAtSignificance0001) {
  const ContextRegionOptions o = many_regions();
  const ContextRegions regions(o);
  const int bins = 20;
  std::vector<int> counts(bins, 0);
  const double lo = std::log(o.min_area), hi = std::log(o.max_area);
  for (const RegionRect& r : regions.rects()) {
    const int b = std::clamp(static_cast<int>((std::log(r.area()) - lo) / (hi - lo) * bins), 0, bins - 1);
    ++counts[b];
  }
  const double expected = static_cast<double>(o.num_regions) / bins;
  double chi2 = 0;
  for (int c : counts) chi2 += (c - expected) * (c - expected) / expected;
  EXPECT_LT(chi2, 43.82);  // chi-square, 19 degrees of freedom, 0.001 critical value
}

TEST(ContextRegions, AspectIsLogUniformAndCentresReachNearAndFar) {
  const ContextRegionOptions o = many_regions();
  const ContextRegions regions(o);
  std::vector<double> log_aspect;
  int contains_keypoint = 0, far = 0;
  for (const RegionRect& r : regions.rects()) {
    log_aspect.push_back(std::log((double(r.x1) - r.x0) / (double(r.y1) - r.y0)));
    const double cx = 0.5 * (double(r.x0) + r.x1), cy = 0.5 * (double(r.y0) + r.y1);
    const double dist = std::hypot(cx, cy);
    EXPECT_LE(dist, o.max_offset + 0.01);
    contains_keypoint += r.x0 <= 0 && 0 < r.x1 && r.y0 <= 0 && 0 < r.y1;
    far += dist > 0.75 * o.max_offset;
  }
  EXPECT_LT(ks_uniform(log_aspect, -std::log(o.max_aspect), std::log(o.max_aspect)),
            ks_critical_001(log_aspect.size()));
  // Centre distance uniform on [0, max_offset]: a quarter lies beyond 0.75 max_offset.
  EXPECT_NEAR(far / double(o.num_regions), 0.25, 0.02);
  EXPECT_GT(contains_keypoint, o.num_regions / 20);
}

TEST(ContextRegions, CornersAreOnTheGridAndRectanglesNonEmpty) {
  const ContextRegions regions(many_regions());
  for (const RegionRect& r : regions.rects()) {
    for (float c : {r.x0, r.x1, r.y0, r.y1}) {
      const double scaled = double(c) / kRegionGrid;
      EXPECT_EQ(scaled, std::round(scaled));
    }
    EXPECT_GT(r.x1, r.x0);
    EXPECT_GT(r.y1, r.y0);
  }
}

TEST(ContextRegions, SameSeedSameSetOtherSeedOtherSet) {
  ContextRegionOptions o;
  const ContextRegions a(o), b(o);
  EXPECT_TRUE(a == b);
  o.seed = 2;
  EXPECT_FALSE(a == ContextRegions(o));
}

std::string serialized(const ContextRegions& regions) {
  std::ostringstream os(std::ios::binary);
  {
    cereal::PortableBinaryOutputArchive ar(os);
    write_context_regions(ar, regions);
  }
  return os.str();
}

ContextRegions parsed(const std::string& bytes, const std::string& what) {
  BoundedReader r(bytes, what);
  ContextRegions out = read_context_regions(r);
  r.expect_end();
  return out;
}

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(ContextRegions, SerializerRoundTripAndBoundedCount) {
  const ContextRegions a{ContextRegionOptions{}};
  const std::string bytes = serialized(a);
  const ContextRegions b = parsed(bytes, "x.lbm");
  EXPECT_TRUE(a == b);
  EXPECT_EQ(b.options().seed, a.options().seed);
  EXPECT_EQ(b.options().max_offset, a.options().max_offset);
  EXPECT_EQ(serialized(b), bytes);

  // A corrupted count is rejected before anything is allocated from it. The uint64 count follows
  // the endianness byte, int32 num_regions, uint64 seed and four doubles.
  std::string bad = bytes;
  const size_t count_offset = 1 + 4 + 8 + 4 * 8;
  const uint64_t huge = uint64_t{1} << 60;
  bad.replace(count_offset, 8, reinterpret_cast<const char*>(&huge), 8);
  EXPECT_NE(error_of([&] { parsed(bad, "x.lbm"); }).find("x.lbm: regions: corrupt count 1152921504606846976"),
            std::string::npos);
  // An empty rectangle: the error names the source, not only "context regions".
  std::string empty = bytes;
  const float x0 = 0.f;
  empty.replace(count_offset + 8 + 8, 4, reinterpret_cast<const char*>(&x0), 4);  // x1 of region 0
  empty.replace(count_offset + 8, 4, reinterpret_cast<const char*>(&x0), 4);      // x0 of region 0
  EXPECT_EQ(error_of([&] { parsed(empty, "x.lbm"); }).rfind("x.lbm: regions: region 0 is empty", 0), 0u)
      << error_of([&] { parsed(empty, "x.lbm"); });
}

TEST(ContextRegions, BadOptionsAndRectanglesThrow) {
  auto with = [](auto set) {
    ContextRegionOptions o;
    set(o);
    return o;
  };
  EXPECT_THROW(with([](auto& o) { o.num_regions = 0; }).check(), Error);
  EXPECT_THROW(with([](auto& o) { o.min_area = 0; }).check(), Error);
  EXPECT_THROW(with([](auto& o) { o.min_area = NAN; }).check(), Error);
  EXPECT_THROW(with([](auto& o) { o.max_area = 0.5; }).check(), Error);
  EXPECT_THROW(with([](auto& o) { o.max_aspect = 0.5; }).check(), Error);
  EXPECT_THROW(with([](auto& o) { o.max_offset = -1; }).check(), Error);
  EXPECT_NO_THROW(ContextRegionOptions{}.check());
  EXPECT_THROW(ContextRegions(std::vector<RegionRect>{}), Error);
  EXPECT_THROW(ContextRegions(std::vector<RegionRect>{{0.f, 0.f, 0.f, 1.f}}), Error);
  EXPECT_THROW(ContextRegions(std::vector<RegionRect>{{0.f, 0.f, NAN, 1.f}}), Error);
  EXPECT_NO_THROW(ContextRegions(std::vector<RegionRect>{{0.f, 0.f, 1.f, 1.f}}));
}

}  // namespace
}  // namespace lmb
