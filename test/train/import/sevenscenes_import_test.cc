#include "train/import/sevenscenes_import.h"

#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "common/error.h"
#include "common/io/colmap_model.h"
#include "common/io/gravity_file.h"
#include "common/io/session_file.h"

namespace lmb {
namespace {

namespace fs = std::filesystem;

// The synthetic recording's camera-to-world pose of frame k: upright cameras (world down = +y)
// turning about the vertical and pitching slightly, moving along a line.
Rigid3d true_world_from_cam(int k) {
  const Eigen::Quaterniond r(Eigen::AngleAxisd(0.2 * k, Eigen::Vector3d::UnitY()) *
                             Eigen::AngleAxisd(0.1 + 0.01 * k, Eigen::Vector3d::UnitX()));
  return Rigid3d(r.normalized(), Eigen::Vector3d(0.1 * k, -0.05 * k, 0.3));
}

Eigen::Matrix4d matrix(const Rigid3d& p) {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.topLeftCorner<3, 3>() = p.rotation.toRotationMatrix();
  m.block<3, 1>(0, 3) = p.translation;
  return m;
}

void write_text(const fs::path& path, const std::string& text) {
  std::ofstream out(path, std::ios::trunc);
  out << text;
}

// A pose file as 7-Scenes writes it: 4 rows of 4 numbers.
void write_pose(const fs::path& path, const Eigen::Matrix4d& m) {
  std::ostringstream s;
  s.precision(17);
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) s << (c ? "\t" : "") << m(r, c);
    s << "\n";
  }
  write_text(path, s.str());
}

std::string frame_name(int k, const char* suffix) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "frame-%06d%s", k, suffix);
  return buf;
}

