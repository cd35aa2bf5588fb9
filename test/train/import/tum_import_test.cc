#include "train/import/tum_import.h"

#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iomanip>

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

// The synthetic sequence's true motion: the camera centre moves linearly, (t - 100) * (1, 2, 3) m,
// and the camera turns about a fixed tilted axis at 3 rad/s from 0.5 rad.
Rigid3d true_world_from_cam(double t) {
  const double s = t - 100.0;
  const Eigen::Vector3d axis = Eigen::Vector3d(1, 0.2, 0.1).normalized();
  return Rigid3d(Eigen::Quaterniond(Eigen::AngleAxisd(0.5 + 3.0 * s, axis)), s * Eigen::Vector3d(1, 2, 3));
}

std::string stamp(double t) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.3f", t);
  return buf;
}

class TumImportTest : public ::testing::Test {
 protected:
  void SetUp() override {
    root_ = fs::temp_directory_path() / ("lmb_tum_" + std::to_string(::getpid()) + "_" +
                                         ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(root_);
    data_ = root_ / "seq";
    fs::create_directories(data_ / "rgb");
  }
  void TearDown() override { fs::remove_all(root_); }

  // Writes a TUM-like sequence. Ground truth at 10 ms from 100.00 to 100.12 and from 100.40 to
  // 100.45; accelerometer every 2 ms from 99.90 to 100.30, reading the reaction to gravity (world
  // up +z) in the Kinect frame. With gt_lag > 0 the ground truth lags the sensors: the reading at
  // t shows the pose the ground truth stamps t + gt_lag.
  void write_sequence(double gt_lag = 0.0) {
    std::ofstream rgb(data_ / "rgb.txt");
    rgb << "# color images\n# timestamp filename\n";
    const cv::Mat pixels(6, 8, CV_8UC3, cv::Scalar(10, 200, 30));
    for (double t : image_times_) {
      const std::string name = "rgb/" + stamp(t) + ".png";
      ASSERT_TRUE(cv::imwrite((data_ / name).string(), pixels));
      rgb << stamp(t) << ' ' << name << '\n';
    }
    std::ofstream gt(data_ / "groundtruth.txt");
    gt << "# ground truth trajectory\n# timestamp tx ty tz qx qy qz qw\n" << std::setprecision(17);
    auto sample = [&](double t) {
      const Rigid3d p = true_world_from_cam(t);
      const Eigen::Quaterniond& q = p.rotation;
      gt << t << ' ' << p.translation.x() << ' ' << p.translation.y() << ' ' << p.translation.z() << ' ' << q.x() << ' '
         << q.y() << ' ' << q.z() << ' ' << q.w() << '\n';
    };
    for (int k = 0; k <= 12; ++k) sample(100.0 + 0.01 * k);
    for (int k = 0; k <= 5; ++k) sample(100.4 + 0.01 * k);
    std::ofstream acc(data_ / "accelerometer.txt");
    acc << "# accelerometer data\n# timestamp ax ay az\n" << std::setprecision(17);
    for (int k = 0; k <= 200; ++k) {
      const double t = 99.9 + 0.002 * k;
      const Eigen::Vector3d up_in_cam = true_world_from_cam(t + gt_lag).rotation.conjugate() * Eigen::Vector3d::UnitZ();
      const Eigen::Vector3d a = tum_cam_from_accel().transpose() * (9.81 * up_in_cam);
      acc << t << ' ' << a.x() << ' ' << a.y() << ' ' << a.z() << '\n';
    }
  }

  TumImportOptions options(const std::string& out) const {
    TumImportOptions o;
    o.data_dirs = {data_};
    o.out_dir = root_ / out;
    return o;
  }

  fs::path root_, data_;
  // Skipped without ground truth: 99.0 (before it), 100.2 (80 ms after the last sample before
  // the gap), 100.5 (50 ms after the end). 100.425 has ground truth but no accelerometer.
  std::vector<double> image_times_ = {99.0,   100.0, 100.013, 100.033, 100.047, 100.066,
                                      100.08, 100.1, 100.2,   100.425, 100.5};
};

TEST_F(TumImportTest, InterpolationKnownValues) {
  write_sequence();
  const TumTrajectory trajectory = read_tum_trajectory(data_ / "groundtruth.txt");
  ASSERT_EQ(trajectory.time_s.size(), 19u);
  // Linear position and constant-rate rotation about a fixed axis: lerp + slerp are exact.
  for (double t : {100.0, 100.0333, 100.047, 100.1, 100.12, 100.4271}) {
    const std::optional<Rigid3d> p = interpolate_pose(trajectory, t, 0.02);
    ASSERT_TRUE(p.has_value()) << t;
    const Rigid3d truth = true_world_from_cam(t);
    EXPECT_LT((p->translation - truth.translation).norm(), 1e-9) << t;
    EXPECT_LT(p->rotation.angularDistance(truth.rotation), 1e-9) << t;
  }
  // Hand-computed: at 100.033 the centre is 0.033 * (1, 2, 3) and the angle 0.5 + 0.099 rad.
  const Rigid3d p = *interpolate_pose(trajectory, 100.033, 0.02);
  EXPECT_NEAR(p.translation.z(), 0.099, 1e-9);
  EXPECT_NEAR(Eigen::AngleAxisd(p.rotation).angle(), 0.599, 1e-9);
  // Gaps: before the first sample, after the last, and inside the 100.12..100.40 hole.
  EXPECT_FALSE(interpolate_pose(trajectory, 99.999, 0.02));
  EXPECT_FALSE(interpolate_pose(trajectory, 100.451, 0.02));
  EXPECT_FALSE(interpolate_pose(trajectory, 100.2, 0.02));
  EXPECT_FALSE(interpolate_pose(trajectory, 100.139, 0.02).has_value());  // 100.40 is 261 ms away
  EXPECT_TRUE(interpolate_pose(trajectory, 100.139, 0.3).has_value());
}

// Several sequences into one collection: each map sequence a map session (and its split-off frames a
// query session), each query sequence a query session; sessions.txt lists them; names default to
// the folders' names, can be given, and must be unique.
TEST_F(TumImportTest, JoinsSequencesIntoSessions) {
  write_sequence();
  for (const char* copy : {"seq_b", "seq_c"}) {
    fs::create_directories(root_ / copy);
    fs::copy(data_, root_ / copy, fs::copy_options::recursive);
  }
  TumImportOptions o = options("joined");
  o.data_dirs = {data_, root_ / "seq_b"};
  o.query_dirs = {root_ / "seq_c"};
  o.gravity = "none";
  o.split = "every:2";
  const TumImportStats s = import_tum(o);
  EXPECT_EQ(s.imported_frames, 24);
  EXPECT_EQ(s.map_frames, 8);  // frames 0, 2, 4, 6 of each map sequence
  EXPECT_EQ(s.query_frames, 16);
  const std::vector<MapSession> sessions = read_session_file(o.out_dir / "sessions.txt");
  const std::vector<std::string> names = {"seq", "seq-query", "seq_b", "seq_b-query", "seq_c"};
  ASSERT_EQ(sessions.size(), names.size());
  ASSERT_EQ(s.sessions.size(), names.size());
  for (size_t i = 0; i < names.size(); ++i) {
    EXPECT_EQ(sessions[i].name, names[i]);
    EXPECT_EQ(sessions[i].kind, i % 2 == 0 && i < 4 ? SessionKind::kMap : SessionKind::kQuery) << names[i];
  }
  EXPECT_EQ(s.session_frames, (std::vector<int>{4, 4, 4, 4, 8}));
  const ColmapModel m = read_colmap_text(o.out_dir / "sparse");
  ASSERT_EQ(m.images.size(), 24u);
  EXPECT_EQ(m.images[0].name, "seq/100.000.png");
  EXPECT_EQ(m.images[1].name, "seq-query/100.013.png");
  EXPECT_EQ(m.images[8].name, "seq_b/100.000.png");
  EXPECT_EQ(m.images[16].name, "seq_c/100.000.png");
  EXPECT_EQ(m.images[23].name, "seq_c/100.425.png");
  EXPECT_TRUE(fs::equivalent(o.out_dir / "images" / m.images[16].name, root_ / "seq_c" / "rgb" / "100.000.png"));
  for (size_t i = 0; i < 24; ++i) EXPECT_EQ(m.images[i].image_id, static_cast<int>(i) + 1);
  EXPECT_EQ(image_sessions(sessions, m, o.out_dir / "sessions.txt").back(), 4);

  // Given names; a time rule counts from each sequence's first frame.
  o.out_dir = root_ / "named";
  o.session_names = {"day1", "day2", "evening"};
  o.split = "time:0:0.04";
  const TumImportStats named = import_tum(o);
  EXPECT_EQ(named.map_frames, 6);
  EXPECT_EQ(named.sessions[2].name, "day2");
  EXPECT_EQ(named.sessions[4].name, "evening");
  // A list rule over several map sequences: each entry must name a frame of one of them.
  o.out_dir = root_ / "listed";
  o.split = "list:" + (root_ / "list.txt").string();
  std::ofstream(root_ / "list.txt") << "100.013\n";
  EXPECT_EQ(import_tum(o).map_frames, 2);  // the entry names a frame of both sequences: once each is fine
  std::ofstream(root_ / "list.txt") << "100.013\n100.999\n";
  o.out_dir = root_ / "listed2";
  EXPECT_THROW(import_tum(o), Error);

  // Two sequences whose folders share a name, a name list of the wrong size, a bad name.
  o = options("clash");
  fs::create_directories(root_ / "other");
  fs::copy(data_, root_ / "other" / "seq", fs::copy_options::recursive);
  o.data_dirs = {data_, root_ / "other" / "seq"};
  o.gravity = "none";
  try {
    import_tum(o);
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("session name 'seq' is already used"), std::string::npos) << e.what();
  }
  o.session_names = {"a"};
  EXPECT_THROW(import_tum(o), Error);
  o.session_names = {"a", "b c"};
  EXPECT_THROW(import_tum(o), Error);
  EXPECT_FALSE(fs::exists(root_ / "clash" / "sparse"));
}

