// `lboost scene` on the photo world's map (fixture lmb_photo_world): the COLMAP text model reads
// back with the project's COLMAP reader (common/io/colmap_model.h) with the map's landmarks, map
// frames, their keypoints linked to the landmarks and the localized photos of a poses file; the
// landmarks take the colour of their images; the PLY's header counts its vertices.
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "common/camera.h"
#include "common/file_io.h"
#include "common/io/colmap_model.h"
#include "common/io/map_h5.h"
#include "common/landmark_map.h"
#include "test/support/lboost_run.h"

namespace lmb {
namespace {

namespace fs = std::filesystem;

using test::expect_one_error;
using test::RunResult;
using test::slurp;

RunResult run(const std::string& args, const fs::path& dir) { return test::run_lboost(args, dir); }

nlohmann::json pose_json(const Rigid3d& pose) {
  const Eigen::Quaterniond& q = pose.rotation;
  const Eigen::Vector3d& t = pose.translation;
  return {{"qw", q.w()}, {"qx", q.x()}, {"qy", q.y()}, {"qz", q.z()}, {"tx", t.x()}, {"ty", t.y()}, {"tz", t.z()}};
}

class SceneCliTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const char* world = std::getenv("LMB_PHOTO_WORLD");
    if (world == nullptr || !fs::exists(fs::path(world) / "map.h5")) {
      GTEST_SKIP() << "LMB_PHOTO_WORLD (the fixture lmb_photo_world) is not available";
    }
    world_ = world;
    dir_ = fs::temp_directory_path() / ("lmb_scene_cli_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    map_ = read_map_h5(world_ / "map.h5");
  }
  void TearDown() override {
    if (!dir_.empty()) fs::remove_all(dir_);
  }
  // A poses file as `lboost localize --image` writes it: three photos, two localized (the first
  // two query frames' true poses), one not; camera `camera`.
  fs::path write_photo_poses(const std::string& camera) {
    nlohmann::json photos = nlohmann::json::array();
    int k = 0;
    for (const MapFrame& f : map_.frames) {
      if (map_.sessions[f.session].kind != SessionKind::kQuery || k == 3) continue;
      nlohmann::json p = {{"path", "/path/to/photos/" + fs::path(f.name).filename().string()}, {"success", k < 2}};
      p["cam_from_world"] = pose_json(f.cam_from_world);
      photos.push_back(p);
      query_poses_.push_back(f.cam_from_world);
      ++k;
    }
    const fs::path path = dir_ / "poses.json";
    write_file_atomically(path, nlohmann::json({{"camera", camera}, {"photos", photos}}).dump());
    return path;
  }
  int map_frames() const {
    int n = 0;
    for (const MapFrame& f : map_.frames) n += !f.is_query;
    return n;
  }

