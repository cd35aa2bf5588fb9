#include "train/mapping/mapper.h"

#include <unistd.h>

#include <array>
#include <fstream>
#include <map>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "common/error.h"
#include "common/io/colmap_model.h"
#include "common/io/map_h5.h"
#include "synthetic_scene.h"
#include "train/mapping/descriptor_nn.h"

namespace lmb {
namespace {

namespace fs = std::filesystem;

struct Accuracy {
  double mean_purity = 0;  // per landmark: share of observations of its majority point
  double median_position_error = 0;
  double query_label_accuracy = 0;  // query keypoints with a landmark whose majority point is theirs
  int64_t landmarks = 0;
};

Accuracy evaluate(const test::SyntheticScene& s, const LandmarkMap& map) {
  std::vector<std::map<int, int>> votes(map.landmarks.size());
  std::vector<int> frame_of_keypoint;
  for (size_t f = 0; f < map.frames.size(); ++f) {
    for (int k = 0; k < map.frames[f].num_keypoints; ++k) {
      const landmark_t l = map.keypoint_landmark[map.frames[f].first_keypoint + k];
      if (l >= 0) ++votes[l][s.keypoint_point[f][k]];
    }
  }
  Accuracy a;
  a.landmarks = static_cast<int64_t>(map.landmarks.size());
  std::vector<int> majority(map.landmarks.size(), -1);
  std::vector<double> errors;
  double purity_sum = 0;
  for (size_t l = 0; l < map.landmarks.size(); ++l) {
    int best = 0, total = 0;
    for (auto [p, n] : votes[l]) {
      total += n;
      if (n > best && p >= 0) {
        best = n;
        majority[l] = p;
      }
    }
    purity_sum += static_cast<double>(best) / total;
    if (majority[l] >= 0) errors.push_back((map.landmarks[l].position - s.points[majority[l]]).norm());
  }
  a.mean_purity = purity_sum / std::max<size_t>(1, map.landmarks.size());
  std::sort(errors.begin(), errors.end());
  a.median_position_error = errors.empty() ? 1e9 : errors[errors.size() / 2];
  int64_t right = 0, total = 0;
  for (size_t f = 0; f < map.frames.size(); ++f) {
    if (!map.frames[f].is_query) continue;
    for (int k = 0; k < map.frames[f].num_keypoints; ++k) {
      const landmark_t l = map.keypoint_landmark[map.frames[f].first_keypoint + k];
      if (l < 0) continue;
      ++total;
      right += majority[l] == s.keypoint_point[f][k] ? 1 : 0;
    }
  }
  a.query_label_accuracy = total > 0 ? static_cast<double>(right) / total : 0;
  return a;
}

TEST(BuildLandmarkMap, RecoversSyntheticGroundTruth) {
  test::SyntheticSceneOptions o;
  o.num_patterns = 300;  // aliased descriptors: the epipolar guidance must disambiguate
  o.unique_bits = 20;
  const test::SyntheticScene s = test::make_synthetic_scene(o);
  MapperOptions options;
  options.threads = 2;
  MapperStats stats;
  const LandmarkMap map = build_landmark_map({s.camera}, s.frames, "BRISK", 64, options, &stats);
  validate_landmark_map(map, "mapped");
  const Accuracy a = evaluate(s, map);
  std::printf(
      "synthetic: %lld landmarks, purity %.4f, median position error %.4f m, query labels %.4f, "
      "%.2f obs/landmark\n",
      static_cast<long long>(a.landmarks), a.mean_purity, a.median_position_error, a.query_label_accuracy,
      stats.mean_map_observations);
  EXPECT_GT(a.landmarks, 800);
  EXPECT_GT(a.mean_purity, 0.99);
  EXPECT_LT(a.median_position_error, 0.02);
  EXPECT_GT(a.query_label_accuracy, 0.98);
  EXPECT_GT(stats.num_query_observations, 300);
  for (const Landmark& l : map.landmarks) {
    EXPECT_GE(l.num_map_observations, 3);
    EXPECT_GT(l.quality, 0.f);
    EXPECT_LT(l.mean_reprojection_error, options.triangulation.max_reprojection_error_px);
  }
  for (const MapFrame& f : map.frames) {
    EXPECT_LT((f.gravity_in_cam - f.cam_from_world.rotation * Eigen::Vector3d(0, 0, -1)).norm(), 1e-12);
  }
  // Thread count does not change the result.
  options.threads = 1;
  const LandmarkMap serial = build_landmark_map({s.camera}, s.frames, "BRISK", 64, options);
  EXPECT_EQ(serial.keypoint_landmark, map.keypoint_landmark);
  ASSERT_EQ(serial.landmarks.size(), map.landmarks.size());
  for (size_t l = 0; l < map.landmarks.size(); ++l) EXPECT_EQ(serial.landmarks[l].position, map.landmarks[l].position);
}

TEST(BuildLandmarkMap, AliasedDescriptorsDefeatPlainNearestNeighbour) {
  // The same scene with unique descriptors and with shared patterns: the mapper finds the same
  // structure, but plain Hamming NN precision@1 collapses under aliasing.
  test::SyntheticSceneOptions unique;
  unique.num_points = 1500;
  test::SyntheticSceneOptions aliased = unique;
  aliased.num_patterns = 100;  // 15 points per pattern, told apart only by observation noise
  aliased.unique_bits = 0;
  MapperOptions options;
  const auto su = test::make_synthetic_scene(unique);
  const auto sa = test::make_synthetic_scene(aliased);
  const HammingNnStats nu = evaluate_hamming_nn(build_landmark_map({su.camera}, su.frames, "BRISK", 64, options), 2);
  const HammingNnStats na = evaluate_hamming_nn(build_landmark_map({sa.camera}, sa.frames, "BRISK", 64, options), 2);
  std::printf("synthetic hamming NN precision@1: unique %.3f (%lld queries), aliased %.3f (%lld queries)\n",
              nu.precision_at_1, static_cast<long long>(nu.num_queries), na.precision_at_1,
              static_cast<long long>(na.num_queries));
  EXPECT_GT(nu.num_queries, 200);
  EXPECT_GT(na.num_queries, 200);
  EXPECT_GT(nu.precision_at_1, 0.95);
  EXPECT_LT(na.precision_at_1, 0.6);
}

// A dense video along the corridor (map frames 2 cm apart, 1.2 m of path) and query frames that
// see the same corridor from about 1 m to the side: the pose rule alone (here its automatic
// distance, 8 x 2 cm) gives them no partner and no landmark; the default overlap rule links them,
// with the right landmarks.
TEST(BuildLandmarkMap, QueryFramesAMetreFromDenseMapFramesGetTheirLandmarks) {
  test::SyntheticSceneOptions o;
  o.num_points = 3000;
  o.num_map_frames = 60;
  o.map_spacing = 0.02;
  o.map_wobble = 0.0;
  o.query_poses = {test::look_along(Eigen::Vector3d(0.3, 1.0, 1.4), 0.05),
                   test::look_along(Eigen::Vector3d(0.9, -1.0, 1.6), -0.05, 0.05)};
  const test::SyntheticScene s = test::make_synthetic_scene(o);
  MapperOptions options;
  options.pairs.max_center_distance = 8 * 0.02;  // the pose rule alone, at its automatic distance
  MapperStats by_pose;
  build_landmark_map({s.camera}, s.frames, "BRISK", 64, options, &by_pose);
  EXPECT_FALSE(by_pose.pairs_by_overlap);
  EXPECT_EQ(by_pose.num_query_observations, 0);

  options.pairs.max_center_distance = 0;  // default: query partners by view overlap
  MapperStats stats;
  const LandmarkMap map = build_landmark_map({s.camera}, s.frames, "BRISK", 64, options, &stats);
  validate_landmark_map(map, "mapped");
  const Accuracy a = evaluate(s, map);
  std::printf(
      "dense map, queries 1 m aside: %lld overlap pairs (query-partner distance median %.2f m, max %.2f m), %lld "
      "query keypoints with a landmark, query labels %.4f\n",
      static_cast<long long>(stats.overlap.pairs), stats.overlap.median_partner_distance,
      stats.overlap.max_partner_distance, static_cast<long long>(stats.num_query_observations), a.query_label_accuracy);
  EXPECT_TRUE(stats.pairs_by_overlap);
  EXPECT_EQ(stats.overlap.query_frames_with, 2);
  EXPECT_GE(stats.overlap.median_partner_distance, 0.9);
  EXPECT_GT(stats.num_query_observations, 200);
  EXPECT_GT(a.query_label_accuracy, 0.98);
  EXPECT_GT(a.mean_purity, 0.98);
}

TEST(BuildLandmarkMap, QueryOnlyTracksAreNotLandmarks) {
  test::SyntheticSceneOptions o;
  o.num_points = 800;
  test::SyntheticScene s = test::make_synthetic_scene(o);
  // Keep only 2 map frames: no track can reach 3 map observations.
  std::vector<MapperFrame> frames;
  for (const auto& f : s.frames) {
    if (f.is_query || f.name == "map/3.png" || f.name == "map/4.png") frames.push_back(f);
  }
  const MapperOptions options;
  const LandmarkMap map = build_landmark_map({s.camera}, frames, "BRISK", 64, options);
  EXPECT_TRUE(map.landmarks.empty());
  for (landmark_t l : map.keypoint_landmark) EXPECT_EQ(l, kInvalidLandmarkId);
}

// Sessions: the map frames in two map sessions (alternating, as two walks over the same places),
// the query frames in a query session, and copies of the query frames in an outside session.
// Tracks join both map sessions; outside frames are never matched, so none of their keypoints gets
// a landmark; frames keep their session.
TEST(BuildLandmarkMap, TracksJoinMapSessionsAndOutsideFramesStayBackground) {
  test::SyntheticSceneOptions o;
  o.num_points = 1200;
  const test::SyntheticScene s = test::make_synthetic_scene(o);
  const std::vector<MapSession> sessions = {{"walk-a", SessionKind::kMap},
                                            {"walk-b", SessionKind::kMap},
                                            {"query", SessionKind::kQuery},
                                            {"elsewhere", SessionKind::kOutside}};
  std::vector<MapperFrame> frames;
  int map_index = 0;
  for (const MapperFrame& f : s.frames) {
    MapperFrame g = f;
    g.session = f.is_query ? 2 : map_index++ % 2;
    frames.push_back(std::move(g));
  }
  const size_t num_scene_frames = frames.size();
  for (size_t i = 0; i < num_scene_frames; ++i) {
    if (!frames[i].is_query) continue;
    MapperFrame g = frames[i];
    g.session = 3;
    g.name = "elsewhere/" + g.name;
    frames.push_back(std::move(g));
  }
  MapperOptions options;
  MapperStats stats;
  const LandmarkMap map = build_landmark_map({s.camera}, sessions, frames, "BRISK", 64, options, &stats);
  validate_landmark_map(map, "mapped");
  EXPECT_EQ(stats.num_sessions, 4);
  EXPECT_EQ(stats.num_outside_frames, o.num_query_frames);
  ASSERT_EQ(map.sessions.size(), 4u);
  for (size_t i = 0; i < sessions.size(); ++i) {
    EXPECT_EQ(map.sessions[i].name, sessions[i].name);
    EXPECT_EQ(map.sessions[i].kind, sessions[i].kind);
  }
  std::vector<std::array<int, 2>> per_session(map.landmarks.size(), {0, 0});
  int64_t outside_keypoints = 0;
  for (size_t f = 0; f < map.frames.size(); ++f) {
    EXPECT_EQ(map.frames[f].session, frames[f].session);
    for (int k = 0; k < map.frames[f].num_keypoints; ++k) {
      const landmark_t l = map.keypoint_landmark[map.frames[f].first_keypoint + k];
      if (map.frames[f].session == 3) {
        ++outside_keypoints;
        EXPECT_EQ(l, kInvalidLandmarkId);
      } else if (l >= 0 && map.frames[f].session < 2) {
        ++per_session[l][map.frames[f].session];
      }
    }
  }
  EXPECT_GT(outside_keypoints, 300);
  int64_t both = 0;
  for (const auto& c : per_session) both += c[0] > 0 && c[1] > 0;
  std::printf("two map sessions: %lld of %zu landmarks observed in both\n", static_cast<long long>(both),
              map.landmarks.size());
  EXPECT_GT(both, static_cast<int64_t>(0.8 * static_cast<double>(map.landmarks.size())));
  // Query keypoints still get their true landmark.
  const Accuracy a = evaluate(s, [&] {
    LandmarkMap first = map;  // evaluate() reads the scene's frames: drop the outside copies
    first.frames.resize(num_scene_frames);
    return first;
  }());
  EXPECT_GT(a.mean_purity, 0.99);
  EXPECT_GT(a.query_label_accuracy, 0.98);

  // A frame whose is_query disagrees with its session's kind, and a session index out of range.
  auto bad = frames;
  bad[0].session = 2;
  EXPECT_THROW(build_landmark_map({s.camera}, sessions, bad, "BRISK", 64, options), Error);
  bad = frames;
  bad[0].session = 4;
  EXPECT_THROW(build_landmark_map({s.camera}, sessions, bad, "BRISK", 64, options), Error);
  auto twins = sessions;
  twins[1].name = "walk-a";
  EXPECT_THROW(build_landmark_map({s.camera}, twins, frames, "BRISK", 64, options), Error);
}

TEST(BuildLandmarkMap, RejectsInconsistentInput) {
  test::SyntheticSceneOptions o;
  o.num_points = 100;
  o.num_map_frames = 3;
  o.num_query_frames = 0;
  test::SyntheticScene s = test::make_synthetic_scene(o);
  const MapperOptions options;
  auto frames = s.frames;
  frames[1].camera = 1;
  EXPECT_THROW(build_landmark_map({s.camera}, frames, "BRISK", 64, options), Error);
  frames = s.frames;
  frames[2].descriptors.pop_back();
  EXPECT_THROW(build_landmark_map({s.camera}, frames, "BRISK", 64, options), Error);
}

TEST(ParseUpAxis, KnownAxesAndErrors) {
  EXPECT_EQ(parse_up_axis("+z"), Eigen::Vector3d(0, 0, 1));
  EXPECT_EQ(parse_up_axis("-y"), Eigen::Vector3d(0, -1, 0));
  EXPECT_EQ(parse_up_axis("x"), Eigen::Vector3d(1, 0, 0));
  EXPECT_THROW(parse_up_axis("up"), Error);
  EXPECT_THROW(parse_up_axis("+w"), Error);
}

TEST(LandmarkQuality, MonotoneInEachTerm) {
  EXPECT_GT(landmark_quality(10, 0.5, 10), landmark_quality(5, 0.5, 10));
  EXPECT_GT(landmark_quality(10, 0.5, 10), landmark_quality(10, 1.5, 10));
  EXPECT_GT(landmark_quality(10, 0.5, 20), landmark_quality(10, 0.5, 10));
}

// Bad collections: one clear error naming file and reason.
class MapCollectionTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("lmb_mapcoll_" + std::to_string(::getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_ / "images" / "map");
    fs::create_directories(dir_ / "images" / "query");
    ColmapModel model;
    Camera c;
    c.model = CameraModel::kSimpleRadial;
    c.width = 160;
    c.height = 120;
    c.params = {120, 80, 60, -0.01};
    model.cameras[1] = c;
    for (int i = 0; i < 4; ++i) {
      ColmapImage im;
      im.image_id = i + 1;
      im.camera_id = 1;
      im.name = (i < 3 ? "map/" : "query/") + std::to_string(i) + ".png";
      im.cam_from_world = test::look_along(Eigen::Vector3d(0.2 * i, 0, 1), 0);
      model.images.push_back(im);
      cv::Mat img(120, 160, CV_8UC1, cv::Scalar(60));
      cv::circle(img, cv::Point(40 + 20 * i, 60), 12, cv::Scalar(220), cv::FILLED);
      cv::rectangle(img, cv::Point(100, 20), cv::Point(130, 50), cv::Scalar(200), cv::FILLED);
      cv::imwrite((dir_ / "images" / im.name).string(), img);
    }
    write_colmap_text(model, dir_ / "sparse");
  }
  void TearDown() override { fs::remove_all(dir_); }

