// choose_map_gravity: which gravity `lboost map` uses for a collection (train/mapping/map_gravity.h).
#include "train/mapping/map_gravity.h"

#include <unistd.h>

#include <map>

#include <gtest/gtest.h>

#include "common/error.h"
#include "common/io/colmap_model.h"
#include "common/io/gravity_file.h"
#include "synthetic_scene.h"

namespace lmb {
namespace {

namespace fs = std::filesystem;

class MapGravityTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("lmb_map_gravity_" + std::to_string(::getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    Camera c;
    c.model = CameraModel::kPinhole;
    c.width = 64;
    c.height = 48;
    c.params = {50, 50, 32, 24};
    model_.cameras[1] = c;
    for (int i = 0; i < 5; ++i) {
      ColmapImage im;
      im.image_id = i + 1;
      im.camera_id = 1;
      im.name = "map/" + std::to_string(i) + ".png";
      im.cam_from_world = test::look_along(Eigen::Vector3d(0.1 * i, 0, 1), 0.3 * i, 0.1 * i);
      model_.images.push_back(im);
    }
    write_colmap_text(model_, dir_ / "sparse");
  }
  void TearDown() override { fs::remove_all(dir_); }

  // gravity.txt with each image's gravity from world up `up` (a z-up world seen upside down: -z).
  void write_gravity(const Eigen::Vector3d& up) {
    std::map<std::string, Eigen::Vector3d> g;
    for (const ColmapImage& im : model_.images) g[im.name] = im.cam_from_world.rotation * -up;
    write_gravity_file(g, dir_ / "gravity.txt");
  }
  MapGravityRequest request(const std::string& gravity, const std::string& up, bool up_given) const {
    MapGravityRequest r;
    r.collection = dir_;
    r.gravity = gravity;
    r.up = up;
    r.up_given = up_given;
    return r;
  }
  std::string error(const MapGravityRequest& r) {
    try {
      choose_map_gravity(r);
    } catch (const Error& e) {
      EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos);
      return e.what();
    }
    return "";
  }

  fs::path dir_;
  ColmapModel model_;
};

TEST_F(MapGravityTest, WithoutAFileTheUpAxisIsUsedAndSaidSo) {
  const MapGravityChoice c = choose_map_gravity(request("", "+z", false));
  EXPECT_TRUE(c.gravity_file.empty());
  EXPECT_EQ(c.up, Eigen::Vector3d(0, 0, 1));
  EXPECT_EQ(c.description, "-up of --up +z (the default) (no " + (dir_ / "gravity.txt").string() + ")");
  const MapGravityChoice y = choose_map_gravity(request("", "-y", true));
  EXPECT_EQ(y.up, Eigen::Vector3d(0, -1, 0));
  EXPECT_EQ(y.description.rfind("-up of --up -y (no ", 0), 0u) << y.description;
}

// The case: a model whose +z points down; import wrote gravity.txt, map was run without
// flags and used +z silently. Now the collection's file wins over the default axis.
TEST_F(MapGravityTest, TheCollectionsGravityFileIsUsedByDefault) {
  write_gravity(Eigen::Vector3d(0, 0, -1));
  const MapGravityChoice c = choose_map_gravity(request("", "+z", false));
  EXPECT_EQ(c.gravity_file, dir_ / "gravity.txt");
  EXPECT_NE(c.description.find("per image from " + (dir_ / "gravity.txt").string() + " (found in the collection"),
            std::string::npos)
      << c.description;
}

TEST_F(MapGravityTest, AnExplicitUpThatDisagreesWithTheFileIsAnError) {
  write_gravity(Eigen::Vector3d(0, 0, -1));
  const std::string e = error(request("", "+z", true));
  EXPECT_NE(
      e.find("--up +z disagrees with " + (dir_ / "gravity.txt").string() + " by a median 180.0 deg over 5 images"),
      std::string::npos)
      << e;
  EXPECT_NE(e.find("--gravity none"), std::string::npos) << e;
}

TEST_F(MapGravityTest, AnExplicitUpThatAgreesWithTheFileIsUsedWithTheAgreement) {
  // The file is 10 deg off +z (about x): within the tolerance, so --up +z is used, and said so.
  write_gravity(Eigen::AngleAxisd(10.0 * M_PI / 180, Eigen::Vector3d::UnitX()) * Eigen::Vector3d(0, 0, 1));
  const MapGravityChoice c = choose_map_gravity(request("", "+z", true));
  EXPECT_TRUE(c.gravity_file.empty());
  EXPECT_EQ(c.images_compared, 5);
  EXPECT_NEAR(c.median_angle_deg, 10.0, 1e-6);
  EXPECT_NEAR(c.max_angle_deg, 10.0, 1e-6);
  EXPECT_NE(c.description.find("agrees: median 10.0 deg, max 10.0 deg over 5 images"), std::string::npos)
      << c.description;
}

TEST_F(MapGravityTest, GravityNoneAndAnExplicitFile) {
  write_gravity(Eigen::Vector3d(0, 0, -1));
  const MapGravityChoice none = choose_map_gravity(request("none", "+z", true));
  EXPECT_TRUE(none.gravity_file.empty());
  EXPECT_EQ(none.up, Eigen::Vector3d(0, 0, 1));
  EXPECT_NE(none.description.find("--gravity none: " + (dir_ / "gravity.txt").string() + " is not used"),
            std::string::npos)
      << none.description;

  const fs::path other = dir_ / "other.txt";
  fs::copy_file(dir_ / "gravity.txt", other);
  const MapGravityChoice file = choose_map_gravity(request(other.string(), "+z", false));
  EXPECT_EQ(file.gravity_file, other);
  EXPECT_EQ(file.description, "per image from " + other.string() + " (--gravity)");

  EXPECT_NE(
      error(request(other.string(), "+z", true)).find("--gravity " + other.string() + " and --up +z are exclusive"),
      std::string::npos);
  EXPECT_NE(error(request((dir_ / "missing.txt").string(), "+z", false)).find("missing.txt: no such file"),
            std::string::npos);
  EXPECT_NE(error(request("", "up", true)).find("--up: 'up' is not an axis"), std::string::npos);
}

}  // namespace
}  // namespace lmb
