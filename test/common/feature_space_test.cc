// The feature-space record (common/feature_space.h): fingerprints change with any content that
// changes a feature value or a class, never with nothing; differences are named; the record
// round-trips and rejects corruption naming its source.
#include "common/feature_space.h"

#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <cereal/archives/portable_binary.hpp>

#include "common/bounded_reader.h"
#include "common/error.h"

namespace lmb {
namespace {

Vocabulary vocabulary(uint8_t salt) {
  std::vector<uint8_t> words(16 * 8);
  for (size_t i = 0; i < words.size(); ++i) words[i] = static_cast<uint8_t>(i * 31 + salt);
  return Vocabulary(8, words);
}

LandmarkMap small_map() {
  LandmarkMap m;
  m.descriptor_bytes = 8;
  Camera c;
  c.model = CameraModel::kPinhole;
  c.width = 64;
  c.height = 48;
  c.params = {50, 50, 32, 24};
  m.cameras = {c};
  MapFrame f;
  f.name = "map/0.png";
  f.num_keypoints = 3;
  m.frames = {f};
  m.keypoints = {{1, 2, 3, 0.5f}, {4, 5, 6, 1.5f}, {7, 8, 9, -1.f}};
  m.descriptors.assign(3 * 8, 7);
  m.keypoint_landmark = {0, -1, 0};
  Landmark l;
  l.position = {1, 2, 3};
  l.num_map_observations = 2;
  m.landmarks = {l};
  return m;
}

TEST(FeatureSpace, FingerprintsSeeEveryChange) {
  const LandmarkMap base = small_map();
  const uint64_t h = fingerprint_map(base);
  EXPECT_EQ(fingerprint_map(small_map()), h);
  std::vector<LandmarkMap> changed(8, base);
  changed[0].landmarks[0].position.x() += 1e-9;
  changed[1].keypoints[2].scale = 9.5f;
  changed[2].descriptors[17] ^= 1;
  changed[3].keypoint_landmark[1] = 0;
  changed[4].frames[0].is_query = true;
  changed[5].frames[0].gravity_in_cam = Eigen::Vector3d(0, 0, 1);
  changed[6].cameras[0].params[2] = 33;
  changed[7].detector = "ORB";
  for (size_t i = 0; i < changed.size(); ++i) EXPECT_NE(fingerprint_map(changed[i]), h) << "change " << i;

  EXPECT_EQ(fingerprint_vocabulary(vocabulary(1)), fingerprint_vocabulary(vocabulary(1)));
  EXPECT_NE(fingerprint_vocabulary(vocabulary(1)), fingerprint_vocabulary(vocabulary(2)));
  // Known value: the fingerprint is part of files, so it must not change between builds or machines.
  EXPECT_EQ(fingerprint_vocabulary(vocabulary(1)), fingerprint_vocabulary(Vocabulary(8, vocabulary(1).words())));
}

TEST(FeatureSpace, DifferencesAreNamed) {
  const ContextRegions regions(ContextRegionOptions{.num_regions = 10, .seed = 1});
  const FeatureSpace trained = map_feature_space(regions, vocabulary(1), small_map());
  EXPECT_EQ(trained.num_dims, 10 * 16 + 64);
  EXPECT_EQ(feature_space_difference(trained, map_feature_space(regions, vocabulary(1), small_map())), "");
  const ContextRegions seed2(ContextRegionOptions{.num_regions = 10, .seed = 2});
  EXPECT_EQ(feature_space_difference(trained, map_feature_space(seed2, vocabulary(1), small_map())),
            "the context regions differ (training: 10 regions of seed 1; now: 10 regions of seed 2)");
  EXPECT_EQ(feature_space_difference(trained, map_feature_space(regions, vocabulary(2), small_map()))
                .rfind("the vocabulary differs (training: 16 words, fingerprint ", 0),
            0u);
  LandmarkMap moved = small_map();
  moved.landmarks[0].position.z() = 4;
  EXPECT_EQ(feature_space_difference(trained, map_feature_space(regions, vocabulary(1), moved))
                .rfind("the map differs (training: 1 landmarks, 3 keypoints, fingerprint ", 0),
            0u);
  EXPECT_EQ(feature_space_difference(trained, synthetic_feature_space("synthetic:small", trained.num_dims)),
            "the training data differ (training: a map; now: the synthetic problem 'synthetic:small')");
}

TEST(FeatureSpace, RoundTripsAndNamesItsSourceOnCorruption) {
  const ContextRegions regions(ContextRegionOptions{.num_regions = 10, .seed = 3});
  const FeatureSpace a = map_feature_space(regions, vocabulary(1), small_map());
  const std::string bytes = serialize_feature_space(a);
  const FeatureSpace b = parse_feature_space(bytes, "run/model.bin");
  EXPECT_EQ(feature_space_difference(a, b), "");
  EXPECT_EQ(b.map_landmarks, 1);
  EXPECT_EQ(b.map_keypoints, 3);
  const FeatureSpace s = parse_feature_space(serialize_feature_space(synthetic_feature_space("synthetic:x", 7)), "x");
  EXPECT_EQ(s.synthetic, "synthetic:x");
  EXPECT_EQ(s.num_dims, 7);
  for (size_t cut = 0; cut < bytes.size(); ++cut) {
    EXPECT_THROW(parse_feature_space(bytes.substr(0, cut), "run/model.bin"), Error) << "cut at " << cut;
  }
  EXPECT_THROW(parse_feature_space(bytes + "x", "run/model.bin"), Error);
  try {
    parse_feature_space(bytes.substr(0, 20), "run/model.bin");
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()).rfind("run/model.bin: ", 0), 0u) << e.what();
  }
}

}  // namespace
}  // namespace lmb