TEST_F(TumImportTest, ImportsCountsSplitsAndLinks) {
  write_sequence();
  TumImportOptions o = options("c");
  o.gravity = "groundtruth-up";
  const TumImportStats s = import_tum(o);
  EXPECT_EQ(s.listed_frames, 11);
  EXPECT_EQ(s.skipped_no_pose, 3);
  EXPECT_EQ(s.skipped_no_accelerometer, 0);
  EXPECT_EQ(s.imported_frames, 8);
  // every:3 over the 8 imported frames: 0, 3, 6 are map frames.
  EXPECT_EQ(s.map_frames, 3);
  EXPECT_EQ(s.query_frames, 5);

  ColmapFormat format = ColmapFormat::kBinary;
  const ColmapModel m = read_colmap_model(o.out_dir / "sparse", &format);
  EXPECT_EQ(format, ColmapFormat::kText);
  ASSERT_EQ(m.cameras.size(), 1u);
  EXPECT_EQ(m.cameras.at(1).model, CameraModel::kFullOpenCV);
  EXPECT_EQ(m.cameras.at(1).params[8], 1.1633);
  ASSERT_EQ(m.images.size(), 8u);
  const std::vector<std::string> expected = {"map/100.000.png", "query/100.013.png", "query/100.033.png",
                                             "map/100.047.png", "query/100.066.png", "query/100.080.png",
                                             "map/100.100.png", "query/100.425.png"};
  for (size_t i = 0; i < 8; ++i) {
    EXPECT_EQ(m.images[i].name, expected[i]);
    const fs::path link = o.out_dir / "images" / m.images[i].name;
    EXPECT_TRUE(fs::is_symlink(link)) << link;
    EXPECT_TRUE(fs::read_symlink(link).is_absolute()) << link;
    EXPECT_TRUE(fs::equivalent(link, data_ / "rgb" / (m.images[i].name.substr(m.images[i].name.find('/') + 1))));
  }
  check_collection_images(m, o.out_dir / "images");
  // cam_from_world is the inverse of TUM's world_from_cam, interpolated at the image time.
  const Rigid3d truth = true_world_from_cam(100.033).inverse();
  EXPECT_LT(m.images[2].cam_from_world.rotation.angularDistance(truth.rotation), 1e-9);
  EXPECT_LT((m.images[2].cam_from_world.translation - truth.translation).norm(), 1e-9);
  // Gravity from the ground truth: cam_from_world * (0, 0, -1).
  const auto g = read_gravity_file(o.out_dir / "gravity.txt", m);
  EXPECT_LT((g.at("query/100.033.png") - truth.rotation * Eigen::Vector3d(0, 0, -1)).norm(), 1e-9);

  // A time offset shifts the ground-truth lookup: image 100.033 gets the pose of 100.037.
  o.out_dir = root_ / "shifted";
  o.time_offset_s = 0.004;
  import_tum(o);
  const ColmapModel shifted = read_colmap_text(o.out_dir / "sparse");
  EXPECT_LT(shifted.images[2].cam_from_world.rotation.angularDistance(true_world_from_cam(100.037).inverse().rotation),
            1e-9);

  // Other split rules.
  o.time_offset_s = 0;
  o.overwrite = true;
  o.split = "first:0.5";
  EXPECT_EQ(import_tum(o).map_frames, 4);
  o.split = "time:0:0.04";  // 100.000, 100.013, 100.033
  EXPECT_EQ(import_tum(o).map_frames, 3);
  const fs::path list = root_ / "list.txt";
  std::ofstream(list) << "100.013\nrgb/100.080.png\n100.425.png\n";
  o.split = "list:" + list.string();
  const TumImportStats listed = import_tum(o);
  EXPECT_EQ(listed.map_frames, 3);
  const ColmapModel lm = read_colmap_text(o.out_dir / "sparse");
  EXPECT_EQ(lm.images[1].name, "map/100.013.png");
  EXPECT_EQ(lm.images[5].name, "map/100.080.png");
  EXPECT_EQ(lm.images[7].name, "map/100.425.png");
  EXPECT_EQ(lm.images[0].name, "query/100.000.png");

  // An existing output is not overwritten by accident.
  o.overwrite = false;
  try {
    import_tum(o);
    ADD_FAILURE() << "existing output overwritten";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("exists and is not empty"), std::string::npos) << e.what();
  }
}

