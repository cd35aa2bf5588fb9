#include "train/import/colmap_import.h"

#include <signal.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "common/error.h"
#include "common/io/colmap_binary.h"
#include "common/io/gravity_file.h"

namespace lmb {
namespace {

namespace fs = std::filesystem;

class ColmapImportTest : public ::testing::Test {
 protected:
  void SetUp() override {
    root_ = fs::temp_directory_path() / ("lmb_colmap_import_" + std::to_string(::getpid()) + "_" +
                                         ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(root_);
    fs::create_directories(root_ / "photos" / "day1");
    Camera c;
    c.model = CameraModel::kSimpleRadial;
    c.width = 8;
    c.height = 6;
    c.params = {10, 4, 3, -0.01};
    model_.cameras[2] = c;
    const cv::Mat pixels(6, 8, CV_8UC1, cv::Scalar(99));
    // Ids in reverse name order, to see that the split follows names.
    for (int i = 0; i < 5; ++i) {
      ColmapImage im;
      im.image_id = 50 - i;
      im.camera_id = 2;
      im.name = "day1/img_" + std::to_string(i) + ".jpg";
      im.cam_from_world.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(0.2 * i, Eigen::Vector3d::UnitX()));
      im.cam_from_world.translation = Eigen::Vector3d(i, 0, 0);
      im.points2d = {{Eigen::Vector2d(1, 2), -1}};
      model_.images.push_back(im);
      ASSERT_TRUE(cv::imwrite((root_ / "photos" / im.name).string(), pixels));
    }
  }
  void TearDown() override { fs::remove_all(root_); }

  ColmapImportOptions options() const {
    ColmapImportOptions o;
    o.sparse_dir = root_ / "sparse";
    o.image_dir = root_ / "photos";
    o.out_dir = root_ / "collection";
    return o;
  }
  std::string error(const ColmapImportOptions& o) {
    try {
      import_colmap(o);
    } catch (const Error& e) {
      return e.what();
    }
    return "";
  }

