#include "train/world/world_writer.h"

#include <fstream>
#include <iterator>
#include <map>

#include <gtest/gtest.h>
#include <unistd.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "common/error.h"
#include "common/io/colmap_model.h"
#include "common/io/session_file.h"

namespace fs = std::filesystem;

namespace lmb {
namespace {

class WorldWriterTest : public ::testing::Test {
 protected:
  void SetUp() override {
    root_ = fs::temp_directory_path() / ("lmb_world_writer_test_" + std::to_string(::getpid()));
    fs::remove_all(root_);
    fs::create_directories(root_);
  }
  void TearDown() override { fs::remove_all(root_); }

  static WorldOptions small(uint64_t seed) {
    WorldOptions o = world_preset("tiny");
    o.seed = seed;
    o.map_frames = 4;
    o.query_frames = 2;
    return o;
  }

  fs::path root_;
};

std::map<std::string, std::string> read_tree(const fs::path& dir) {
  std::map<std::string, std::string> files;
  for (const auto& e : fs::recursive_directory_iterator(dir)) {
    if (!e.is_regular_file()) continue;
    std::ifstream f(e.path(), std::ios::binary);
    files[fs::relative(e.path(), dir).string()] = std::string(std::istreambuf_iterator<char>(f), {});
  }
  return files;
}

TEST_F(WorldWriterTest, SameSeedGivesByteIdenticalFilesOtherSeedDiffers) {
  const WorldWriteStats s = write_world(small(1), root_ / "a");
  EXPECT_EQ(s.map_frames, 4);
  EXPECT_EQ(s.query_frames, 2);
  write_world(small(1), root_ / "b");
  write_world(small(2), root_ / "c");
  const auto a = read_tree(root_ / "a"), b = read_tree(root_ / "b"), c = read_tree(root_ / "c");
  ASSERT_EQ(a.size(), 5u + 2 * 6u);  // world.json, sessions.txt, 3 sparse files, 6 images, 6 depth maps
  EXPECT_EQ(a.at("sessions.txt").substr(a.at("sessions.txt").find("\nmap ")), "\nmap map\nquery query\n");
  EXPECT_EQ(a, b);
  int differing_images = 0;
  for (const auto& [name, bytes] : a) {
    if (name.rfind("images/", 0) == 0) differing_images += c.at(name) != bytes;
  }
  EXPECT_EQ(differing_images, 6);
  // Nothing but the outputs is left in the parent folder (no temporary folders).
  int entries = 0;
  for ([[maybe_unused]] const auto& e : fs::directory_iterator(root_)) ++entries;
  EXPECT_EQ(entries, 3);
}

TEST_F(WorldWriterTest, CollectionReadsBackWithUprightCamerasAndMatchingFiles) {
  write_world(small(3), root_ / "w");
  const ColmapModel m = read_colmap_text(root_ / "w" / "sparse");
  ASSERT_EQ(m.cameras.size(), 1u);
  const Camera& cam = m.cameras.at(1);
  EXPECT_EQ(cam.model, CameraModel::kOpenCV);
  EXPECT_EQ(cam.width, 640);
  ASSERT_EQ(m.images.size(), 6u);
  EXPECT_EQ(m.images[0].name, "map/000000.png");
  EXPECT_EQ(m.images[3].name, "map/000003.png");
  EXPECT_EQ(m.images[4].name, "query/000000.png");
  int floor_pixels = 0;
  for (const ColmapImage& im : m.images) {
    // Camera up (-y) against world +z: gravity is -z.
    const Eigen::Vector3d up = im.cam_from_world.rotation.conjugate() * Eigen::Vector3d(0, -1, 0);
    EXPECT_GT(up.z(), 0.95) << im.name;
    const cv::Mat image = cv::imread((root_ / "w" / "images" / im.name).string(), cv::IMREAD_UNCHANGED);
    const cv::Mat depth = cv::imread((root_ / "w" / "depth" / im.name).string(), cv::IMREAD_UNCHANGED);
    ASSERT_EQ(image.type(), CV_8UC1);
    ASSERT_EQ(depth.type(), CV_16UC1);
    EXPECT_EQ(image.size(), cv::Size(640, 480));
    EXPECT_EQ(depth.size(), cv::Size(640, 480));
    // Depth back-projects inside the corridor (x in [0, 8], |y| <= 1.2, z in [0, 2.7]), and some
    // pixels land on the floor (z ~ 0).
    for (int r = 0; r < 480; r += 8) {
      for (int c = 0; c < 640; c += 8) {
        const Eigen::Vector2d n = cam.cam_from_img(Eigen::Vector2d(c + 0.5, r + 0.5));
        const Eigen::Vector3d x =
            im.cam_from_world.inverse() * (depth.at<uint16_t>(r, c) * 1e-3 * Eigen::Vector3d(n.x(), n.y(), 1.0));
        EXPECT_TRUE(x.x() > -3e-3 && x.x() < 8.003 && std::abs(x.y()) < 1.203 && x.z() > -3e-3 && x.z() < 2.703)
            << im.name << " " << x.transpose();
        floor_pixels += std::abs(x.z()) < 3e-3;
      }
    }
  }
  EXPECT_GT(floor_pixels, 100);
  std::ifstream f(root_ / "w" / "world.json");
  const nlohmann::json j = nlohmann::json::parse(f);
  EXPECT_EQ(j["preset"], "tiny");
  EXPECT_EQ(j["seed"], 3);
  EXPECT_EQ(j["non_aliased"], false);
  EXPECT_EQ(j["up_axis"], nlohmann::json({0, 0, 1}));
  EXPECT_EQ(j["counts"]["map_frames"], 4);
  EXPECT_EQ(j["counts"]["query_frames"], 2);
  EXPECT_EQ(j["camera"]["model"], "OPENCV");
  EXPECT_TRUE(j["sessions"].contains("map"));
  EXPECT_TRUE(j["sessions"].contains("query"));
  EXPECT_EQ(j["sessions"]["query"]["kind"], "query");
  EXPECT_EQ(j["sessions"]["map"]["passes"].size(), 2u);
  EXPECT_NE(j["sessions"]["map"]["lighting"]["gain"], j["sessions"]["query"]["lighting"]["gain"]);
}

// Several map and query sessions: one image and depth folder each, listed in sessions.txt with
// their kinds; the first map and query sessions are the same images as in a one-session world.
TEST_F(WorldWriterTest, MultiSessionWorldWritesEverySessionAndKeepsTheFirst) {
  WorldOptions o = small(4);
  o.map_sessions = 2;
  o.query_sessions = 2;
  o.map_frames = 5;  // 3 + 2
  o.query_frames = 1;
  const WorldWriteStats s = write_world(o, root_ / "multi");
  EXPECT_EQ(s.map_frames, 5);
  EXPECT_EQ(s.query_frames, 2);
  const std::vector<MapSession> sessions = read_session_file(root_ / "multi" / "sessions.txt");
  ASSERT_EQ(sessions.size(), 4u);
  const char* names[] = {"map", "map-2", "query", "query-2"};
  for (size_t i = 0; i < 4; ++i) {
    EXPECT_EQ(sessions[i].name, names[i]);
    EXPECT_EQ(sessions[i].kind, i < 2 ? SessionKind::kMap : SessionKind::kQuery);
  }
  const ColmapModel m = read_colmap_text(root_ / "multi" / "sparse");
  std::vector<std::string> image_names;
  for (const ColmapImage& im : m.images) image_names.push_back(im.name);
  EXPECT_EQ(image_names,
            (std::vector<std::string>{"map/000000.png", "map/000001.png", "map/000002.png", "map-2/000000.png",
                                      "map-2/000001.png", "query/000000.png", "query-2/000000.png"}));
  EXPECT_EQ(image_sessions(sessions, m, root_ / "multi" / "sessions.txt"), (std::vector<int32_t>{0, 0, 0, 1, 1, 2, 3}));
  std::ifstream f(root_ / "multi" / "world.json");
  const nlohmann::json j = nlohmann::json::parse(f);
  EXPECT_EQ(j["counts"]["map_sessions"], 2);
  EXPECT_EQ(j["sessions"]["map-2"]["kind"], "map");
  EXPECT_EQ(j["sessions"]["map-2"]["frames"], 2);
  EXPECT_NE(j["sessions"]["map-2"]["lighting"]["ambient"], j["sessions"]["map"]["lighting"]["ambient"]);

  // The same seed with one map session of 3 frames and one query session: identical "map" and
  // "query" images and poses.
  WorldOptions one = small(4);
  one.map_frames = 3;
  one.query_frames = 1;
  write_world(one, root_ / "one");
  const auto multi_files = read_tree(root_ / "multi"), one_files = read_tree(root_ / "one");
  for (const char* name :
       {"images/map/000000.png", "images/map/000002.png", "depth/map/000001.png", "images/query/000000.png"}) {
    ASSERT_TRUE(multi_files.count(name)) << name;
    EXPECT_EQ(multi_files.at(name), one_files.at(name)) << name;
  }
  EXPECT_NE(multi_files.at("images/map-2/000000.png"), one_files.at("images/map/000000.png"));
  const ColmapModel m1 = read_colmap_text(root_ / "one" / "sparse");
  EXPECT_EQ(m1.images[1].cam_from_world.translation, m.images[1].cam_from_world.translation);
  // Rendering is deterministic for a seed.
  write_world(o, root_ / "again");
  EXPECT_EQ(read_tree(root_ / "again"), multi_files);
}

TEST_F(WorldWriterTest, ReplacesAPreviousWorldButNotForeignFolders) {
  write_world(small(1), root_ / "w");
  write_world(small(2), root_ / "w");
  std::ifstream f(root_ / "w" / "world.json");
  EXPECT_EQ(nlohmann::json::parse(f)["seed"], 2);
  fs::create_directories(root_ / "foreign");
  std::ofstream(root_ / "foreign" / "thesis.tex") << "precious";
  EXPECT_THROW(write_world(small(1), root_ / "foreign"), Error);
  EXPECT_TRUE(fs::exists(root_ / "foreign" / "thesis.tex"));
}

TEST_F(WorldWriterTest, BadOptionsAndUnwritableFoldersThrow) {
  WorldOptions o = small(1);
  o.map_frames = 0;
  EXPECT_THROW(write_world(o, root_ / "x"), Error);
  o = small(1);
  o.query_frames = 0;
  EXPECT_THROW(write_world(o, root_ / "x"), Error);
  EXPECT_FALSE(fs::exists(root_ / "x"));
  EXPECT_THROW(world_preset("enormous"), Error);
  // A file in the way of the output folder's parent, and a folder under /proc.
  std::ofstream(root_ / "file") << "x";
  EXPECT_THROW(write_world(small(1), root_ / "file" / "w"), Error);
  EXPECT_THROW(write_world(small(1), "/proc/lmb_no_such_dir/w"), Error);
  try {
    write_world(small(1), root_ / "file" / "w");
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("file"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace lmb
