#include "train/features/build_features.h"

#include <algorithm>
#include <cmath>

#include <gtest/gtest.h>

#include "common/error.h"
#include "common/hamming.h"
#include "common/random.h"
#include "test/support/feature_fixtures.h"

namespace lmb {
namespace {

using test::random_vocabulary;
using test::small_regions;

constexpr int kBytes = 16;

// A random map: two cameras (pinhole, OpenCV with distortion), frames with rolled and tilted
// gravity (one degenerate: looking straight down), 0..300 keypoints per frame.
LandmarkMap random_map(uint64_t seed) {
  Rng rng(seed);
  LandmarkMap map;
  map.descriptor_bytes = kBytes;
  Camera pinhole;
  pinhole.model = CameraModel::kPinhole;
  pinhole.width = 640;
  pinhole.height = 480;
  pinhole.params = {500, 510, 320, 240};
  Camera distorted;
  distorted.model = CameraModel::kOpenCV;
  distorted.width = 640;
  distorted.height = 480;
  distorted.params = {450, 450, 330, 235, -0.1, 0.01, 0.0005, -0.0005};
  map.cameras = {pinhole, distorted};
  const int sizes[] = {120, 0, 300, 1, 200, 80};
  for (int f = 0; f < 6; ++f) {
    MapFrame frame;
    frame.name = "map/" + std::to_string(f) + ".png";
    frame.camera = f % 2;
    const double roll = rng.uniform(-1.0, 1.0);
    frame.gravity_in_cam =
        f == 4 ? Eigen::Vector3d(0, 0, 1) : Eigen::Vector3d(std::sin(roll), std::cos(roll), 0.3).normalized();
    frame.first_keypoint = static_cast<int64_t>(map.keypoints.size());
    frame.num_keypoints = sizes[f];
    map.frames.push_back(frame);
    for (int k = 0; k < sizes[f]; ++k) {
      map.keypoints.push_back(Keypoint{static_cast<float>(rng.uniform(0, 639)), static_cast<float>(rng.uniform(0, 479)),
                                       static_cast<float>(rng.uniform(8, 40)), -1.f});
      map.keypoint_landmark.push_back(rng.uniform() < 0.3 ? 0 : kInvalidLandmarkId);
    }
  }
  map.landmarks.resize(1);
  map.descriptors.resize(map.keypoints.size() * kBytes);
  for (auto& b : map.descriptors) b = static_cast<uint8_t>(rng.below(256));
  return map;
}

// Samples in random order, from every frame, with repeats.
std::vector<int64_t> random_samples(const LandmarkMap& map, int n, uint64_t seed) {
  Rng rng(seed);
  std::vector<int64_t> s;
  for (int i = 0; i < n; ++i) s.push_back(static_cast<int64_t>(rng.below(map.keypoints.size())));
  return s;
}

TEST(BuildFeatures, EveryColumnEqualsTheBruteForceEmbeddingAndDescriptorBits) {
  const LandmarkMap map = random_map(1);
  const Vocabulary vocab = random_vocabulary(8, kBytes, 2);
  const ContextRegions regions = small_regions();
  const std::vector<int64_t> samples = random_samples(map, 300, 3);
  FeatureBuildOptions options;
  const FeatureMatrix m = build_training_features(map, regions, vocab, samples, options);
  const EmbeddingLayout layout = embedding_layout(map, regions, vocab);
  ASSERT_EQ(m.num_samples, 300);
  ASSERT_EQ(m.num_dims, layout.num_dims());
  ASSERT_EQ(m.num_dims, 60 * 8 + 8 * kBytes);
  ASSERT_TRUE(m.dims.empty());
  ASSERT_EQ(m.data.size(), static_cast<size_t>(300) * m.num_dims);

  const std::vector<uint8_t> words = keypoint_words(map, vocab);
  const std::vector<frame_t> frame_of = keypoint_frames(map);
  std::vector<uint8_t> row(static_cast<size_t>(layout.num_context_dims()));
  int64_t nonzero = 0;
  for (int64_t i = 0; i < m.num_samples; ++i) {
    const int64_t kp = samples[i];
    const frame_t f = frame_of[kp];
    const FrameKeypoints frame = map_frame_keypoints(map, f, words);
    embed_context_brute_force(regions, 8, frame, static_cast<int32_t>(kp - map.frames[f].first_keypoint), row.data());
    for (int32_t d = 0; d < m.num_dims; ++d) {
      const uint8_t expected =
          layout.is_context(d) ? row[d] : static_cast<uint8_t>(descriptor_bit(map.descriptor(kp), layout.bit_of(d)));
      ASSERT_EQ(m.column(d)[i], expected) << "sample " << i << " dim " << d;
      nonzero += layout.is_context(d) && expected != 0;
    }
  }
  EXPECT_GT(nonzero, 300 * 20);
}

TEST(BuildFeatures, IdenticalForAnyThreadCountAndDimSubsetsMatchFullColumns) {
  const LandmarkMap map = random_map(5);
  const Vocabulary vocab = random_vocabulary(16, kBytes, 6);
  const ContextRegions regions = small_regions();
  const std::vector<int64_t> samples = random_samples(map, 500, 7);
  FeatureBuildOptions options;
  const FeatureMatrix one = build_training_features(map, regions, vocab, samples, options);
  options.num_threads = 3;
  const FeatureMatrix three = build_training_features(map, regions, vocab, samples, options);
  EXPECT_EQ(one.data, three.data);

  // A subset of dims (a rank's share), context and bits: column i is global dim dims[i].
  Rng rng(8);
  for (int32_t d = 0; d < one.num_dims; ++d) {
    if (rng.below(7) == 0) options.dims.push_back(d);
  }
  options.dims.push_back(one.num_dims - 1);
  options.dims.erase(std::unique(options.dims.begin(), options.dims.end()), options.dims.end());
  const FeatureMatrix part = build_training_features(map, regions, vocab, samples, options);
  ASSERT_EQ(part.dims, options.dims);
  ASSERT_EQ(part.num_stored_columns(), static_cast<int32_t>(options.dims.size()));
  ASSERT_EQ(part.num_dims, one.num_dims);
  for (int32_t c = 0; c < part.num_stored_columns(); ++c) {
    ASSERT_TRUE(std::equal(part.column(c), part.column(c) + part.num_samples, one.column(options.dims[c])))
        << "dim " << options.dims[c];
  }
}

TEST(BuildFeatures, KeypointWordsEqualQuantize) {
  const LandmarkMap map = random_map(9);
  const Vocabulary vocab = random_vocabulary(16, kBytes, 10);
  const std::vector<uint8_t> w1 = keypoint_words(map, vocab, 1);
  EXPECT_EQ(keypoint_words(map, vocab, 2), w1);
  for (size_t k = 0; k < map.keypoints.size(); ++k) {
    ASSERT_EQ(w1[k], vocab.quantize(map.descriptor(static_cast<int64_t>(k))));
  }
}

TEST(BuildFeatures, BadInputThrowsNamingTheProblem) {
  LandmarkMap map = random_map(11);
  const Vocabulary vocab = random_vocabulary(8, kBytes, 12);
  const ContextRegions regions = small_regions();
  FeatureBuildOptions options;
  // Another descriptor length.
  EXPECT_THROW(build_training_features(map, regions, random_vocabulary(8, 32, 1), {0}, options), Error);
  EXPECT_THROW(keypoint_words(map, random_vocabulary(8, 32, 1)), Error);
  // Samples out of range.
  EXPECT_THROW(build_training_features(map, regions, vocab, {-1}, options), Error);
  EXPECT_THROW(build_training_features(map, regions, vocab, {static_cast<int64_t>(map.keypoints.size())}, options),
               Error);
  // Dims unsorted, repeated, out of range; thread count.
  options.dims = {5, 3};
  EXPECT_THROW(build_training_features(map, regions, vocab, {0}, options), Error);
  options.dims = {3, 3};
  EXPECT_THROW(build_training_features(map, regions, vocab, {0}, options), Error);
  options.dims = {100000};
  EXPECT_THROW(build_training_features(map, regions, vocab, {0}, options), Error);
  options.dims.clear();
  options.num_threads = 0;
  EXPECT_THROW(build_training_features(map, regions, vocab, {0}, options), Error);
  options.num_threads = 2;
  // No samples: an empty matrix.
  const FeatureMatrix empty = build_training_features(map, regions, vocab, {}, options);
  EXPECT_EQ(empty.num_samples, 0);
  EXPECT_TRUE(empty.data.empty());
  // A zero keypoint scale in frame 2: the error names the frame, even when the sample is elsewhere
  // in that frame.
  map.keypoints[map.frames[2].first_keypoint + 7].scale = 0.f;
  try {
    build_training_features(map, regions, vocab, {map.frames[2].first_keypoint}, options);
    FAIL() << "no error for a zero keypoint scale";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("frame 2"), std::string::npos) << e.what();
  }
  map.keypoints[map.frames[2].first_keypoint + 7].scale = NAN;
  EXPECT_THROW(build_training_features(map, regions, vocab, {map.frames[2].first_keypoint}, options), Error);
  map.keypoints[map.frames[2].first_keypoint + 7].scale = 10.f;
  // Zero gravity is an error; gravity along the optical axis (frame 4) is the documented fallback.
  map.frames[2].gravity_in_cam = Eigen::Vector3d::Zero();
  EXPECT_THROW(build_training_features(map, regions, vocab, {map.frames[2].first_keypoint}, options), Error);
}

}  // namespace
}  // namespace lmb