  std::string error() {
    try {
      map_collection(dir_, options_);
    } catch (const Error& e) {
      const std::string msg = e.what();
      EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
      return msg;
    }
    return "";
  }

  void replace_in(const fs::path& file, const std::string& from, const std::string& to) {
    std::ifstream in(file);
    std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const size_t at = text.find(from);
    ASSERT_NE(at, std::string::npos) << from;
    text.replace(at, from.size(), to);
    std::ofstream(file) << text;
  }

  fs::path dir_;
  MapperOptions options_;
};

TEST_F(MapCollectionTest, ValidCollectionMaps) {
  MapperStats stats;
  const LandmarkMap map = map_collection(dir_, options_, &stats);
  EXPECT_EQ(stats.num_map_frames, 3);
  EXPECT_EQ(stats.num_query_frames, 1);
  ASSERT_EQ(map.frames.size(), 4u);
  EXPECT_TRUE(map.frames[3].is_query);
  EXPECT_FALSE(map.frames[0].is_query);
  EXPECT_EQ(map.frames[0].name, "map/0.png");
  EXPECT_GT(map.keypoints.size(), 0u);
  validate_landmark_map(map, "collection map");
}

TEST_F(MapCollectionTest, MissingImage) {
  fs::remove(dir_ / "images" / "map" / "1.png");
  const std::string msg = error();
  EXPECT_NE(msg.find("map/1.png"), std::string::npos) << msg;
  EXPECT_NE(msg.find("missing"), std::string::npos) << msg;
}

TEST_F(MapCollectionTest, UnreadableImage) {
  std::ofstream(dir_ / "images" / "map" / "2.png") << "not a png";
  const std::string msg = error();
  EXPECT_NE(msg.find("map/2.png"), std::string::npos) << msg;
  // Caught before decoding by the collection check (common/io/colmap_model.h).
  EXPECT_NE(msg.find("not an image file"), std::string::npos) << msg;
}

TEST_F(MapCollectionTest, ImageOfWrongSize) {
  cv::imwrite((dir_ / "images" / "query" / "3.png").string(), cv::Mat(100, 100, CV_8UC1, cv::Scalar(5)));
  const std::string msg = error();
  EXPECT_NE(msg.find("query/3.png"), std::string::npos) << msg;
  EXPECT_NE(msg.find("100x100"), std::string::npos) << msg;
}

TEST_F(MapCollectionTest, ImagesSmallerThanTheDetectorTakes) {
  replace_in(dir_ / "sparse" / "cameras.txt", "160 120", "5 5");
  for (const char* name : {"map/0.png", "map/1.png", "map/2.png", "query/3.png"}) {
    cv::imwrite((dir_ / "images" / name).string(), cv::Mat(5, 5, CV_8UC1, cv::Scalar(90)));
  }
  const std::string msg = error();
  EXPECT_NE(msg.find((dir_ / "images").string()), std::string::npos) << msg;
  EXPECT_NE(msg.find(".png: image is 5x5 pixels, smaller than the 6x6 that BRISK with 3 octaves takes"),
            std::string::npos)
      << msg;
}

TEST_F(MapCollectionTest, UnknownCameraModel) {
  replace_in(dir_ / "sparse" / "cameras.txt", "SIMPLE_RADIAL", "FOV");
  const std::string msg = error();
  EXPECT_NE(msg.find("sparse"), std::string::npos) << msg;
  EXPECT_NE(msg.find("FOV"), std::string::npos) << msg;
}

TEST_F(MapCollectionTest, NanOrNonRotationPose) {
  {
    std::ifstream in(dir_ / "sparse" / "images.txt");
    std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    // Second image line: replace its first quaternion value.
    const size_t line = text.find("\n2 ");
    ASSERT_NE(line, std::string::npos);
    const size_t start = line + 3, end = text.find(' ', start);
    std::string nan_text = text;
    nan_text.replace(start, end - start, "nan");
    std::ofstream(dir_ / "sparse" / "images.txt") << nan_text;
    const std::string msg = error();
    EXPECT_NE(msg.find("images.txt"), std::string::npos) << msg;
    EXPECT_NE(msg.find("QW"), std::string::npos) << msg;
    std::string scaled = text;
    scaled.replace(start, end - start, "3.5");
    std::ofstream(dir_ / "sparse" / "images.txt") << scaled;
  }
  const std::string msg = error();
  EXPECT_NE(msg.find("images.txt"), std::string::npos) << msg;
  EXPECT_NE(msg.find("not a rotation"), std::string::npos) << msg;
}

TEST_F(MapCollectionTest, MissingSparseModel) {
  fs::remove_all(dir_ / "sparse");
  const std::string msg = error();
  EXPECT_NE(msg.find("sparse"), std::string::npos) << msg;
}

}  // namespace
}  // namespace lmb
