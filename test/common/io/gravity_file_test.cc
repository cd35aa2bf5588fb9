#include "common/io/gravity_file.h"

#include <unistd.h>

#include <fstream>

#include <gtest/gtest.h>

#include "common/error.h"

namespace lmb {
namespace {

namespace fs = std::filesystem;

class GravityFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    path_ = fs::temp_directory_path() / ("lmb_gravity_" + std::to_string(::getpid()) + "_" +
                                         ::testing::UnitTest::GetInstance()->current_test_info()->name() + ".txt");
  }
  void TearDown() override { fs::remove(path_); }
  void write(const std::string& text) { std::ofstream(path_, std::ios::trunc) << text; }
  std::string error(const ColmapModel* model = nullptr) {
    try {
      if (model) {
        read_gravity_file(path_, *model);
      } else {
        read_gravity_file(path_);
      }
    } catch (const Error& e) {
      return e.what();
    }
    return "";
  }
  static ColmapModel model_with(const std::vector<std::string>& names) {
    ColmapModel m;
    int id = 1;
    for (const std::string& n : names) {
      ColmapImage im;
      im.image_id = id++;
      im.name = n;
      m.images.push_back(im);
    }
    return m;
  }
  fs::path path_;
};

TEST_F(GravityFileTest, ReadsAndNormalizes) {
  write("# comment\n\nmap/a.jpg 0 9.81 0\r\nquery/b.jpg  3 -4 0\n");
  const auto g = read_gravity_file(path_);
  ASSERT_EQ(g.size(), 2u);
  EXPECT_TRUE(g.at("map/a.jpg").isApprox(Eigen::Vector3d(0, 1, 0)));
  EXPECT_TRUE(g.at("query/b.jpg").isApprox(Eigen::Vector3d(0.6, -0.8, 0)));
  EXPECT_EQ(read_gravity_file(path_, model_with({"map/a.jpg", "query/b.jpg"})).size(), 2u);
}

// Regression (found by test/fuzz/fuzz_gravity, its input below): components near the largest
// double overflowed the norm to inf and "normalized" the vector to zero.
TEST_F(GravityFileTest, HugeComponentsStillGiveUnitVectors) {
  write(
      "# Gravity hIMAGE_/2.png 0 1 0\nmap/2.png 0.100000000000000011e308 0.9000000000000011e308 "
      "0.900000000000000000000000000000001\nquery/3.qng 0.001 2.5 1000\nbig.png 1.7e308 -1.7e308 0\n");
  const auto g = read_gravity_file(path_);
  ASSERT_EQ(g.size(), 3u);
  for (const auto& [name, v] : g) EXPECT_NEAR(v.norm(), 1.0, 1e-12) << name;
  EXPECT_TRUE(g.at("map/2.png").isApprox(Eigen::Vector3d(0.1, 0.9, 0).normalized(), 1e-12));
  EXPECT_TRUE(g.at("big.png").isApprox(Eigen::Vector3d(1, -1, 0).normalized(), 1e-12));
}

TEST_F(GravityFileTest, WriteReadRoundTrip) {
  const std::map<std::string, Eigen::Vector3d> g = {{"x/1.png", Eigen::Vector3d(0.1, 0.7, -0.3).normalized()},
                                                    {"x/2.png", Eigen::Vector3d(0, 0, 1)}};
  write_gravity_file(g, path_);
  const auto r = read_gravity_file(path_);
  ASSERT_EQ(r.size(), 2u);
  for (const auto& [name, v] : g) EXPECT_LT((r.at(name) - v).norm(), 1e-15) << name;
}

TEST_F(GravityFileTest, MalformedLinesFailNamingFileAndLine) {
  write("a.jpg 0 1\n");
  EXPECT_NE(error().find(path_.string() + " line 1: expected 4 fields (IMAGE_NAME GX GY GZ), got 3"), std::string::npos)
      << error();
  write("# x\na.jpg 0 nan 1\n");
  EXPECT_NE(error().find("line 2: GY is not finite"), std::string::npos) << error();
  write("a.jpg 0 1x 1\n");
  EXPECT_NE(error().find("line 1: GY is not a number: '1x'"), std::string::npos) << error();
  write("a.jpg 0 0 0\n");
  EXPECT_NE(error().find("line 1: gravity of image a.jpg is the zero vector"), std::string::npos) << error();
  write("a.jpg 0 0 1\na.jpg 0 1 0\n");
  EXPECT_NE(error().find("line 2: duplicate image name a.jpg"), std::string::npos) << error();
  fs::remove(path_);
  EXPECT_NE(error().find(path_.string() + ": cannot open file: No such file or directory"), std::string::npos)
      << error();
}

TEST_F(GravityFileTest, NamesMustMatchTheModel) {
  write("a.jpg 0 1 0\nc.jpg 0 1 0\n");
  const ColmapModel m = model_with({"a.jpg", "b.jpg"});
  EXPECT_NE(error(&m).find("image name c.jpg is not in the sparse model"), std::string::npos) << error(&m);
  write("a.jpg 0 1 0\n");
  EXPECT_NE(error(&m).find("no gravity for image b.jpg (image id 2)"), std::string::npos) << error(&m);
}

}  // namespace
}  // namespace lmb