TEST_F(TumImportTest, AccelerometerGravityPointsDownInTheCameraFrame) {
  write_sequence();
  TumImportOptions o = options("c");
  const TumImportStats s = import_tum(o);
  EXPECT_EQ(s.skipped_no_accelerometer, 1);  // 100.425
  EXPECT_EQ(s.imported_frames, 7);
  const ColmapModel m = read_colmap_text(o.out_dir / "sparse");
  const auto g = read_gravity_file(o.out_dir / "gravity.txt", m);
  for (const ColmapImage& im : m.images) {
    // Gravity points down: the world's -z seen from the camera, within the averaging blur.
    const Eigen::Vector3d truth = im.cam_from_world.rotation * Eigen::Vector3d(0, 0, -1);
    EXPECT_LT(std::acos(std::min(1.0, g.at(im.name).dot(truth))) * 180 / M_PI, 0.5) << im.name;
  }
  ASSERT_TRUE(s.gravity_agreement.has_value());
  const GravityAgreement& a = *s.gravity_agreement;
  EXPECT_EQ(a.frames, 7);
  EXPECT_LT(a.median_deg, 0.5);
  EXPECT_LT(a.median_deg_by_world_axis[4], 0.5);  // +z
  EXPECT_GT(a.median_deg_by_world_axis[5], 179);  // -z
  EXPECT_LT(a.fitted_rotation_offset_deg, 5.0);
  EXPECT_NEAR(a.best_time_offset_s, 0.0, 1e-9);
}

