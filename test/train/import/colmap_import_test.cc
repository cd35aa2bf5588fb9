#include "train/import/colmap_import.h"

#include <unistd.h>

#include <fstream>

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

}  // namespace
}  // namespace lmb
