#include "common/context_embedding.h"

#include <algorithm>
#include <cmath>

#include <gtest/gtest.h>

#include "common/error.h"
#include "common/hamming.h"
#include "common/random.h"

namespace lmb {
namespace {

constexpr int kWords = 8;

// A random frame whose coordinates are multiples of 1/64 in [-1, 1) and whose scales are powers of
// two (1/32 .. 1/4): with region corners on the 1/1024 grid, every region bound is exact in float
// and many keypoints sit exactly on region borders (the half-open convention is exercised).
struct RawFrame {
  std::vector<Eigen::Vector2d> positions;
  std::vector<double> scales;
  std::vector<uint8_t> words;
};

RawFrame dyadic_frame(int n, uint64_t seed, int num_words = kWords) {
  Rng rng(seed);
  RawFrame f;
  for (int i = 0; i < n; ++i) {
    const double x = (static_cast<double>(rng.below(128)) - 64.0) / 64.0;
    const double y = (static_cast<double>(rng.below(128)) - 64.0) / 64.0;
    f.positions.emplace_back(x, y);
    f.scales.push_back(std::ldexp(1.0, -2 - static_cast<int>(rng.below(4))));
    f.words.push_back(static_cast<uint8_t>(rng.below(num_words)));
  }
  return f;
}

FrameKeypoints align(const RawFrame& f, const Eigen::Vector2d& g = Eigen::Vector2d(0, 1)) {
  return align_frame_keypoints(f.positions, f.scales, f.words, g, "test frame");
}

ContextRegions test_regions(int num = 200, uint64_t seed = 3) {
  ContextRegionOptions o;
  o.num_regions = num;
  o.seed = seed;
  o.max_area = 256;
  o.max_offset = 12;
  // Random regions plus hand-made ones with a border through the anchor itself (both sides of
  // the half-open convention) and one far away.
  std::vector<RegionRect> rects = ContextRegions(o).rects();
  rects.push_back({-1.f, -1.f, 0.f, 1.f});
  rects.push_back({0.f, -1.f, 1.f, 1.f});
  rects.push_back({-1.f, 0.f, 1.f, 1.f});
  rects.push_back({-1.f, -1.f, 1.f, 0.f});
  rects.push_back({-0.5f, -0.5f, 0.5f, 0.5f});
  rects.push_back({30.f, 30.f, 31.f, 40.f});
  return ContextRegions(rects, o);
}

std::vector<uint8_t> embed_all(const FrameContext& ctx) {
  const int32_t dims = ctx.regions().size() * ctx.num_words();
  std::vector<uint8_t> out(static_cast<size_t>(ctx.num_keypoints()) * dims);
  for (int32_t k = 0; k < ctx.num_keypoints(); ++k) ctx.embed_context(k, out.data() + k * dims);
  return out;
}

TEST(ContextBin, KnownValues) {
  EXPECT_EQ(context_bin(0, 0), 0);
  EXPECT_EQ(context_bin(0, 5), 0);
  EXPECT_EQ(context_bin(3, 3), 255);
  EXPECT_EQ(context_bin(1, 2), 128);  // 127.5 rounds half up
  EXPECT_EQ(context_bin(1, 3), 85);
  EXPECT_EQ(context_bin(2, 3), 170);
  EXPECT_EQ(context_bin(1, 1000), 0);  // 0.255 rounds to 0
  EXPECT_EQ(context_bin(2, 1000), 1);
}

// The division-free bin: every count of every total up to 4096, and for larger totals (up to the
// frame limit, where the proof's margin is smallest) the counts near 0, the half and the total,
// and random ones.
TEST(ContextBin, FastDivisionEqualsContextBin) {
  for (int32_t total = 0; total <= 4096; ++total) {
    const uint64_t magic = context_bin_magic(total);
    for (int32_t count = 0; count <= total; ++count) {
      ASSERT_EQ(context_bin_fast(count, total, magic), context_bin(count, total)) << count << " / " << total;
    }
  }
  Rng rng(9);
  for (int32_t total = 4097; total <= 65535; ++total) {
    const uint64_t magic = context_bin_magic(total);
    for (int32_t count : {0, 1, total / 255, total / 2 - 1, total / 2, total / 2 + 1, total - 1, total,
                          static_cast<int32_t>(rng.below(static_cast<uint64_t>(total) + 1))}) {
      ASSERT_EQ(context_bin_fast(count, total, magic), context_bin(count, total)) << count << " / " << total;
    }
  }
}

TEST(EmbeddingLayout, DimensionMapping) {
  const EmbeddingLayout l{1000, 16, 64};
  EXPECT_EQ(l.num_context_dims(), 16000);
  EXPECT_EQ(l.num_dims(), 16512);
  EXPECT_TRUE(l.is_context(15999));
  EXPECT_FALSE(l.is_context(16000));
  EXPECT_EQ(l.region_of(35), 2);
  EXPECT_EQ(l.word_of(35), 3);
  EXPECT_EQ(l.bit_of(16007), 7);
  EXPECT_NO_THROW(l.check());
  EXPECT_THROW((EmbeddingLayout{0, 16, 64}.check()), Error);
  EXPECT_THROW((EmbeddingLayout{10, 0, 64}.check()), Error);
}

TEST(FrameContext, FastEqualsBruteForceOnEveryDimension) {
  const ContextRegions regions = test_regions();
  FrameContext ctx(regions, kWords);
  std::vector<uint8_t> reference(static_cast<size_t>(regions.size()) * kWords);
  int64_t nonzero = 0, checked = 0;
  for (int n : {0, 1, 2, 3, 17, 150, 600}) {
    for (uint64_t seed = 1; seed <= 3; ++seed) {
      const FrameKeypoints frame = align(dyadic_frame(n, seed * 100 + n));
      ctx.reset(frame);
      ASSERT_EQ(ctx.num_keypoints(), n);
      const std::vector<uint8_t> fast = embed_all(ctx);
      for (int k = 0; k < n; ++k) {
        embed_context_brute_force(regions, kWords, frame, k, reference.data());
        for (size_t d = 0; d < reference.size(); ++d) {
          ASSERT_EQ(fast[k * reference.size() + d], reference[d]) << "n " << n << " keypoint " << k << " dim " << d;
          nonzero += reference[d] != 0;
          ++checked;
        }
      }
    }
  }
  // The comparison is not vacuous: a good share of the bins is non-zero.
  EXPECT_GT(nonzero, checked / 20);
}

TEST(FrameContext, FastEqualsBruteForceOnGeneralFloatFrames) {
  // Non-dyadic positions and scales, with duplicated positions (coincident keypoints count, the
  // anchor does not).
  const ContextRegions regions = test_regions(150, 9);
  Rng rng(77);
  RawFrame f;
  for (int i = 0; i < 400; ++i) {
    if (i > 0 && rng.uniform() < 0.1) {
      f.positions.push_back(f.positions[rng.below(i)]);
    } else {
      f.positions.emplace_back(rng.uniform(-0.8, 0.8), rng.uniform(-0.6, 0.6));
    }
    f.scales.push_back(std::exp(rng.uniform(std::log(0.01), std::log(0.2))));
    f.words.push_back(static_cast<uint8_t>(rng.below(kWords)));
  }
  const double angle = 0.7;
  const FrameKeypoints frame = align(f, Eigen::Vector2d(std::sin(angle), std::cos(angle)));
  FrameContext ctx(regions, kWords);
  ctx.reset(frame);
  std::vector<int32_t> fast(kWords), slow(kWords);
  for (int k = 0; k < frame.size(); ++k) {
    for (int r = 0; r < regions.size(); ++r) {
      const int32_t tf = ctx.region_counts(k, r, fast.data());
      const int32_t ts = region_counts_brute_force(regions, kWords, frame, k, r, slow.data());
      ASSERT_EQ(tf, ts) << k << " " << r;
      ASSERT_EQ(fast, slow) << k << " " << r;
    }
  }
}

// Brute-force value of one feature dimension.
uint8_t reference_dim(const ContextRegions& regions, const FrameKeypoints& frame, int k, int32_t d,
                      const uint8_t* descriptor) {
  const int32_t context_dims = regions.size() * kWords;
  if (d >= context_dims) return static_cast<uint8_t>(descriptor_bit(descriptor, d - context_dims));
  std::vector<int32_t> counts(kWords);
  const int32_t total = region_counts_brute_force(regions, kWords, frame, k, d / kWords, counts.data());
  return context_bin(counts[d % kWords], total);
}

// compute_dims_columns equals the plan's rows (rows: n x plan.size(), from compute_dims_all) for
// every keypoint in a shuffled order and for a subset in reverse order, with a stride above the
// count (the padding bytes stay untouched).
void expect_columns_equal_rows(const FrameContext& ctx, const DimPlan& plan, const uint8_t* descriptors,
                               const std::vector<uint8_t>& rows, int n, Rng& rng) {
  std::vector<int32_t> shuffled(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) shuffled[i] = i;
  rng.shuffle(shuffled);
  std::vector<int32_t> subset;
  for (int i = n - 1; i >= 0; i -= 3) subset.push_back(i);
  for (const std::vector<int32_t>& ids : {shuffled, subset}) {
    const int count = static_cast<int>(ids.size());
    const size_t stride = static_cast<size_t>(count) + 5;
    std::vector<uint8_t> columns(static_cast<size_t>(plan.size()) * stride, 0xEE);
    ctx.compute_dims_columns(plan, ids.data(), count, descriptors, columns.data(), stride);
    for (int32_t u = 0; u < plan.size(); ++u) {
      for (int i = 0; i < count; ++i) {
        ASSERT_EQ(columns[u * stride + i], rows[static_cast<size_t>(ids[i]) * plan.size() + u])
            << "n " << n << " keypoint " << ids[i] << " plan dim " << plan.dims()[u];
      }
      for (size_t i = count; i < stride; ++i) ASSERT_EQ(columns[u * stride + i], 0xEE);
    }
  }
}

TEST(FrameContext, ComputeDimsEqualsBruteForceWithAndWithoutAPlan) {
  const ContextRegions regions = test_regions(300, 5);
  const int bytes = 32;
  const int32_t num_dims = regions.size() * kWords + 8 * bytes;
  Rng rng(4);
  for (int n : {1, 40, 500, 2100}) {
    const FrameKeypoints frame = align(dyadic_frame(n, 1000 + n));
    std::vector<uint8_t> descriptors(static_cast<size_t>(n) * bytes);
    for (auto& b : descriptors) b = static_cast<uint8_t>(rng.below(256));
    for (int density : {3, 40, 400}) {
      // A sorted random subset of all dimensions, context and descriptor bits.
      std::vector<int32_t> dims;
      for (int32_t d = 0; d < num_dims; ++d) {
        if (rng.below(1000) < static_cast<uint64_t>(density)) dims.push_back(d);
      }
      {
        FrameContext ctx(regions, kWords);
        ctx.reset(frame);
        std::vector<uint8_t> all(static_cast<size_t>(n) * dims.size());
        ctx.compute_dims_all(dims.data(), static_cast<int32_t>(dims.size()), descriptors.data(), bytes, all.data());
        // The prepared plan gives the same bytes.
        const DimPlan plan(regions, EmbeddingLayout{regions.size(), kWords, bytes}, dims);
        std::vector<uint8_t> planned(all.size(), 0xEE);
        ctx.compute_dims_all(plan, descriptors.data(), planned.data());
        ASSERT_EQ(planned, all) << "n " << n << " density " << density;
        expect_columns_equal_rows(ctx, plan, descriptors.data(), planned, n, rng);
        const int step = n > 100 ? 37 : 1;  // brute force on a subset of large frames
        for (int k = 0; k < n; k += step) {
          for (size_t i = 0; i < dims.size(); ++i) {
            ASSERT_EQ(all[k * dims.size() + i],
                      reference_dim(regions, frame, k, dims[i], descriptors.data() + k * bytes))
                << "n " << n << " k " << k << " dim " << dims[i];
          }
        }
      }
    }
  }
}

// Frames whose coordinates defeat the rank grid: every keypoint on one vertical line (a zero
// x range: a single grid cell), clusters of identical positions (cells holding many keypoints:
// the binary-search fallback), one keypoint, and a frame with one keypoint far from the others
// (nearly all keypoints in one cell). The plan path equals the brute force on every dim.
TEST(FrameContext, PlanPathOnDegenerateAndCrowdedFramesEqualsBruteForce) {
  const ContextRegions regions = test_regions(150, 8);
  const int bytes = 4;
  const int32_t context_dims = regions.size() * kWords;
  std::vector<int32_t> dims;
  for (int32_t d = 0; d < context_dims; d += 3) dims.push_back(d);
  const DimPlan plan(regions, EmbeddingLayout{regions.size(), kWords, bytes}, dims);
  Rng rng(12);
  std::vector<RawFrame> frames(4);
  for (int i = 0; i < 300; ++i) {  // one vertical line
    frames[0].positions.emplace_back(0.25, (static_cast<double>(rng.below(64)) - 32.0) / 64.0);
  }
  for (int i = 0; i < 400; ++i) {  // 5 clusters of identical positions
    const double c = static_cast<double>(rng.below(5)) / 8.0;
    frames[1].positions.emplace_back(c, -c);
  }
  frames[2].positions.emplace_back(0.5, 0.5);
  for (int i = 0; i < 300; ++i) {
    frames[3].positions.emplace_back(rng.uniform(0.0, 1e-3), rng.uniform(0.0, 1e-3));
  }
  frames[3].positions.emplace_back(1e4, -1e4);
  for (RawFrame& f : frames) {
    for (size_t i = 0; i < f.positions.size(); ++i) {
      f.scales.push_back(std::ldexp(1.0, -2 - static_cast<int>(rng.below(4))));
      f.words.push_back(static_cast<uint8_t>(rng.below(kWords)));
    }
    const FrameKeypoints frame = align(f);
    const int n = frame.size();
    std::vector<uint8_t> descriptors(static_cast<size_t>(n) * bytes, 0x33);
    FrameContext ctx(regions, kWords);
    ctx.reset(frame);
    std::vector<uint8_t> planned(static_cast<size_t>(n) * dims.size());
    ctx.compute_dims_all(plan, descriptors.data(), planned.data());
    expect_columns_equal_rows(ctx, plan, descriptors.data(), planned, n, rng);
    int nonzero = 0;
    for (int k = 0; k<n; k += n> 50 ? 7 : 1) {
      for (size_t i = 0; i < dims.size(); ++i) {
        const uint8_t v = planned[k * dims.size() + i];
        ASSERT_EQ(v, reference_dim(regions, frame, k, dims[i], descriptors.data() + k * bytes))
            << "n " << n << " k " << k << " dim " << dims[i];
        nonzero += v > 0;
      }
    }
    if (n > 1) {
      EXPECT_GT(nonzero, 0);
    }
  }
}

// Frames above FrameContext::kMaxDominanceKeypoints take count_all from the word tables in the
// DimPlan path: the same bytes as the raw dims path.
TEST(FrameContext, PlanOnFramesBeyondTheDominanceLimitEqualsRawDims) {
  const ContextRegions regions = test_regions(60, 6);
  const int bytes = 8;
  const int n = FrameContext::kMaxDominanceKeypoints + 300;
  const FrameKeypoints frame = align(dyadic_frame(n, 77));
  std::vector<uint8_t> descriptors(static_cast<size_t>(n) * bytes, 0x5A);
  std::vector<int32_t> dims;
  for (int32_t d = 0; d < regions.size() * kWords; d += 7) dims.push_back(d);
  FrameContext ctx(regions, kWords);
  ctx.reset(frame);
  std::vector<uint8_t> all(static_cast<size_t>(n) * dims.size());
  ctx.compute_dims_all(dims.data(), static_cast<int32_t>(dims.size()), descriptors.data(), bytes, all.data());
  const DimPlan plan(regions, EmbeddingLayout{regions.size(), kWords, bytes}, dims);
  std::vector<uint8_t> planned(all.size(), 0xEE);
  ctx.compute_dims_all(plan, descriptors.data(), planned.data());
  ASSERT_EQ(planned, all);
  Rng rng(78);
  expect_columns_equal_rows(ctx, plan, descriptors.data(), planned, n, rng);
  int nonzero = 0;
  for (uint8_t v : all) nonzero += v > 0;
  EXPECT_GT(nonzero, 1000);
}

// Invariance under exact (dyadic) similarity transforms applied to positions, scales and gravity.
TEST(FrameContext, EmbeddingIsExactlyInvariantUnderTranslationScalingAndRotationWithGravity) {
  const ContextRegions regions = test_regions();
  FrameContext ctx(regions, kWords);
  const RawFrame base = dyadic_frame(300, 21);
  ctx.reset(align(base));
  const std::vector<uint8_t> expected = embed_all(ctx);
  int64_t nonzero = std::count_if(expected.begin(), expected.end(), [](uint8_t v) { return v; });
  ASSERT_GT(nonzero, static_cast<int64_t>(expected.size() / 20));

  struct Transform {
    const char* name;
    double scale;
    int quarter_turns;  // counter-clockwise, in the image (x right, y down)
    Eigen::Vector2d translation;
  };
  const Transform transforms[] = {
      {"translate", 1.0, 0, {0.25, -0.375}},  {"scale x2", 2.0, 0, {0, 0}},       {"scale x0.5", 0.5, 0, {0, 0}},
      {"rotate 90", 1.0, 1, {0, 0}},          {"rotate 180", 1.0, 2, {0, 0}},     {"rotate 270", 1.0, 3, {0, 0}},
      {"all together", 2.0, 1, {-0.5, 0.75}}, {"all, 180", 0.5, 2, {0.125, 0.5}},
  };
  for (const Transform& t : transforms) {
    Eigen::Matrix2d rot = Eigen::Matrix2d::Identity();
    for (int q = 0; q < t.quarter_turns; ++q) rot = Eigen::Matrix2d{{0, -1}, {1, 0}} * rot;
    RawFrame moved = base;
    for (size_t i = 0; i < moved.positions.size(); ++i) {
      moved.positions[i] = t.scale * (rot * base.positions[i]) + t.translation;
      moved.scales[i] = t.scale * base.scales[i];
    }
    // Gravity rotates with the frame; it comes from a 3D vector with an optical-axis component.
    const Eigen::Vector2d g2 = rot * Eigen::Vector2d(0, 0.5);
    const Eigen::Vector3d gravity_in_cam(g2.x(), g2.y(), 0.75);
    bool degenerate = true;
    const Eigen::Vector2d g = gravity_direction_in_image(gravity_in_cam, &degenerate);
    EXPECT_FALSE(degenerate);
    ctx.reset(align(moved, g));
    EXPECT_EQ(embed_all(ctx), expected) << t.name;
  }
}

// For a general rotation angle the rotated coordinates are rounded differently, so a keypoint
// lying within rounding distance of a region border may change sides: each count may differ by at
// most the number of keypoints (of that word) within 1e-5 of the region's border.
TEST(FrameContext, GeneralRotationChangesCountsOnlyByKeypointsOnRegionBorders) {
  const ContextRegions regions = test_regions(100, 8);
  Rng rng(5);
  RawFrame base;
  for (int i = 0; i < 250; ++i) {
    base.positions.emplace_back(rng.uniform(-1, 1), rng.uniform(-1, 1));
    base.scales.push_back(rng.uniform(0.02, 0.1));
    base.words.push_back(static_cast<uint8_t>(rng.below(kWords)));
  }
  const FrameKeypoints a = align(base);
  for (double angle : {0.3, 1.9, -2.5}) {
    const Eigen::Matrix2d rot{{std::cos(angle), -std::sin(angle)}, {std::sin(angle), std::cos(angle)}};
    RawFrame moved = base;
    for (auto& p : moved.positions) p = rot * p + Eigen::Vector2d(0.3, -0.1);
    const FrameKeypoints b = align(moved, rot * Eigen::Vector2d(0, 1));
    FrameContext ctx_a(regions, kWords), ctx_b(regions, kWords);
    ctx_a.reset(a);
    ctx_b.reset(b);
    std::vector<int32_t> ca(kWords), cb(kWords);
    int64_t equal = 0, pairs = 0;
    for (int k = 0; k < a.size(); ++k) {
      for (int r = 0; r < regions.size(); ++r) {
        const int32_t ta = ctx_a.region_counts(k, r, ca.data());
        const int32_t tb = ctx_b.region_counts(k, r, cb.data());
        // Keypoints near the border of region r of k, in frame a (double precision).
        const RegionRect& q = regions[r];
        const double s = a.scale[k];
        const double lx = a.x[k] + s * q.x0, hx = a.x[k] + s * q.x1;
        const double ly = a.y[k] + s * q.y0, hy = a.y[k] + s * q.y1;
        const double eps = 1e-5;
        std::vector<int32_t> near(kWords, 0);
        int32_t near_all = 0;
        for (int j = 0; j < a.size(); ++j) {
          if (j == k) continue;
          const double x = a.x[j], y = a.y[j];
          const bool in_x = x > lx - eps && x<hx + eps, in_y = y> ly - eps && y < hy + eps;
          const bool on_x = std::abs(x - lx) < eps || std::abs(x - hx) < eps;
          const bool on_y = std::abs(y - ly) < eps || std::abs(y - hy) < eps;
          if ((on_x && in_y) || (on_y && in_x)) ++near[a.word[j]], ++near_all;
        }
        ASSERT_LE(std::abs(ta - tb), near_all) << k << " " << r;
        for (int w = 0; w < kWords; ++w) ASSERT_LE(std::abs(ca[w] - cb[w]), near[w]);
        equal += ca == cb && ta > 0;
        ++pairs;
      }
    }
    EXPECT_GT(equal, pairs / 4);  // not vacuous: most non-empty regions match exactly
  }
}

TEST(Geometry, NormalizeKeypointPinholeKnownAnswer) {
  Camera cam;
  cam.model = CameraModel::kPinhole;
  cam.width = 640;
  cam.height = 480;
  cam.params = {500, 400, 320, 240};
  Eigen::Vector2d p;
  double s = 0;
  normalize_keypoint(cam, Keypoint{100.f, 40.f, 20.f, -1.f}, &p, &s);
  EXPECT_NEAR(p.x(), (100.0 - 320.0) / 500.0, 1e-12);
  EXPECT_NEAR(p.y(), (40.0 - 240.0) / 400.0, 1e-12);
  EXPECT_NEAR(s, 20.0 / 500.0, 1e-12);  // measured along x
  EXPECT_THROW(normalize_keypoint(cam, Keypoint{1, 1, 0.f, -1}, &p, &s), Error);
  EXPECT_THROW(normalize_keypoint(cam, Keypoint{1, 1, -3.f, -1}, &p, &s), Error);
  EXPECT_THROW(normalize_keypoint(cam, Keypoint{1, 1, NAN, -1}, &p, &s), Error);
  EXPECT_THROW(normalize_keypoint(cam, Keypoint{NAN, 1, 3.f, -1}, &p, &s), Error);
}

TEST(Geometry, NormalizeKeypointWithDistortionUndistorts) {
  Camera cam;
  cam.model = CameraModel::kOpenCV;
  cam.width = 640;
  cam.height = 480;
  cam.params = {500, 500, 320, 240, -0.2, 0.05, 0.001, -0.001};
  const Eigen::Vector2d truth(0.3, -0.2);
  const Eigen::Vector2d pixel = cam.img_from_cam(truth);
  Eigen::Vector2d p;
  double s = 0;
  normalize_keypoint(cam, Keypoint{static_cast<float>(pixel.x()), static_cast<float>(pixel.y()), 10.f, -1}, &p, &s);
  EXPECT_NEAR(p.x(), truth.x(), 1e-5);
  EXPECT_NEAR(p.y(), truth.y(), 1e-5);
  EXPECT_GT(s, 0.0);
  EXPECT_NEAR(s, 10.0 / 500.0, 0.2 * 10.0 / 500.0);  // barrel distortion stretches it a little
}

TEST(Geometry, GravityDirectionAndDegenerateFallback) {
  bool degenerate = true;
  Eigen::Vector2d g = gravity_direction_in_image(Eigen::Vector3d(0, 1, 0), &degenerate);
  EXPECT_FALSE(degenerate);
  EXPECT_EQ(g, Eigen::Vector2d(0, 1));
  g = gravity_direction_in_image(Eigen::Vector3d(3, 4, 100), &degenerate);
  EXPECT_FALSE(degenerate);
  EXPECT_NEAR(g.x(), 0.6, 1e-15);
  EXPECT_NEAR(g.y(), 0.8, 1e-15);
  // Parallel to the optical axis (camera looking straight down or up): image +y, flagged.
  for (const Eigen::Vector3d& v :
       {Eigen::Vector3d(0, 0, 1), Eigen::Vector3d(0, 0, -1), Eigen::Vector3d(1e-5, -1e-5, 1)}) {
    g = gravity_direction_in_image(v, &degenerate);
    EXPECT_TRUE(degenerate);
    EXPECT_EQ(g, Eigen::Vector2d(0, 1));
  }
  EXPECT_THROW(gravity_direction_in_image(Eigen::Vector3d::Zero()), Error);
  EXPECT_THROW(gravity_direction_in_image(Eigen::Vector3d(NAN, 1, 0)), Error);
  EXPECT_THROW(gravity_direction_in_image(Eigen::Vector3d(INFINITY, 1, 0)), Error);
}

TEST(Geometry, FrameFromDetectionsRotatesByGravity) {
  Camera cam;
  cam.model = CameraModel::kSimplePinhole;
  cam.width = 640;
  cam.height = 480;
  cam.params = {512, 320, 240};
  // Gravity pointing to image +x (camera rolled by 90 degrees): p' = (-p_y, p_x).
  const Keypoint kps[2] = {{320.f + 64.f, 240.f, 8.f, -1}, {320.f, 240.f + 128.f, 16.f, -1}};
  const uint8_t words[2] = {0, 1};
  const FrameKeypoints f = frame_keypoints_from_detections(cam, kps, words, 2, Eigen::Vector3d(1, 0, 0), "frame 3");
  EXPECT_FLOAT_EQ(f.x[0], 0.f);
  EXPECT_FLOAT_EQ(f.y[0], 0.125f);
  EXPECT_FLOAT_EQ(f.x[1], -0.25f);
  EXPECT_FLOAT_EQ(f.y[1], 0.f);
  EXPECT_FLOAT_EQ(f.scale[0], 8.f / 512.f);
  EXPECT_FLOAT_EQ(f.scale[1], 16.f / 512.f);
  const Keypoint bad[1] = {{10, 10, 0.f, -1}};
  try {
    frame_keypoints_from_detections(cam, bad, words, 1, Eigen::Vector3d(0, 1, 0), "frame 3");
    FAIL() << "no error for a zero keypoint scale";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("frame 3"), std::string::npos) << e.what();
  }
  EXPECT_THROW(frame_keypoints_from_detections(cam, kps, words, 2, Eigen::Vector3d(0, 0, 0), "f"), Error);
}

TEST(DimPlan, RejectsUnsortedOrOutOfRangeDimsAndForeignLayouts) {
  const ContextRegions regions = test_regions(20);
  const EmbeddingLayout layout{regions.size(), kWords, 4};
  EXPECT_THROW(DimPlan(regions, layout, {3, 2}), Error);
  EXPECT_THROW(DimPlan(regions, layout, {3, 3}), Error);
  EXPECT_THROW(DimPlan(regions, layout, {-1}), Error);
  EXPECT_THROW(DimPlan(regions, layout, {layout.num_dims()}), Error);
  EXPECT_THROW(DimPlan(regions, EmbeddingLayout{regions.size() + 1, kWords, 4}, {1}), Error);
  const DimPlan plan(regions, layout, {0, 1, 9, 17, layout.num_context_dims() + 3});
  EXPECT_EQ(plan.num_used_regions(), 3);
  FrameContext other(regions, kWords + 1);
  other.reset(align(dyadic_frame(5, 1, kWords)));
  std::vector<uint8_t> out(5 * plan.size()), desc(5 * 4, 0);
  EXPECT_THROW(other.compute_dims_all(plan, desc.data(), out.data()), Error);
}

TEST(FrameContext, BadFramesThrowAndEmptyRegionsGiveZeroNotNaN) {
  const ContextRegions regions = test_regions(50);
  FrameContext ctx(regions, kWords);
  RawFrame f = dyadic_frame(10, 1);
  f.scales[3] = 0;
  EXPECT_THROW(align(f), Error);
  f.scales[3] = -0.1;
  EXPECT_THROW(align(f), Error);
  f.scales[3] = NAN;
  EXPECT_THROW(align(f), Error);
  f.scales[3] = 0.25;
  f.positions[2].x() = NAN;
  EXPECT_THROW(align(f), Error);
  f.positions[2].x() = 0;
  EXPECT_THROW(align(f, Eigen::Vector2d(0, 2)), Error);  // not a unit direction

  FrameKeypoints frame = align(f);
  frame.scale[4] = 0.f;
  EXPECT_THROW(ctx.reset(frame), Error);
  frame.scale[4] = NAN;
  EXPECT_THROW(ctx.reset(frame), Error);
  frame.scale[4] = 0.25f;
  frame.word[5] = kWords;
  EXPECT_THROW(ctx.reset(frame), Error);
  frame.word[5] = 0;
  frame.y.pop_back();
  EXPECT_THROW(ctx.reset(frame), Error);

  // Empty frame: valid, nothing to query.
  EXPECT_NO_THROW(ctx.reset(FrameKeypoints{}));
  EXPECT_EQ(ctx.num_keypoints(), 0);
  // A lone keypoint: every region is empty (the anchor does not count) -> all bins 0.
  const FrameKeypoints one = align(dyadic_frame(1, 2));
  ctx.reset(one);
  std::vector<uint8_t> out(static_cast<size_t>(regions.size()) * kWords, 7);
  ctx.embed_context(0, out.data());
  EXPECT_TRUE(std::all_of(out.begin(), out.end(), [](uint8_t v) { return v == 0; }));
  // Bins of a non-empty region sum to about 255 (each rounded by at most 1/2).
  ctx.reset(align(dyadic_frame(200, 3)));
  ctx.embed_context(0, out.data());
  for (int r = 0; r < regions.size(); ++r) {
    int sum = 0;
    for (int w = 0; w < kWords; ++w) sum += out[r * kWords + w];
    EXPECT_TRUE(sum == 0 || std::abs(sum - 255) <= kWords / 2) << sum;
  }
}

}  // namespace
}  // namespace lmb