  fs::path world_;
  fs::path dir_;
  LandmarkMap map_;
  std::vector<Rigid3d> query_poses_;
};

TEST_F(SceneCliTest, TheColmapModelReadsBackWithTheMapAndThePhotos) {
  const fs::path poses = write_photo_poses("PINHOLE 320 240 200 200 160 120");
  const RunResult r = run("scene --map " + (world_ / "map.h5").string() + " --poses " + poses.string() + " --images " +
                              (world_ / "collection/images").string() + " --out " + (dir_ / "scene").string(),
                          dir_);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const ColmapModel m = read_colmap_text(dir_ / "scene/sparse");
  // Cameras: the map's, then the photos' (another camera).
  ASSERT_EQ(m.cameras.size(), map_.cameras.size() + 1);
  EXPECT_EQ(camera_to_text(m.cameras.at(1)), camera_to_text(map_.cameras[0]));
  EXPECT_EQ(camera_to_text(m.cameras.at(2)), "PINHOLE 320 240 200 200 160 120");
  // Images: the map frames in order, then the two localized photos.
  const int n = map_frames();
  ASSERT_GT(n, 0);
  ASSERT_EQ(m.images.size(), static_cast<size_t>(n) + 2);
  ASSERT_EQ(m.points.size(), map_.landmarks.size());
  const MapFrame& first = map_.frames[0];
  ASSERT_FALSE(first.is_query);
  const ColmapImage& im = m.images[0];
  EXPECT_EQ(im.image_id, 1);
  EXPECT_EQ(im.name, first.name);
  EXPECT_LT(im.cam_from_world.rotation.angularDistance(first.cam_from_world.rotation), 1e-12);
  EXPECT_LT((im.cam_from_world.translation - first.cam_from_world.translation).norm(), 1e-12);
  ASSERT_EQ(im.points2d.size(), static_cast<size_t>(first.num_keypoints));
  int linked = 0;
  for (int32_t k = 0; k < first.num_keypoints; ++k) {
    const landmark_t l = map_.keypoint_landmark[first.first_keypoint + k];
    EXPECT_EQ(im.points2d[k].point3d_id, l == kInvalidLandmarkId ? -1 : int64_t{l} + 1) << k;
    EXPECT_EQ(im.points2d[k].xy.x(), map_.keypoints[first.first_keypoint + k].x);
    linked += l != kInvalidLandmarkId;
  }
  EXPECT_GT(linked, 0);
  for (int i = 0; i < 2; ++i) {
    const ColmapImage& photo = m.images[n + i];
    EXPECT_EQ(photo.camera_id, 2);
    EXPECT_EQ(photo.name.rfind("localized/", 0), 0u) << photo.name;
    EXPECT_TRUE(photo.points2d.empty());
    EXPECT_LT((photo.cam_from_world.translation - query_poses_[i].translation).norm(), 1e-12);
  }
  // A landmark: its position, and its track points back at keypoints that observe it.
  const landmark_t l = map_.keypoint_landmark[first.first_keypoint + [&] {
    int32_t k = 0;
    while (map_.keypoint_landmark[first.first_keypoint + k] == kInvalidLandmarkId) ++k;
    return k;
  }()];
  const ColmapPoint3D& p = m.points[l];
  EXPECT_EQ(p.point3d_id, int64_t{l} + 1);
  EXPECT_EQ(p.xyz, map_.landmarks[l].position);
  ASSERT_EQ(p.track.size(), static_cast<size_t>(map_.landmarks[l].num_map_observations));
  for (const ColmapTrackElement& e : p.track) {
    EXPECT_EQ(m.images[e.image_id - 1].points2d[e.point2d_idx].point3d_id, p.point3d_id);
  }
  // Its colour: the mean of the pixels under its observations (the rendered images are grey).
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (const ColmapTrackElement& e : p.track) {
    const ColmapImage& obs = m.images[e.image_id - 1];
    const cv::Mat image = cv::imread((world_ / "collection/images" / obs.name).string(), cv::IMREAD_COLOR);
    ASSERT_FALSE(image.empty());
    const Eigen::Vector2d& xy = obs.points2d[e.point2d_idx].xy;
    const cv::Vec3b bgr =
        image.at<cv::Vec3b>(static_cast<int>(std::floor(xy.y())), static_cast<int>(std::floor(xy.x())));
    sum += Eigen::Vector3d(bgr[2], bgr[1], bgr[0]);
  }
  const Eigen::Vector3d mean = sum / static_cast<double>(p.track.size());
  for (int c = 0; c < 3; ++c) EXPECT_EQ(p.rgb[c], static_cast<int>(std::round(mean[c])));
  // Not every landmark is the same grey.
  int other = 0;
  for (const ColmapPoint3D& q : m.points) other += q.rgb != p.rgb;
  EXPECT_GT(other, 0);
}

TEST_F(SceneCliTest, ThePlyHeaderCountsItsVertices) {
  const fs::path poses = write_photo_poses(camera_to_text(map_.cameras[0]));
  const RunResult r = run("scene --map " + (world_ / "map.h5").string() + " --poses " + poses.string() + " --out " +
                              (dir_ / "scene").string(),
                          dir_);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  // The photos' camera is the map's: no second camera.
  EXPECT_EQ(read_colmap_text(dir_ / "scene/sparse").cameras.size(), map_.cameras.size());
  std::istringstream ply(slurp(dir_ / "scene/scene.ply"));
  std::string line;
  std::getline(ply, line);
  EXPECT_EQ(line, "ply");
  std::getline(ply, line);
  EXPECT_EQ(line, "format ascii 1.0");
  size_t vertices = 0;
  int properties = 0;
  while (std::getline(ply, line) && line != "end_header") {
    if (line.rfind("element vertex ", 0) == 0) vertices = std::stoul(line.substr(15));
    properties += line.rfind("property ", 0) == 0;
  }
  EXPECT_EQ(line, "end_header");
  EXPECT_EQ(properties, 6);
  const size_t expected = map_.landmarks.size() + static_cast<size_t>(map_frames()) + 2;
  EXPECT_EQ(vertices, expected);
  std::vector<std::string> rows;
  while (std::getline(ply, line)) rows.push_back(line);
  ASSERT_EQ(rows.size(), expected);
  // Without --images every landmark is grey; the first is landmark 0; the last, the second photo's
  // centre in red.
  std::istringstream first(rows[0]);
  double x, y, z;
  int red, green, blue;
  first >> x >> y >> z >> red >> green >> blue;
  EXPECT_NEAR(x, map_.landmarks[0].position.x(), 1e-5);
  EXPECT_EQ(red, 128);
  EXPECT_EQ(green, 128);
  EXPECT_EQ(blue, 128);
  std::istringstream last(rows.back());
  last >> x >> y >> z >> red >> green >> blue;
  EXPECT_LT((Eigen::Vector3d(x, y, z) - query_poses_[1].center()).norm(), 1e-5);
  EXPECT_EQ(red, 255);
  EXPECT_EQ(green, 40);
}

TEST_F(SceneCliTest, BadPosesFilesAreOneLine) {
  write_file_atomically(dir_ / "not_json.json", "{ this is not json");
  const std::string base = "scene --map " + (world_ / "map.h5").string() + " --out " + (dir_ / "scene").string();
  expect_one_error(run(base + " --poses " + (dir_ / "not_json.json").string(), dir_), "scene",
                   "not a poses file of `lboost localize`");
  write_file_atomically(dir_ / "other.json", "{\"modes\": []}");
  expect_one_error(run(base + " --poses " + (dir_ / "other.json").string(), dir_), "scene",
                   "no \"photos\" or \"frames\"");
  // The output folder may not hold the map.
  expect_one_error(run("scene --map " + (world_ / "map.h5").string() + " --out " + world_.string(), dir_), "scene",
                   "contains the input --map");
}

}  // namespace
}  // namespace lmb