TEST_F(TumImportTest, TimeOffsetScanFindsALaggingGroundTruth) {
  write_sequence(/*gt_lag=*/0.015);
  TumImportOptions o = options("c");
  o.gravity = "none";
  o.max_gap_s = 0.02;
  const TumImportStats s = import_tum(o);
  ASSERT_TRUE(s.gravity_agreement.has_value());
  EXPECT_NEAR(s.gravity_agreement->best_time_offset_s, 0.015, 1e-9);
  EXPECT_FALSE(fs::exists(o.out_dir / "gravity.txt"));
}

TEST_F(TumImportTest, MalformedInputsFailWithFileAndLine) {
  write_sequence();
  auto error = [&](const TumImportOptions& o) -> std::string {
    try {
      import_tum(o);
    } catch (const Error& e) {
      return e.what();
    }
    return "";
  };
  TumImportOptions o = options("c");
  std::ofstream(data_ / "groundtruth.txt", std::ios::app) << "100.5 0 0 0 0.5 0.5 0.5 0.6\n";
  EXPECT_NE(error(o).find("groundtruth.txt line 22: quaternion is not a rotation"), std::string::npos) << error(o);
  write_sequence();
  std::ofstream(data_ / "groundtruth.txt", std::ios::app) << "100.3 0 0 0 0 0 0 1\n";
  EXPECT_NE(error(o).find("groundtruth.txt line 22: timestamp 100.3 is not after the previous one"), std::string::npos)
      << error(o);
  write_sequence();
  std::ofstream(data_ / "accelerometer.txt", std::ios::app) << "200 1 nan 2\n";
  EXPECT_NE(error(o).find("accelerometer.txt line 204: ay is not finite"), std::string::npos) << error(o);
  write_sequence();
  fs::remove(data_ / "rgb" / "100.047.png");
  EXPECT_NE(error(o).find("100.047.png: image listed in rgb.txt is missing"), std::string::npos) << error(o);
  o.gravity = "up";
  EXPECT_NE(error(o).find("--gravity: 'up'"), std::string::npos);
  o.gravity = "accelerometer";
  o.split = "every:0";
  EXPECT_NE(error(o).find("N must be an integer"), std::string::npos);
  o.split = "every:3";
  o.camera = "OPENCV_FISHEYE 640 480 500 500 320 240 0 0 0 0";
  EXPECT_NE(error(o).find("unsupported camera model 'OPENCV_FISHEYE'"), std::string::npos) << error(o);
}