  fs::path root_;
  ColmapModel model_;
};

TEST_F(ColmapImportTest, BinaryModelWithSplitAndUpAxis) {
  write_colmap_binary(model_, root_ / "sparse");
  ColmapImportOptions o = options();
  o.split = "every:2";
  o.up = "-y";
  const ColmapImportStats s = import_colmap(o);
  EXPECT_TRUE(s.binary);
  EXPECT_EQ(s.images, 5);
  EXPECT_EQ(s.map_frames, 3);  // img_0, img_2, img_4 by name
  EXPECT_EQ(s.query_frames, 2);
  const ColmapModel r = read_colmap_text(o.out_dir / "sparse");
  ASSERT_EQ(r.images.size(), 5u);
  for (const ColmapImage& im : r.images) {
    const int i = 50 - im.image_id;
    EXPECT_EQ(im.name, std::string(i % 2 ? "query/" : "map/") + "day1/img_" + std::to_string(i) + ".jpg");
    EXPECT_TRUE(im.points2d.empty());
  }
  check_collection_images(r, o.out_dir / "images");
  const auto g = read_gravity_file(o.out_dir / "gravity.txt", r);
  // Up is -y, so gravity is +y in the world, seen from each camera.
  for (const ColmapImage& im : r.images) {
    EXPECT_LT((g.at(im.name) - im.cam_from_world.rotation * Eigen::Vector3d(0, 1, 0)).norm(), 1e-12);
  }
}

TEST_F(ColmapImportTest, GravityFileIsRenamedWithTheSplit) {
  write_colmap_text(model_, root_ / "sparse");
  std::map<std::string, Eigen::Vector3d> gravity;
  for (const ColmapImage& im : model_.images) gravity[im.name] = Eigen::Vector3d(0, 1, 0.1 * im.image_id);
  write_gravity_file(gravity, root_ / "g.txt");
  ColmapImportOptions o = options();
  o.split = "list:" + (root_ / "list.txt").string();
  std::ofstream(root_ / "list.txt") << "img_3.jpg\n";
  o.gravity_file = root_ / "g.txt";
  const ColmapImportStats s = import_colmap(o);
  EXPECT_FALSE(s.binary);
  EXPECT_EQ(s.map_frames, 1);
  const ColmapModel r = read_colmap_text(o.out_dir / "sparse");
  const auto g = read_gravity_file(o.out_dir / "gravity.txt", r);
  EXPECT_TRUE(g.at("map/day1/img_3.jpg").isApprox(Eigen::Vector3d(0, 1, 4.7).normalized()));
  EXPECT_TRUE(g.at("query/day1/img_0.jpg").isApprox(Eigen::Vector3d(0, 1, 5.0).normalized()));
  EXPECT_TRUE(s.gravity_lines_unused.empty());
}

TEST_F(ColmapImportTest, GravityLinesOfUnregisteredPhotosAreSkippedMissingOnesAreAnError) {
  // A gravity file written for every photo of a folder, of which the reconstruction registered
  // only some: the other lines are skipped and named; an image of the model without a line stays
  // an error.
  write_colmap_text(model_, root_ / "sparse");
  std::map<std::string, Eigen::Vector3d> gravity;
  for (const ColmapImage& im : model_.images) gravity[im.name] = Eigen::Vector3d(0, 1, 0.1 * im.image_id);
  gravity["day1/not_registered.jpg"] = Eigen::Vector3d(1, 0, 0);
  gravity["day0/also_not.jpg"] = Eigen::Vector3d(1, 0, 0);
  write_gravity_file(gravity, root_ / "g.txt");
  ColmapImportOptions o = options();
  o.gravity_file = root_ / "g.txt";
  const ColmapImportStats s = import_colmap(o);
  EXPECT_EQ(s.gravity_lines_unused, (std::vector<std::string>{"day0/also_not.jpg", "day1/not_registered.jpg"}));
  const ColmapModel r = read_colmap_text(o.out_dir / "sparse");
  const auto g = read_gravity_file(o.out_dir / "gravity.txt", r);  // exactly the model's images
  EXPECT_EQ(g.size(), model_.images.size());

  gravity.erase(model_.images.back().name);
  write_gravity_file(gravity, root_ / "g.txt");
  o.overwrite = true;
  EXPECT_EQ(error(o), (root_ / "g.txt").string() + ": no gravity for image " + model_.images.back().name +
                          " (image id " + std::to_string(model_.images.back().image_id) + ")");
}

TEST_F(ColmapImportTest, BadInputsFailWithOneClearLine) {
  write_colmap_binary(model_, root_ / "sparse");
  ColmapImportOptions o = options();
  fs::remove(root_ / "photos" / "day1" / "img_2.jpg");
  EXPECT_NE(error(o).find("image 48 'day1/img_2.jpg': "), std::string::npos) << error(o);
  EXPECT_NE(error(o).find("image file is missing"), std::string::npos) << error(o);

  ColmapModel fisheye = model_;
  fisheye.cameras.at(2).model = CameraModel::kOpenCV;
  fisheye.cameras.at(2).params = {10, 10, 4, 3, 0, 0, 0, 0};
  write_colmap_binary(fisheye, root_ / "sparse");
  std::fstream f(root_ / "sparse" / "cameras.bin", std::ios::in | std::ios::out | std::ios::binary);
  f.seekp(12);
  const int32_t opencv_fisheye = 5;
  f.write(reinterpret_cast<const char*>(&opencv_fisheye), 4);
  f.close();
  EXPECT_NE(error(o).find("cameras.bin: camera record 0 (id 2): unsupported camera model id 5 (OPENCV_FISHEYE)"),
            std::string::npos)
      << error(o);
  EXPECT_EQ(error(o).find('\n'), std::string::npos);

  o.up = "+z";
  o.gravity_file = root_ / "g.txt";
  EXPECT_NE(error(o).find("--gravity-file and --up are exclusive"), std::string::npos);
}

// Cameras of a world whose up is `up`: evenly spaced headings, pitch and roll alternating in sign, so
// that the cameras' down axes average to exactly -up.
std::vector<Rigid3d> upright_cameras(const Eigen::Vector3d& up, int n, double pitch_deg, double roll_deg) {
  const Eigen::Vector3d down = -up.normalized();
  const Eigen::Vector3d a = down.unitOrthogonal(), b = down.cross(a);
  std::vector<Rigid3d> poses;
  for (int k = 0; k < n; ++k) {
    const double yaw = 2.0 * M_PI * k / n, sign = k % 2 ? -1.0 : 1.0;
    const Eigen::Vector3d forward = std::cos(yaw) * a + std::sin(yaw) * b;
    Eigen::Matrix3d world_from_level;
    world_from_level << down.cross(forward), down, forward;  // columns: camera x, y, z
    const Eigen::Matrix3d level_from_cam = (Eigen::AngleAxisd(sign * pitch_deg * M_PI / 180, Eigen::Vector3d::UnitX()) *
                                            Eigen::AngleAxisd(sign * roll_deg * M_PI / 180, Eigen::Vector3d::UnitZ()))
                                               .toRotationMatrix();
    const Eigen::Matrix3d world_from_cam = world_from_level * level_from_cam;
    poses.emplace_back(Eigen::Quaterniond(world_from_cam.transpose()).normalized(), Eigen::Vector3d(0.1 * k, 0, 0));
  }
  return poses;
}

double angle_deg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0, 1.0)) * 180.0 / M_PI;
}

