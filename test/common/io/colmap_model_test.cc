#include "common/io/colmap_model.h"

#include <fstream>

#include <gtest/gtest.h>

#include "common/error.h"

namespace lmb {
namespace {

namespace fs = std::filesystem;

class ColmapTextTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("lmb_colmap_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  static ColmapModel sample() {
    ColmapModel m;
    Camera c;
    c.model = CameraModel::kOpenCV;
    c.width = 640;
    c.height = 480;
    c.params = {510, 490, 318, 241, -0.2, 0.05, 0.001, -0.002};
    m.cameras[3] = c;
    for (int i = 0; i < 4; ++i) {
      ColmapImage im;
      im.image_id = 10 - i;
      im.camera_id = 3;
      im.name = "map/" + std::to_string(i) + ".png";
      im.cam_from_world.rotation =
          Eigen::Quaterniond(Eigen::AngleAxisd(0.3 * i, Eigen::Vector3d(0.2, 1, 0.1).normalized()));
      im.cam_from_world.translation = Eigen::Vector3d(i, -2.0 * i, 0.5);
      m.images.push_back(im);
    }
    return m;
  }

  void write(const std::string& file, const std::string& text) {
    std::ofstream(dir_ / file) << text;
  }

  fs::path dir_;
};

TEST_F(ColmapTextTest, RoundTripIsExact) {
  const ColmapModel m = sample();
  write_colmap_text(m, dir_);
  const ColmapModel r = read_colmap_text(dir_);
  ASSERT_EQ(r.cameras.size(), 1u);
  EXPECT_EQ(r.cameras.at(3).params, m.cameras.at(3).params);
  ASSERT_EQ(r.images.size(), 4u);
  for (size_t i = 0; i < 4; ++i) {
    const ColmapImage& a = r.images[i];
    const ColmapImage& b = m.images[3 - i];  // sorted by id on read
    EXPECT_EQ(a.image_id, b.image_id);
    EXPECT_EQ(a.name, b.name);
    EXPECT_LT(a.cam_from_world.rotation.angularDistance(b.cam_from_world.rotation), 1e-12);
    EXPECT_TRUE(a.cam_from_world.translation.isApprox(b.cam_from_world.translation, 1e-15));
  }
}

TEST_F(ColmapTextTest, MalformedFilesFailWithFileAndLine) {
  write_colmap_text(sample(), dir_);
  auto expect_error = [&](const std::string& needle) {
    try {
      read_colmap_text(dir_);
      ADD_FAILURE() << "no error, expected one containing '" << needle << "'";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    }
  };
  write("cameras.txt", "3 OPENCV_FISHEYE 640 480 500 500 320 240 0 0 0 0\n");
  expect_error("unsupported camera model 'OPENCV_FISHEYE'");
  write("cameras.txt", "3 PINHOLE 640 480 500 500 320\n");
  expect_error("cameras.txt line 1: camera model PINHOLE takes 4 parameters, got 3");
  write("cameras.txt", "3 PINHOLE 640 480 500 nan 320 240\n");
  expect_error("not finite");
  write("cameras.txt", "3 PINHOLE 640 480 500 500 320 240\n");
  write("images.txt", "1 0.5 0.5 0.5 0.6 0 0 0 3 a.png\n\n");
  expect_error("images.txt line 1: quaternion is not a rotation");
  write("images.txt", "1 1 0 0 0 0 0 0 9 a.png\n\n");
  expect_error("refers to camera 9");
  write("images.txt", "1 1 0 0 0 0 0 nan 3 a.png\n\n");
  expect_error("field 'TZ' is not");
  write("images.txt", "1 1 0 0 0 0 0 0 3 a.png\n\n2 1 0 0 0 0 0 0 3 a.png\n");
  expect_error("duplicate image name a.png");
  fs::remove(dir_ / "images.txt");
  expect_error("images.txt: cannot open file");
}

}  // namespace
}  // namespace lmb