// The real sequence, when the shared data is there.
TEST(TumImportRealData, Freiburg1RpyImportsAndReadsBack) {
  const char* shared = std::getenv("LMB_SHARED_DATA");
  const fs::path data = shared ? fs::path(shared) / "tum_fr1_rpy" : fs::path();
  if (data.empty() || !fs::exists(data / "rgb.txt")) {
    GTEST_SKIP() << "LMB_SHARED_DATA/tum_fr1_rpy not found (set LMB_SHARED_DATA to the folder holding "
                    "tum_fr1_rpy; ctest sets it from the CMake cache variable LMB_SHARED_DATA)";
  }
  const fs::path out = fs::temp_directory_path() / ("lmb_tum_real_" + std::to_string(::getpid()));
  fs::remove_all(out);
  TumImportOptions o;
  o.data_dirs = {data};
  o.out_dir = out;
  const TumImportStats s = import_tum(o);
  // 723 frames; 7 fall into the motion-capture dropouts around t = 1305031244.8-245.1 (gaps of
  // 30-130 ms) and are skipped; the accelerometer covers every frame.
  EXPECT_EQ(s.listed_frames, 723);
  EXPECT_EQ(s.skipped_no_pose, 7);
  EXPECT_EQ(s.skipped_no_accelerometer, 0);
  EXPECT_EQ(s.imported_frames, 716);
  EXPECT_EQ(s.map_frames, 239);  // every:3 over 716
  EXPECT_EQ(s.query_frames, 477);
  const ColmapModel m = read_colmap_model(out / "sparse");
  EXPECT_EQ(m.images.size(), 716u);
  check_collection_images(m, out / "images");
  EXPECT_EQ(read_gravity_file(out / "gravity.txt", m).size(), 716u);
  // The accelerometer agrees with the motion-capture vertical (+z) to a few degrees, and +z is
  // the best of the six axes.
  ASSERT_TRUE(s.gravity_agreement.has_value());
  const GravityAgreement& a = *s.gravity_agreement;
  std::printf(
      "accelerometer vs mocap gravity: median %.2f deg, mean %.2f, p90 %.2f; by axis +x %.1f -x %.1f "
      "+y %.1f -y %.1f +z %.1f -z %.1f; best offset %+.3f s (%.2f deg); fitted rotation %.2f deg off "
      "(median %.2f deg after)\n",
      a.median_deg, a.mean_deg, a.p90_deg, a.median_deg_by_world_axis[0], a.median_deg_by_world_axis[1],
      a.median_deg_by_world_axis[2], a.median_deg_by_world_axis[3], a.median_deg_by_world_axis[4],
      a.median_deg_by_world_axis[5], a.best_time_offset_s, a.best_time_offset_median_deg, a.fitted_rotation_offset_deg,
      a.fitted_median_deg);
  EXPECT_LT(a.median_deg, 10.0);
  for (int k = 0; k < 6; ++k) {
    if (k != 4) {
      EXPECT_GT(a.median_deg_by_world_axis[k], 30.0) << k;
    }
  }
  fs::remove_all(out);
}

}  // namespace
}  // namespace lmb