TEST(EstimateUpFromCameras, UprightCamerasGiveTheUpDirectionAndTheNearestAxis) {
  // Up is -y turned 4 deg about x: the nearest axis is -y, 4 deg away.
  const Eigen::Vector3d up = Eigen::AngleAxisd(4.0 * M_PI / 180, Eigen::Vector3d::UnitX()) * Eigen::Vector3d(0, -1, 0);
  const UpEstimate e = estimate_up_from_cameras(upright_cameras(up, 24, 15.0, 3.0));
  EXPECT_LT(angle_deg(e.up, up), 1e-6);
  EXPECT_EQ(e.cameras, 24);
  EXPECT_EQ(e.nearest_axis, "-y");
  EXPECT_NEAR(e.nearest_axis_deg, 4.0, 1e-6);
  // Tilted cameras: each down axis is 15.3 deg off -up, so the mean is shorter than 1.
  EXPECT_NEAR(e.mean_resultant_length, std::cos(15.0 * M_PI / 180) * std::cos(3.0 * M_PI / 180), 1e-9);

  const UpEstimate z = estimate_up_from_cameras(upright_cameras(Eigen::Vector3d(0, 0, 1), 6, 0.0, 0.0));
  EXPECT_EQ(z.nearest_axis, "+z");
  EXPECT_LT(z.nearest_axis_deg, 1e-6);
  EXPECT_NEAR(z.mean_resultant_length, 1.0, 1e-12);
}

TEST(EstimateUpFromCameras, CancellingCamerasAndNoCamerasFail) {
  std::vector<Rigid3d> poses = upright_cameras(Eigen::Vector3d(0, 0, 1), 4, 0.0, 0.0);
  const std::vector<Rigid3d> upside_down = upright_cameras(Eigen::Vector3d(0, 0, -1), 4, 0.0, 0.0);
  poses.insert(poses.end(), upside_down.begin(), upside_down.end());
  try {
    estimate_up_from_cameras(poses);
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("--up auto: the 8 cameras' down directions cancel out"), std::string::npos)
        << e.what();
  }
  EXPECT_THROW(estimate_up_from_cameras({}), Error);
}

