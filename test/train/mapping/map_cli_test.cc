// `lboost map` and `lboost inspect` on bad input: one error line naming file and reason, a non-zero
// exit code, and no output file.
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <fstream>
#include <sstream>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "common/io/colmap_model.h"
#include "synthetic_scene.h"
#include "test/support/lboost_run.h"

namespace lmb {
namespace {

namespace fs = std::filesystem;

using test::RunResult;
using test::slurp;

RunResult run(const std::string& args, const fs::path& dir, const std::string& prefix = "") {
  return test::run_lboost(args, dir, prefix);
}

class MapCliTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("lmb_map_cli_" + std::to_string(::getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_ / "coll" / "images" / "map");
    ColmapModel model;
    Camera c;
    c.model = CameraModel::kPinhole;
    c.width = 64;
    c.height = 48;
    c.params = {50, 50, 32, 24};
    model.cameras[1] = c;
    for (int i = 0; i < 3; ++i) {
      ColmapImage im;
      im.image_id = i + 1;
      im.camera_id = 1;
      im.name = "map/" + std::to_string(i) + ".png";
      im.cam_from_world = test::look_along(Eigen::Vector3d(0.1 * i, 0, 1), 0);
      model.images.push_back(im);
      cv::imwrite((dir_ / "coll" / "images" / im.name).string(), cv::Mat(48, 64, CV_8UC1, cv::Scalar(100)));
    }
    write_colmap_text(model, dir_ / "coll" / "sparse");
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

TEST_F(MapCliTest, MissingImage) {
  fs::remove(dir_ / "coll" / "images" / "map" / "1.png");
  const fs::path out = dir_ / "map.h5";
  const RunResult r = run("map --collection " + (dir_ / "coll").string() + " --out " + out.string(), dir_);
  test::expect_one_error(r, "map", "map/1.png");
  EXPECT_FALSE(fs::exists(out));
}

TEST_F(MapCliTest, NonRotationPose) {
  std::ifstream in(dir_ / "coll" / "sparse" / "images.txt");
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  // Scale the first image's QW to 7: no longer a unit quaternion.
  const size_t at = text.find("\n1 ");
  ASSERT_NE(at, std::string::npos) << text;
  const size_t start = at + 3, end = text.find(' ', start);
  std::ofstream(dir_ / "coll" / "sparse" / "images.txt") << text.substr(0, start) << '7' << text.substr(end);
  const fs::path out = dir_ / "map.h5";
  const RunResult r = run("map --collection " + (dir_ / "coll").string() + " --out " + out.string(), dir_);
  test::expect_one_error(r, "map", "not a rotation");
  EXPECT_FALSE(fs::exists(out));
}

TEST_F(MapCliTest, NoLandmarksWritesNothing) {
  const fs::path out = dir_ / "map.h5";
  const RunResult r = run("map --collection " + (dir_ / "coll").string() + " --out " + out.string(), dir_);
  test::expect_one_error(r, "map", "no landmark");
  EXPECT_FALSE(fs::exists(out));
  EXPECT_EQ(std::distance(fs::directory_iterator(dir_), fs::directory_iterator()), 1);  // coll
}

TEST_F(MapCliTest, InspectRejectsBadFiles) {
  std::ofstream(dir_ / "text.h5") << "hello, this is not HDF5\n";
  test::expect_one_error(run("inspect " + (dir_ / "text.h5").string(), dir_), "inspect", "not an HDF5 file");
  test::expect_one_error(run("inspect " + (dir_ / "none.h5").string(), dir_), "inspect", "no such file");
}

}  // namespace
}  // namespace lmb
