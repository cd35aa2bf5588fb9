#include "common/io/colmap_model.h"

#include <algorithm>
#include <fstream>

#include <gtest/gtest.h>

#include "common/error.h"
#include "common/io/colmap_binary.h"

namespace lmb {
namespace {

namespace fs = std::filesystem;

class ColmapTextTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("lmb_colmap_" + std::to_string(::getpid()) + "_" +
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

  void write(const std::string& file, const std::string& text) { std::ofstream(dir_ / file) << text; }
  // Reading the model fails with a message containing `needle`.
  void expect_error(const std::string& needle) {
    try {
      read_colmap_text(dir_);
      ADD_FAILURE() << "no error, expected one containing '" << needle << "'";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    }
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
  expect_error("images.txt: cannot open file: No such file or directory");
}

// An image name must stay inside the image folder (`import colmap` links images at these names);
// ids are never negative; a NUL byte is an error naming file and line (it would cut messages).
TEST_F(ColmapTextTest, NamesIdsAndBytesThatCannotBeUsed) {
  write("cameras.txt", "3 PINHOLE 640 480 500 500 320 240\n");
  write("images.txt", "1 1 0 0 0 0 0 0 3 ../../outside.png\n\n");
  expect_error("images.txt line 1: image name '../../outside.png' leaves the image folder ('..' component)");
  write("images.txt", "1 1 0 0 0 0 0 0 3 map/../../x.png\n\n");
  expect_error("leaves the image folder");
  write("images.txt", "1 1 0 0 0 0 0 0 3 /etc/passwd\n\n");
  expect_error("images.txt line 1: image name '/etc/passwd' is an absolute path");
  write("images.txt", "1 1 0 0 0 0 0 0 3 a//b.png\n\n");
  expect_error("has an empty path component");
  write("images.txt", "-5 1 0 0 0 0 0 0 3 a.png\n\n");
  expect_error("images.txt line 1: IMAGE_ID -5 is negative");
  write("images.txt", std::string("1 1 0 0 0 0 0 0 3 a") + '\0' + "b.png\n\n");
  expect_error("images.txt line 1: contains a NUL byte (not a text file?)");
  write("images.txt", "1 1 0 0 0 0 0 0 3 dir/a.png\n\n");
  write("cameras.txt", "-3 PINHOLE 640 480 500 500 320 240\n");
  expect_error("cameras.txt line 1: CAMERA_ID -3 is negative");
  write("cameras.txt", "3 PINHOLE 640 480 500 500 320 240\n");
  write("points3D.txt", "-7 0 0 1 1 2 3 0.5\n");
  expect_error("points3D.txt line 1: POINT3D_ID -7 is negative");
  fs::remove(dir_ / "points3D.txt");
  EXPECT_EQ(read_colmap_text(dir_).images[0].name, "dir/a.png");
  EXPECT_EQ(image_name_error("a/./b.png"), "image name 'a/./b.png' has a '.' path component");
  EXPECT_EQ(image_name_error(""), "empty image name");
  EXPECT_EQ(image_name_error("sub/dir/a b..png"), "");
}

TEST_F(ColmapTextTest, PointsAndTracksRoundTripAndAreValidated) {
  ColmapModel m = sample();
  m.images[0].points2d = {{Eigen::Vector2d(1.25, 2.5), 7}, {Eigen::Vector2d(3, 4), ColmapPoint2D::kNoPoint3D}};
  ColmapPoint3D p;
  p.point3d_id = 7;
  p.xyz = Eigen::Vector3d(1, 2, 3);
  p.track = {{m.images[0].image_id, 0}, {m.images[1].image_id, 5}};
  m.points.push_back(p);
  write_colmap_text(m, dir_);
  const ColmapModel r = read_colmap_text(dir_);
  const auto it = std::find_if(r.images.begin(), r.images.end(),
                               [&](const ColmapImage& im) { return im.image_id == m.images[0].image_id; });
  ASSERT_NE(it, r.images.end());
  EXPECT_EQ(it->points2d, m.images[0].points2d);
  ASSERT_EQ(r.points.size(), 1u);
  EXPECT_EQ(r.points[0].track, p.track);

  write("points3D.txt", "7 1 2 3 0 0 0 0.5 10 0 11\n");
  EXPECT_THROW(read_colmap_text(dir_), Error);
  write("points3D.txt", "");
  write("images.txt", "1 1 0 0 0 0 0 0 3 a.png\n1 nan -1\n");
  try {
    read_colmap_text(dir_);
    ADD_FAILURE() << "NaN 2D point accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("images.txt line 2: field 'POINTS2D[].Y' is not"), std::string::npos)
        << e.what();
  }
  write("images.txt", "1 1 0 0 0 0 0 0 3 a.png\n1 2 -1\n3 4 -1\n");
  EXPECT_THROW(read_colmap_text(dir_), Error);  // two POINTS2D lines for one image
}

TEST_F(ColmapTextTest, ReadModelDetectsTheFormat) {
  const ColmapModel m = sample();
  auto error_of = [&](const fs::path& dir) -> std::string {
    try {
      read_colmap_model(dir);
    } catch (const Error& e) {
      return e.what();
    }
    return "";
  };
  EXPECT_NE(error_of(dir_ / "nope").find("sparse model folder does not exist"), std::string::npos);
  EXPECT_NE(error_of(dir_).find("no COLMAP sparse model"), std::string::npos);
  write_colmap_text(m, dir_);
  ColmapFormat format = ColmapFormat::kBinary;
  EXPECT_EQ(read_colmap_model(dir_, &format).images.size(), 4u);
  EXPECT_EQ(format, ColmapFormat::kText);
  // Both formats: binary wins (as in COLMAP); make the binary model differ to see it.
  ColmapModel other = m;
  other.images.pop_back();
  write_colmap_binary(other, dir_);
  EXPECT_EQ(read_colmap_model(dir_, &format).images.size(), 3u);
  EXPECT_EQ(format, ColmapFormat::kBinary);
  fs::remove(dir_ / "images.bin");
  EXPECT_NE(error_of(dir_).find("incomplete binary model: images.bin is missing"), std::string::npos) << error_of(dir_);
}

TEST_F(ColmapTextTest, CheckCollectionImagesNamesTheFirstBadFile) {
  const ColmapModel m = sample();  // ids 7..10, names map/3.png .. map/0.png
  const fs::path images = dir_ / "images";
  fs::create_directories(images / "map");
  const std::string png("\x89PNG\r\n\x1A\n\0\0\0\rIHDR", 16);
  for (int i = 0; i < 4; ++i) std::ofstream(images / "map" / (std::to_string(i) + ".png")) << png;
  EXPECT_NO_THROW(check_collection_images(m, images));
  auto error = [&]() -> std::string {
    try {
      check_collection_images(m, images);
    } catch (const Error& e) {
      return e.what();
    }
    return "";
  };
  // Image ids: name map/i.png has id 10 - i, so map/3.png (id 7) is checked first.
  fs::remove(images / "map" / "1.png");
  EXPECT_NE(error().find("image 9 'map/1.png': "), std::string::npos) << error();
  EXPECT_NE(error().find("image file is missing"), std::string::npos) << error();
  fs::create_symlink(dir_ / "gone.png", images / "map" / "1.png");
  EXPECT_NE(error().find("dangling symbolic link to"), std::string::npos) << error();
  fs::remove(images / "map" / "1.png");
  std::ofstream(images / "map" / "1.png") << "hello, not an image";
  EXPECT_NE(error().find("not an image file"), std::string::npos) << error();
  std::ofstream(images / "map" / "1.png", std::ios::trunc).close();
  EXPECT_NE(error().find("empty file"), std::string::npos) << error();
  fs::remove(images / "map" / "1.png");
  fs::create_directories(images / "map" / "1.png");
  EXPECT_NE(error().find("not a regular file"), std::string::npos) << error();
  fs::remove(images / "map" / "1.png");
  std::ofstream(images / "map" / "1.png") << "\xFF\xD8\xFF\xE0 jpeg";
  fs::remove(images / "map" / "0.png");  // id 10: after id 9, which is fine now
  EXPECT_NE(error().find("image 10 'map/0.png'"), std::string::npos) << error();
  EXPECT_EQ(error().find('\n'), std::string::npos);
}

}  // namespace
}  // namespace lmb