TEST_F(ColmapImportTest, UpAutoWritesGravityFromTheEstimatedUp) {
  const Eigen::Vector3d up = Eigen::AngleAxisd(-10.0 * M_PI / 180, Eigen::Vector3d::UnitY()) * Eigen::Vector3d(0, 0, 1);
  model_.images.clear();
  const std::vector<Rigid3d> poses = upright_cameras(up, 8, 20.0, 5.0);
  const cv::Mat pixels(6, 8, CV_8UC1, cv::Scalar(99));
  for (int i = 0; i < 8; ++i) {
    ColmapImage im;
    im.image_id = i + 1;
    im.camera_id = 2;
    im.name = "day1/cam_" + std::to_string(i) + ".jpg";
    im.cam_from_world = poses[i];
    model_.images.push_back(im);
    ASSERT_TRUE(cv::imwrite((root_ / "photos" / im.name).string(), pixels));
  }
  write_colmap_text(model_, root_ / "sparse");
  ColmapImportOptions o = options();
  o.up = "auto";
  const ColmapImportStats s = import_colmap(o);
  ASSERT_TRUE(s.up_estimate.has_value());
  EXPECT_LT(angle_deg(s.up_estimate->up, up), 1e-6);
  EXPECT_EQ(s.up_estimate->nearest_axis, "+z");
  EXPECT_NEAR(s.up_estimate->nearest_axis_deg, 10.0, 1e-6);
  ASSERT_TRUE(s.has_gravity);
  const ColmapModel r = read_colmap_text(o.out_dir / "sparse");
  const auto g = read_gravity_file(o.out_dir / "gravity.txt", r);
  for (const ColmapImage& im : r.images) {
    EXPECT_LT(angle_deg(g.at(im.name), im.cam_from_world.rotation * -up), 1e-6) << im.name;
  }
  // "auto" is the only word --up takes besides the axes.
  o.up = "automatic";
  EXPECT_NE(error(o).find("--up: 'automatic' is neither an axis nor auto"), std::string::npos) << error(o);
}

TEST_F(ColmapImportTest, DepthsOfTheModelsPointsAreReported) {
  // Without points: nothing to report.
  EXPECT_FALSE(observed_point_depths(model_).has_value());
  // Points straight ahead of image 50 (identity rotation, centre at the origin) at depths 1..20,
  // seen by it; one point behind it (not counted) and one element of a missing image (ignored).
  for (int i = 1; i <= 20; ++i) {
    ColmapPoint3D p;
    p.point3d_id = i;
    p.xyz = Eigen::Vector3d(0, 0, i);
    p.track = {{50, 0}};
    model_.points.push_back(p);
  }
  ColmapPoint3D behind;
  behind.point3d_id = 100;
  behind.xyz = Eigen::Vector3d(0, 0, -5);
  behind.track = {{50, 0}, {7, 0}};
  model_.points.push_back(behind);
  const std::optional<DepthStats> d = observed_point_depths(model_);
  ASSERT_TRUE(d.has_value());
  EXPECT_EQ(d->observations, 20);
  EXPECT_EQ(d->median, 11.0);  // the element at 0.5 * 19 + 0.5, rounded down: the 11th
  EXPECT_EQ(d->p95, 19.0);
  model_.points.back().track = {{50, 0}};  // the reader refuses tracks of missing images
  write_colmap_text(model_, root_ / "sparse");
  const ColmapImportStats s = import_colmap(options());
  ASSERT_TRUE(s.depths.has_value());
  EXPECT_EQ(s.depths->observations, 20);
}

// A name with ".." cannot make `import colmap` create folders and links outside --out.
TEST_F(ColmapImportTest, ImageNamesCannotLeaveTheFolders) {
  model_.images[1].name = "../../../../escapee/x.jpg";
  write_colmap_text(model_, root_ / "sparse");
  EXPECT_NE(error(options()).find("image name '../../../../escapee/x.jpg' leaves the image folder"), std::string::npos)
      << error(options());
  EXPECT_FALSE(fs::exists(root_ / "escapee"));
  EXPECT_FALSE(fs::exists(root_.parent_path() / "escapee"));
  EXPECT_FALSE(fs::exists(root_ / "collection"));
}