class SevenScenesImportTest : public ::testing::Test {
 protected:
  void SetUp() override {
    root_ = fs::temp_directory_path() / ("lmb_7scenes_" + std::to_string(::getpid()) + "_" +
                                         ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(root_);
    data_ = root_ / "scene";
    fs::create_directories(data_);
  }
  void TearDown() override { fs::remove_all(root_); }

  // Frames 0..count-1: images (8x6 PNG) in image_dir, poses in pose_dir.
  void write_frames(const fs::path& image_dir, const fs::path& pose_dir, int count) {
    fs::create_directories(image_dir);
    fs::create_directories(pose_dir);
    const cv::Mat pixels(6, 8, CV_8UC3, cv::Scalar(10, 200, 30));
    for (int k = 0; k < count; ++k) {
      ASSERT_TRUE(cv::imwrite((image_dir / frame_name(k, ".color.png")).string(), pixels));
      write_pose(pose_dir / frame_name(k, ".pose.txt"), matrix(true_world_from_cam(k)));
    }
  }
  // The redistributed layout: DIR/rgb, DIR/pose, camera-intrinsics.txt, gravity-direction.txt.
  void write_rgb_pose_scene(int count = 10) {
    write_frames(data_ / "rgb", data_ / "pose", count);
    write_text(data_ / "camera-intrinsics.txt", "5 0 4\n0 5.5 3\n0 0 1\n");
    write_text(data_ / "gravity-direction.txt", "0\n1\n0\n");
  }

  SevenScenesImportOptions options(const std::string& map, const std::string& query, const std::string& out = "c") {
    SevenScenesImportOptions o;
    o.data_dir = data_;
    o.out_dir = root_ / out;
    o.map_frames = map;
    o.query_frames = query;
    return o;
  }

  // The error of an import, the data folder written as DIR ("(accepted)" when it succeeds).
  std::string error(const SevenScenesImportOptions& o) const {
    try {
      import_sevenscenes(o);
    } catch (const Error& e) {
      std::string m = e.what();
      const std::string d = data_.string();
      for (size_t at = m.find(d); at != std::string::npos; at = m.find(d, at)) m.replace(at, d.size(), "DIR");
      return m;
    }
    return "(accepted)";
  }

  fs::path root_, data_;
};

TEST_F(SevenScenesImportTest, PosesRoundTripIntoMapAndQuerySessions) {
  write_rgb_pose_scene();
  // Frame 7 lost its track: 7-Scenes writes inf.
  write_text(data_ / "pose" / frame_name(7, ".pose.txt"),
             "-inf -inf -inf -inf\n-inf -inf -inf -inf\n-inf -inf -inf -inf\n0 0 0 1\n");
  const SevenScenesImportOptions o = options("0-4", "5-9");
  const SevenScenesImportStats s = import_sevenscenes(o);
  EXPECT_EQ(s.layout, "rgb/ and pose/ folders");
  EXPECT_EQ(s.selected_frames, 10);
  EXPECT_EQ(s.imported_frames, 9);
  EXPECT_EQ(s.map_frames, 5);
  EXPECT_EQ(s.query_frames, 4);
  EXPECT_EQ(s.skipped_invalid_pose, 1);
  ASSERT_EQ(s.skipped_poses.size(), 1u);
  EXPECT_EQ(fs::path(s.skipped_poses[0]).filename(), "frame-000007.pose.txt");
  EXPECT_EQ(s.camera_source, (data_ / "camera-intrinsics.txt").string());
  EXPECT_EQ(s.camera.params, (std::vector<double>{5, 5.5, 4, 3}));

  // Sessions: map frames in the map session, query frames in the query session.
  const std::vector<MapSession> sessions = read_session_file(o.out_dir / "sessions.txt");
  ASSERT_EQ(sessions.size(), 2u);
  EXPECT_EQ(sessions[0].name, "map");
  EXPECT_EQ(sessions[0].kind, SessionKind::kMap);
  EXPECT_EQ(sessions[1].name, "query");
  EXPECT_EQ(sessions[1].kind, SessionKind::kQuery);
  EXPECT_EQ(s.session_frames, (std::vector<int>{5, 4}));

  const ColmapModel m = read_colmap_model(o.out_dir / "sparse");
  ASSERT_EQ(m.cameras.size(), 1u);
  const Camera& camera = m.cameras.at(1);
  EXPECT_EQ(camera.model, CameraModel::kPinhole);
  EXPECT_EQ(camera.width, 8);
  EXPECT_EQ(camera.height, 6);
  EXPECT_EQ(camera.params, (std::vector<double>{5, 5.5, 4, 3}));
  ASSERT_EQ(m.images.size(), 9u);
  const std::vector<int> frames = {0, 1, 2, 3, 4, 5, 6, 8, 9};
  const auto gravity = read_gravity_file(o.out_dir / "gravity.txt", m);
  for (size_t i = 0; i < frames.size(); ++i) {
    const ColmapImage& im = m.images[i];
    const int k = frames[i];
    EXPECT_EQ(im.name, std::string(k < 5 ? "map/" : "query/") + frame_name(k, ".color.png"));
    const fs::path link = o.out_dir / "images" / im.name;
    EXPECT_TRUE(fs::is_symlink(link)) << link;
    EXPECT_TRUE(fs::equivalent(link, data_ / "rgb" / frame_name(k, ".color.png"))) << link;
    // cam_from_world is the inverse of the given camera-to-world matrix.
    const Eigen::Matrix4d expected = matrix(true_world_from_cam(k)).inverse();
    EXPECT_LT((matrix(im.cam_from_world) - expected).cwiseAbs().maxCoeff(), 1e-9) << im.name;
    // Gravity: the world's down (+y) seen from the camera.
    EXPECT_LT((gravity.at(im.name) - im.cam_from_world.rotation * Eigen::Vector3d::UnitY()).norm(), 1e-9);
  }
  check_collection_images(m, o.out_dir / "images");
  // Upright cameras pitched 0.1-0.19 rad: their image down axes lie 5.7-10.9 deg from gravity.
  EXPECT_NEAR(s.image_down_median_deg, (0.1 + 0.01 * 4) * 180 / M_PI, 1e-6);
}

TEST_F(SevenScenesImportTest, ListsStridesAndSingleFrames) {
  write_rgb_pose_scene();
  SevenScenesImportOptions o = options("0-4, 8", "5");
  o.stride = 2;
  const SevenScenesImportStats s = import_sevenscenes(o);
  EXPECT_EQ(s.map_frames, 4);  // 0, 2, 4, 8
  EXPECT_EQ(s.query_frames, 1);
  const ColmapModel m = read_colmap_text(o.out_dir / "sparse");
  std::vector<std::string> names;
  for (const ColmapImage& im : m.images) names.push_back(im.name);
  EXPECT_EQ(names, (std::vector<std::string>{"map/frame-000000.color.png", "map/frame-000002.color.png",
                                             "map/frame-000004.color.png", "map/frame-000008.color.png",
                                             "query/frame-000005.color.png"}));
  // Without query frames: one map session. --gravity none: no gravity.txt.
  o = options("1-3", "", "map_only");
  o.gravity = "none";
  const SevenScenesImportStats only = import_sevenscenes(o);
  EXPECT_EQ(only.sessions.size(), 1u);
  EXPECT_EQ(only.query_frames, 0);
  EXPECT_FALSE(fs::exists(o.out_dir / "gravity.txt"));
  // An existing output is kept unless --overwrite.
  EXPECT_NE(error(o).find("exists and is not empty"), std::string::npos) << error(o);
  o.overwrite = true;
  EXPECT_EQ(error(o), "(accepted)");
}

// The original 7-Scenes layout: sequence folders holding the frames and, beside each image, its pose.
TEST_F(SevenScenesImportTest, SequenceFoldersBecomeSessions) {
  write_frames(data_ / "seq-01", data_ / "seq-01", 6);
  write_frames(data_ / "seq-02", data_ / "seq-02", 4);
  fs::create_directories(data_ / "notes");  // not a sequence: no frames
  SevenScenesImportOptions o = options("seq-01", "seq-02");
  o.focal = 5;  // 7-Scenes ships no camera-intrinsics.txt
  const SevenScenesImportStats s = import_sevenscenes(o);
  EXPECT_EQ(s.layout, "sequence folders");
  EXPECT_EQ(s.map_frames, 6);
  EXPECT_EQ(s.query_frames, 4);
  EXPECT_EQ(s.camera.params, (std::vector<double>{5, 5, 4, 3}));  // cx, cy: the image centre
  EXPECT_FALSE(s.gravity_down_world.has_value());
  EXPECT_FALSE(fs::exists(o.out_dir / "gravity.txt"));
  std::vector<MapSession> sessions = read_session_file(o.out_dir / "sessions.txt");
  ASSERT_EQ(sessions.size(), 2u);
  EXPECT_EQ(sessions[0].name, "seq-01");
  EXPECT_EQ(sessions[0].kind, SessionKind::kMap);
  EXPECT_EQ(sessions[1].name, "seq-02");
  EXPECT_EQ(sessions[1].kind, SessionKind::kQuery);
  const ColmapModel m = read_colmap_text(o.out_dir / "sparse");
  EXPECT_EQ(m.images[7].name, "seq-02/frame-000001.color.png");
  EXPECT_TRUE(fs::equivalent(o.out_dir / "images" / m.images[7].name, data_ / "seq-02" / "frame-000001.color.png"));
  EXPECT_LT((matrix(m.images[7].cam_from_world) - matrix(true_world_from_cam(1)).inverse()).cwiseAbs().maxCoeff(),
            1e-9);

  // One sequence split by frame numbers: its query frames form NAME-query; --gravity-up.
  o = options("seq-01:0-2", "seq-01:3-5,seq-02", "split");
  o.focal = 5;
  o.cx = 3.5;
  o.cy = 2.5;
  o.gravity_up = Eigen::Vector3d(0, -2, 0);
  const SevenScenesImportStats split = import_sevenscenes(o);
  EXPECT_EQ(split.camera.params, (std::vector<double>{5, 5, 3.5, 2.5}));
  sessions = read_session_file(o.out_dir / "sessions.txt");
  ASSERT_EQ(sessions.size(), 3u);
  EXPECT_EQ(sessions[0].name, "seq-01");
  EXPECT_EQ(sessions[1].name, "seq-01-query");
  EXPECT_EQ(sessions[1].kind, SessionKind::kQuery);
  EXPECT_EQ(sessions[2].name, "seq-02");
  EXPECT_EQ(split.session_frames, (std::vector<int>{3, 3, 4}));
  const ColmapModel sm = read_colmap_text(o.out_dir / "sparse");
  const auto gravity = read_gravity_file(o.out_dir / "gravity.txt", sm);
  EXPECT_LT((gravity.at("seq-01-query/frame-000004.color.png") -
             true_world_from_cam(4).rotation.conjugate() * Eigen::Vector3d::UnitY())
                .norm(),
            1e-9);
}

// 12-Scenes: frames and poses together in data/, the camera from a K file elsewhere.
TEST_F(SevenScenesImportTest, FramesDirectlyInTheFolder) {
  write_frames(data_, data_, 5);
  write_text(root_ / "k.txt", "6 0 4\n0 6 3\n0 0 1\n");
  SevenScenesImportOptions o = options("0-2", "3-4");
  o.intrinsics_file = root_ / "k.txt";
  const SevenScenesImportStats s = import_sevenscenes(o);
  EXPECT_EQ(s.layout, "frames in the folder");
  EXPECT_EQ(s.imported_frames, 5);
  EXPECT_EQ(s.camera.params, (std::vector<double>{6, 6, 4, 3}));
  EXPECT_EQ(s.camera_source, (root_ / "k.txt").string());
}

TEST_F(SevenScenesImportTest, FlagsOverrideTheIntrinsicsFile) {
  write_rgb_pose_scene(4);
  SevenScenesImportOptions o = options("0-1", "2-3");
  o.focal = 4.5;
  const SevenScenesImportStats s = import_sevenscenes(o);
  EXPECT_EQ(s.camera.params, (std::vector<double>{4.5, 4.5, 4, 3}));
  EXPECT_NE(s.camera_source.find("instead of " + (data_ / "camera-intrinsics.txt").string()), std::string::npos)
      << s.camera_source;
}

TEST_F(SevenScenesImportTest, NonFiniteEntriesSkipTheirFrame) {
  write_rgb_pose_scene(6);
  write_text(data_ / "pose" / frame_name(1, ".pose.txt"), "1 0 0 nan\n0 1 0 0\n0 0 1 0\n0 0 0 1\n");
  write_text(data_ / "pose" / frame_name(4, ".pose.txt"), "1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 inf\n");
  const SevenScenesImportStats s = import_sevenscenes(options("0-2", "3-5"));
  EXPECT_EQ(s.skipped_invalid_pose, 2);
  EXPECT_EQ(s.map_frames, 2);
  EXPECT_EQ(s.query_frames, 2);
  // A pose within the orthonormality tolerance (tracking rounding) is projected onto a rotation.
  Eigen::Matrix4d rounded = matrix(true_world_from_cam(2));
  rounded(0, 0) += 4e-4;
  write_pose(data_ / "pose" / frame_name(2, ".pose.txt"), rounded);
  const std::optional<Rigid3d> p = read_sevenscenes_pose(data_ / "pose" / frame_name(2, ".pose.txt"));
  ASSERT_TRUE(p.has_value());
  EXPECT_LT(p->rotation.angularDistance(true_world_from_cam(2).rotation), 1e-3);
  EXPECT_NEAR(p->rotation.norm(), 1.0, 1e-12);
}

// Every refusal of `lboost import 7scenes`: one line naming the file or option and the reason, as
// docs/input_validation.md lists it ("Commands", DIR: the --data folder).
struct Refusal {
  std::string defect;
  // Breaks the scene in `data` (10 frames, map 0-4, query 5-9) and the options `o`.
  std::function<void(const fs::path& data, SevenScenesImportOptions& o)> setup;
  std::string message;
};

std::vector<Refusal> refusals() {
  const auto pose = [](const fs::path& data, int k, const std::string& text) {
    write_text(data / "pose" / frame_name(k, ".pose.txt"), text);
  };
  return {
      {"a pose file of 3 rows",
       [=](const fs::path& d, SevenScenesImportOptions& o) { pose(d, 3, "1 0 0 0\n0 1 0 0\n0 0 1 0\n"); },
       "DIR/pose/frame-000003.pose.txt: expected 4 rows of 4 numbers (a 4x4 camera-to-world matrix), got 3 rows"},
      {"a pose row of 3 numbers",
       [=](const fs::path& d, SevenScenesImportOptions& o) { pose(d, 3, "1 0 0 0\n0 1 0\n0 0 1 0\n0 0 0 1\n"); },
       "DIR/pose/frame-000003.pose.txt line 2: expected 4 numbers (a row of the 4x4 camera-to-world matrix), got 3"},
      {"a pose entry that is not a number",
       [=](const fs::path& d, SevenScenesImportOptions& o) { pose(d, 3, "1 0 0 0\n0 1 0 0\n0 0 1 0,5\n0 0 0 1\n"); },
       "DIR/pose/frame-000003.pose.txt line 3: entry 4 is not a number: '0,5'"},
      {"a pose whose last row is not 0 0 0 1 (a projection, or a transposed matrix)",
       [=](const fs::path& d, SevenScenesImportOptions& o) { pose(d, 3, "1 0 0 0\n0 1 0 0\n0 0 1 0\n0.5 0 0 1\n"); },
       "DIR/pose/frame-000003.pose.txt: last row is 0.5 0 0 1, expected 0 0 0 1 (a rigid transform)"},
      {"a pose whose rotation is scaled",
       [=](const fs::path& d, SevenScenesImportOptions& o) {
         pose(d, 3, "1.1 0 0 0\n0 1.1 0 0\n0 0 1.1 0\n0 0 0 1\n");
       },
       "DIR/pose/frame-000003.pose.txt: the rotation block is not a rotation (largest entry of R^T R - I is 0.21, "
       "tolerance 0.01)"},
      {"a pose whose rotation is a reflection",
       [=](const fs::path& d, SevenScenesImportOptions& o) { pose(d, 3, "-1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n"); },
       "DIR/pose/frame-000003.pose.txt: the rotation block is a reflection (determinant -1)"},
      {"a selected frame without a pose file",
       [=](const fs::path& d, SevenScenesImportOptions& o) { fs::remove(d / "pose" / frame_name(6, ".pose.txt")); },
       "DIR/pose/frame-000006.pose.txt: missing (the pose of DIR/rgb/frame-000006.color.png)"},
      {"no camera intrinsics: no camera-intrinsics.txt and no --intrinsics or --focal",
       [=](const fs::path& d, SevenScenesImportOptions& o) { fs::remove(d / "camera-intrinsics.txt"); },
       "DIR: no camera intrinsics (DIR/camera-intrinsics.txt is missing); give --intrinsics FILE (a 3x3 K) or "
       "--focal F [--cx CX --cy CY]"},
      {"a camera matrix with skew",
       [=](const fs::path& d, SevenScenesImportOptions& o) {
         write_text(d / "camera-intrinsics.txt", "5 0.5 4\n0 5 3\n0 0 1\n");
       },
       "DIR/camera-intrinsics.txt: skew K(1,2) is 0.5; only a camera matrix without skew is supported"},
      {"a camera matrix of 4 rows (a 4x4 matrix)",
       [=](const fs::path& d, SevenScenesImportOptions& o) {
         write_text(d / "camera-intrinsics.txt", "5 0 4\n0 5 3\n0 0 1\n0 0 0\n");
       },
       "DIR/camera-intrinsics.txt: expected 3 rows of 3 numbers (a 3x3 camera matrix K), got more"},
      {"a gravity file of 2 numbers",
       [=](const fs::path& d, SevenScenesImportOptions& o) { write_text(d / "gravity-direction.txt", "0 1\n"); },
       "DIR/gravity-direction.txt: expected 3 numbers (a world-frame vector), got 2"},
      {"a frame selected for both map and query",
       [=](const fs::path&, SevenScenesImportOptions& o) {
         o.map_frames = "0-5";
         o.query_frames = "5-9";
       },
       "--query-frames: '5-9': frame 5 is selected twice (also by --map-frames)"},
      {"a selected frame without an image",
       [=](const fs::path&, SevenScenesImportOptions& o) {
         o.map_frames = "0-4";
         o.query_frames = "5-12";
       },
       "--query-frames: '5-12': frame 10 has no image in DIR/rgb (frame-000010.color.png or .jpg)"},
      {"a range that ends before it starts",
       [=](const fs::path&, SevenScenesImportOptions& o) {
         o.map_frames = "4-0";
         o.query_frames = "5-9";
       },
       "--map-frames: '4-0': the range ends before it starts"},
      {"a sequence folder named for a folder of one recording",
       [=](const fs::path&, SevenScenesImportOptions& o) {
         o.map_frames = "seq-01";
         o.query_frames = "5-9";
       },
       "--map-frames: 'seq-01': DIR holds one recording, not sequence folders; give frame numbers such as 0-499"},
      {"every selected query frame without a finite pose",
       [=](const fs::path& d, SevenScenesImportOptions& o) {
         for (int k : {8, 9}) pose(d, k, "nan 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n");
         o.map_frames = "0-4";
         o.query_frames = "8-9";
       },
       "--query-frames '8-9': all 2 selected frames have a non-finite pose (skipped)"},
      {"`--intrinsics` and `--focal` together",
       [=](const fs::path& d, SevenScenesImportOptions& o) {
         o.intrinsics_file = d / "camera-intrinsics.txt";
         o.focal = 500;
       },
       "--intrinsics and --focal are exclusive (give the camera one way)"},
  };
}

TEST_F(SevenScenesImportTest, RefusalsAreOneLineAndDocumented) {
  const char* source = std::getenv("LMB_SOURCE_DIR");
  ASSERT_NE(source, nullptr) << "LMB_SOURCE_DIR is not set (ctest sets it)";
  std::ifstream in(fs::path(source) / "docs" / "input_validation.md");
  std::stringstream doc;
  doc << in.rdbuf();
  ASSERT_FALSE(doc.str().empty()) << "docs/input_validation.md is missing";
  for (const Refusal& r : refusals()) {
    fs::remove_all(data_);
    write_rgb_pose_scene();
    SevenScenesImportOptions o = options("0-4", "5-9");
    r.setup(data_, o);
    const std::string got = error(o);
    EXPECT_EQ(got, r.message) << r.defect;
    EXPECT_FALSE(fs::exists(o.out_dir)) << r.defect << ": the refused import left its output";
    const std::string row = "| import 7scenes | " + r.defect + " | `" + r.message + "` |";
    EXPECT_NE(doc.str().find(row), std::string::npos) << "docs/input_validation.md lacks the row\n" << row;
  }
}

TEST_F(SevenScenesImportTest, MoreRefusalsOfTheSelectionAndLayout) {
  EXPECT_EQ(error(options("0-4", "")),
            "DIR: no frames (expected rgb/frame-NNNNNN.color.png or .jpg, such frames in "
            "the folder, or sequence folders such as seq-01/ holding them)");
  write_frames(data_ / "seq-01", data_ / "seq-01", 3);
  SevenScenesImportOptions o = options("0-2", "");
  o.focal = 5;
  EXPECT_EQ(error(o), "--map-frames: '0-2': DIR holds sequence folders (seq-01); name them: NAME or NAME:FIRST-LAST");
  o.map_frames = "seq-03";
  EXPECT_EQ(error(o), "--map-frames: 'seq-03': DIR/seq-03 is not a sequence folder with frames (DIR holds seq-01)");
  o.map_frames = "seq-01,,seq-01";
  EXPECT_NE(error(o).find("--map-frames: 'seq-01,,seq-01': an empty item"), std::string::npos) << error(o);
  o.map_frames = "seq-01:2-1";
  EXPECT_EQ(error(o), "--map-frames: 'seq-01:2-1': the range ends before it starts");
  o.map_frames = "seq-01:x";
  EXPECT_EQ(error(o), "--map-frames: 'seq-01:x': expected NAME:FIRST-LAST (e.g. seq-01:0-499)");
  o.map_frames = "seq-01";
  o.stride = 0;
  EXPECT_EQ(error(o), "--stride: 0 must be >= 1");
  o.stride = 1;
  o.focal.reset();
  o.cx = 3;
  EXPECT_EQ(error(o), "--cx and --cy need --focal");
}

// The real redistributed 7-Scenes "redkitchen" recording, when the shared data is there.
TEST(SevenScenesImportRealData, RedkitchenSplitsIntoTheFirstAndSecondHalf) {
  const char* shared = std::getenv("LMB_SHARED_DATA");
  const fs::path data = shared ? fs::path(shared) / "7scenes_redkitchen" : fs::path();
  if (data.empty() || !fs::exists(data / "pose")) {
    GTEST_SKIP() << "LMB_SHARED_DATA/7scenes_redkitchen not found (set LMB_SHARED_DATA to the folder holding "
                    "7scenes_redkitchen; ctest sets it from the CMake cache variable LMB_SHARED_DATA, default "
                    "../shared/data beside the repository)";
  }
  const fs::path out = fs::temp_directory_path() / ("lmb_7scenes_real_" + std::to_string(::getpid()));
  fs::remove_all(out);
  SevenScenesImportOptions o;
  o.data_dir = data;
  o.out_dir = out;
  o.map_frames = "0-499";
  o.query_frames = "500-999";
  const SevenScenesImportStats s = import_sevenscenes(o);
  EXPECT_EQ(s.layout, "rgb/ and pose/ folders");
  EXPECT_EQ(s.selected_frames, 1000);
  EXPECT_EQ(s.skipped_invalid_pose, 0);
  EXPECT_EQ(s.map_frames, 500);
  EXPECT_EQ(s.query_frames, 500);
  EXPECT_EQ(s.session_frames, (std::vector<int>{500, 500}));
  EXPECT_EQ(s.camera.width, 640);
  EXPECT_EQ(s.camera.height, 480);
  EXPECT_EQ(s.camera.params, (std::vector<double>{585, 585, 320, 240}));
  // gravity-direction.txt points down: the hand-held cameras' image down axes lie near it.
  ASSERT_TRUE(s.gravity_down_world.has_value());
  std::printf("image down axes vs gravity-direction.txt: median %.1f deg, 10%%-90%% %.1f-%.1f deg\n",
              s.image_down_median_deg, s.image_down_p10_deg, s.image_down_p90_deg);
  EXPECT_LT(s.image_down_median_deg, 45.0);
  const ColmapModel m = read_colmap_model(out / "sparse");
  ASSERT_EQ(m.images.size(), 1000u);
  EXPECT_EQ(m.images.front().name, "map/frame-000000.color.jpg");
  EXPECT_EQ(m.images[500].name, "query/frame-000500.color.jpg");
  EXPECT_EQ(read_gravity_file(out / "gravity.txt", m).size(), 1000u);
  fs::remove_all(out);
}

}  // namespace
}  // namespace lmb
