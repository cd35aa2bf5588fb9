// `lboost map` and `lboost import colmap --up auto` end to end on a part of the tiny rendered world
// (the lmb_tiny_world fixture of test/train/export; z-up, cameras about level):
// - map uses COLLECTION/gravity.txt when present and says so (it used to fall back to --up +z
//   silently), and refuses an explicit --up that disagrees with the file;
// - import colmap --up auto estimates the up axis from the cameras and reports its angle to the
//   nearest world axis.
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <fstream>
#include <map>
#include <sstream>
#include <string>

#include <gtest/gtest.h>

#include "common/io/colmap_model.h"
#include "common/io/gravity_file.h"
#include "common/io/map_h5.h"
#include "test/support/lboost_run.h"

namespace lmb {
namespace {

namespace fs = std::filesystem;

using test::RunResult;
using test::slurp;

RunResult run(const std::string& args, const fs::path& dir, const std::string& prefix = "") {
  return test::run_lboost(args, dir, prefix);
}

class GravityCliTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const char* tiny = std::getenv("LMB_TINY_DIR");
    if (tiny == nullptr || !fs::exists(fs::path(tiny) / "collection" / "sparse")) {
      GTEST_SKIP() << "LMB_TINY_DIR (the tiny world of the lmb_tiny_world fixture) is not available";
    }
    source_ = fs::path(tiny) / "collection";
    dir_ = fs::temp_directory_path() / ("lmb_gravity_cli_" + std::to_string(::getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_ / "coll");
    // The first 8 map frames and 2 query frames, images linked.
    ColmapModel model = read_colmap_text(source_ / "sparse");
    ColmapModel part;
    part.cameras = model.cameras;
    int maps = 0, queries = 0;
    for (ColmapImage& im : model.images) {
      const bool query = im.name.rfind("query/", 0) == 0;
      if (query ? queries++ >= 2 : maps++ >= 8) continue;
      im.points2d.clear();
      part.images.push_back(im);
    }
    write_colmap_text(part, dir_ / "coll" / "sparse");
    fs::create_directory_symlink(source_ / "images", dir_ / "coll" / "images");
    model_ = part;
  }
  void TearDown() override {
    if (!dir_.empty()) fs::remove_all(dir_);
  }

  fs::path source_, dir_;
  ColmapModel model_;
};

TEST_F(GravityCliTest, MapUsesTheCollectionsGravityFileAndSaysSo) {
  // gravity.txt of an upside-down world: gravity along +z, i.e. up = -z, as a COLMAP model whose
  // +z points down would give. The map must store the file's gravity, not -up of --up +z.
  std::map<std::string, Eigen::Vector3d> gravity;
  for (const ColmapImage& im : model_.images) gravity[im.name] = im.cam_from_world.rotation * Eigen::Vector3d(0, 0, 1);
  const fs::path file = dir_ / "coll" / "gravity.txt";
  write_gravity_file(gravity, file);
  const fs::path out = dir_ / "map.h5";
  const RunResult r = run(
      "map --collection " + (dir_ / "coll").string() + " --out " + out.string() + " --threads 2 --min-observations 2",
      dir_);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("map: gravity: per image from " + file.string() + " (found in the collection"),
            std::string::npos)
      << r.out;
  const LandmarkMap map = read_map_h5(out);
  ASSERT_EQ(map.frames.size(), model_.images.size());
  for (const MapFrame& f : map.frames) {
    EXPECT_LT((f.gravity_in_cam - gravity.at(f.name).normalized()).norm(), 1e-12) << f.name;
  }

  // An explicit --up that contradicts the file: one error line, nothing written.
  const fs::path out2 = dir_ / "map2.h5";
  const RunResult e =
      run("map --collection " + (dir_ / "coll").string() + " --out " + out2.string() + " --up +z", dir_);
  EXPECT_NE(e.exit_code, 0);
  EXPECT_EQ(e.err, "lboost map: error: --up +z disagrees with " + file.string() +
                       " by a median 180.0 deg over 10 images: drop --up to use the file, or pass --gravity none "
                       "to use --up\n");
  EXPECT_FALSE(fs::exists(out2));
}

TEST_F(GravityCliTest, ImportColmapUpAutoReportsTheEstimateAndWritesGravity) {
  const fs::path out = dir_ / "imported";
  const RunResult r = run("import colmap --sparse " + (dir_ / "coll" / "sparse").string() + " --images " +
                              (dir_ / "coll" / "images").string() + " --out " + out.string() + " --up auto",
                          dir_);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  // "import: --up auto: up = (x, y, z), ... nearest world axis +z, A deg away"
  const size_t at = r.out.find("import: --up auto: up = (");
  ASSERT_NE(at, std::string::npos) << r.out;
  Eigen::Vector3d up;
  char comma = 0;
  std::istringstream in(r.out.substr(at + 26));
  in >> up.x() >> comma >> up.y() >> comma >> up.z();
  ASSERT_TRUE(in.good()) << r.out;
  const size_t axis = r.out.find("nearest world axis +z, ", at);
  ASSERT_NE(axis, std::string::npos) << r.out;
  const double angle = std::stod(r.out.substr(axis + 23));
  // The rendered cameras are about level in a z-up world: the estimate is near +z, and the
  // reported angle is the estimate's (to the printed precision).
  EXPECT_LT(angle, 10.0);
  EXPECT_NEAR(angle, std::acos(std::min(1.0, up.normalized().z())) * 180.0 / M_PI, 0.1);
  const ColmapModel imported = read_colmap_text(out / "sparse");
  const auto g = read_gravity_file(out / "gravity.txt", imported);
  for (const ColmapImage& im : imported.images) {
    EXPECT_LT((g.at(im.name) - im.cam_from_world.rotation * -up.normalized()).norm(), 1e-3) << im.name;
  }
}

}  // namespace
}  // namespace lmb