// A camera of 2147483647 x 2147483647 pixels for 8 x 6 images is refused by the import, not only
// later by map.
TEST_F(ColmapImportTest, CameraSizeMustMatchItsImages) {
  model_.cameras.at(2).width = 2147483647;
  model_.cameras.at(2).height = 2147483647;
  write_colmap_text(model_, root_ / "sparse");
  EXPECT_NE(error(options()).find("camera 2 is 2147483647x2147483647 pixels, but its image " +
                                  (root_ / "photos" / "day1" / "img_4.jpg").string() + " is 8x6"),
            std::string::npos)
      << error(options());
  EXPECT_FALSE(fs::exists(root_ / "collection"));
}

// On a full disk the import must not print "wrote" with 0-byte sparse/*.txt. A file-size limit
// (RLIMIT_FSIZE) fails write(2) like a full disk, at any byte: the import fails naming the file and
// leaves no half collection.
TEST_F(ColmapImportTest, FullDiskFailsAndLeavesNoHalfCollection) {
  write_colmap_text(model_, root_ / "sparse");
  std::map<std::string, Eigen::Vector3d> gravity;
  for (const ColmapImage& im : model_.images) gravity[im.name] = Eigen::Vector3d(0, 1, 0);
  write_gravity_file(gravity, root_ / "g.txt");
  ColmapImportOptions o = options();
  o.gravity_file = root_ / "g.txt";
  // Each written file in turn is the first one too large: the limits just below their sizes.
  import_colmap(o);
  std::vector<rlim_t> limits = {0};
  for (const fs::path& f : {o.out_dir / "sparse" / "cameras.txt", o.out_dir / "sparse" / "images.txt",
                            o.out_dir / "sparse" / "points3D.txt", o.out_dir / "gravity.txt"}) {
    limits.push_back(static_cast<rlim_t>(fs::file_size(f)) - 1);
  }
  fs::remove_all(o.out_dir);
  for (rlim_t limit : limits) {
    std::string message;
    {
      rlimit saved{};
      ::getrlimit(RLIMIT_FSIZE, &saved);
      const auto old_handler = ::signal(SIGXFSZ, SIG_IGN);
      rlimit l = saved;
      l.rlim_cur = limit;
      ::setrlimit(RLIMIT_FSIZE, &l);
      message = error(o);
      ::setrlimit(RLIMIT_FSIZE, &saved);
      ::signal(SIGXFSZ, old_handler);
    }
    EXPECT_NE(message.find(": write failed: File too large"), std::string::npos)
        << "limit " << limit << ": " << message;
    EXPECT_TRUE(message.rfind((root_ / "collection").string(), 0) == 0) << message;
    // The --out folder the import created is removed too.
    EXPECT_FALSE(fs::exists(o.out_dir)) << "limit " << limit;
  }
  // An --out folder that existed (empty) stays, empty; the missing folders above a nested --out that
  // the import created are removed with it.
  for (const fs::path& out : {o.out_dir, root_ / "new" / "deeper" / "collection"}) {
    if (out == o.out_dir) fs::create_directories(out);
    ColmapImportOptions nested = o;
    nested.out_dir = out;
    rlimit saved{};
    ::getrlimit(RLIMIT_FSIZE, &saved);
    const auto old_handler = ::signal(SIGXFSZ, SIG_IGN);
    rlimit l = saved;
    l.rlim_cur = 0;
    ::setrlimit(RLIMIT_FSIZE, &l);
    const std::string message = error(nested);
    ::setrlimit(RLIMIT_FSIZE, &saved);
    ::signal(SIGXFSZ, old_handler);
    EXPECT_NE(message.find(": write failed: File too large"), std::string::npos) << message;
  }
  EXPECT_TRUE(fs::is_directory(o.out_dir) && fs::is_empty(o.out_dir));
  EXPECT_FALSE(fs::exists(root_ / "new"));
  import_colmap(o);  // room again
  EXPECT_EQ(read_colmap_text(o.out_dir / "sparse").images.size(), 5u);
}

}  // namespace
}  // namespace lmb
