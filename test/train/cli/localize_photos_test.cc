// `lboost localize --image/--images` on a small rendered world (fixture lmb_photo_world): the
// world's query frames as photo files give the poses and verdicts that `lboost localize --map` gives
// for the same frames from the map, bit for bit; photos of the outside session are not localized;
// JPEG copies localize; a bundle with a prior scores the areas the prior selects and localizes as
// their models; missing camera, wrong sizes and unreadable photos are reported as documented.
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <optional>
#include <regex>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "common/camera.h"
#include "common/file_io.h"
#include "common/io/gravity_file.h"
#include "common/io/map_h5.h"
#include "common/landmark_map.h"
#include "common/text_parse.h"
#include "infer/area_bundle.h"
#include "test/support/lboost_run.h"

namespace lmb {
namespace {

namespace fs = std::filesystem;

using test::expect_one_error;
using test::RunResult;
using test::slurp;

RunResult run(const std::string& args, const fs::path& dir) { return test::run_lboost(args, dir); }

nlohmann::json read_json(const fs::path& path) { return nlohmann::json::parse(slurp(path)); }

// The frames of a session ("query", "outside"), by file name ("000003.png").
std::map<std::string, const MapFrame*> session_frames(const LandmarkMap& map, const std::string& session) {
  std::map<std::string, const MapFrame*> frames;
  for (const MapFrame& f : map.frames) {
    if (map.sessions[f.session].name == session) frames[fs::path(f.name).filename().string()] = &f;
  }
  return frames;
}

// One trained model on the photo world, and a bundle of its areas, shared by the tests.
class LocalizePhotosTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    const char* world = std::getenv("LMB_PHOTO_WORLD");
    if (world == nullptr || !fs::exists(fs::path(world) / "map.h5")) return;
    world_ = world;
    dir_ = fs::temp_directory_path() / ("lmb_localize_photos_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    map_ = read_map_h5(world_ / "map.h5");
    camera_ = camera_to_text(map_.cameras[0]);
    const std::string m = (world_ / "map.h5").string(), v = (dir_ / "vocab.lbv").string();
    ok_ = step("vocab --words 16 --max-descriptors 20000 --seed 7 --images " + (world_ / "collection/images").string() +
               " --out " + v) &&
          step("train --map " + m + " --vocab " + v + " --rounds 8 --dims-per-round 64 --out " +
               (dir_ / "run").string()) &&
          step("export --run " + (dir_ / "run").string() + " --map " + m + " --vocab " + v + " --out " +
               (dir_ / "model.lbm").string()) &&
          make_bundle(m, v);
    // The map's frames localized by `lboost localize --map`: the reference.
    ok_ = ok_ && step("localize --model " + (dir_ / "model.lbm").string() + " --map " + m + " --out " +
                      (dir_ / "map_poses.json").string());
    for (const std::string session : {"query", "outside"}) write_gravity(session);
  }
  static void TearDownTestSuite() {
    if (!dir_.empty()) fs::remove_all(dir_);
  }
  void SetUp() override {
    if (world_.empty()) GTEST_SKIP() << "LMB_PHOTO_WORLD (the fixture lmb_photo_world) is not available";
    ASSERT_TRUE(ok_) << "the shared model could not be made";
  }

  static bool step(const std::string& args) {
    const RunResult r = run(args, dir_);
    if (r.exit_code != 0) std::fprintf(stderr, "setup: lboost %s failed: %s\n", args.c_str(), r.err.c_str());
    return r.exit_code == 0;
  }
  // Areas of at most two thirds of the eligible landmarks (so at least two), each trained and
  // exported, and their bundle.
  static bool make_bundle(const std::string& m, const std::string& v) {
    int64_t eligible = 0;
    for (const Landmark& l : map_.landmarks) eligible += l.num_map_observations >= 3;
    const std::string areas = (dir_ / "areas.txt").string();
    const RunResult split =
        run("areas --map " + m + " --out " + areas + " --min-observations 3 --overlap 0.2 --max-classes " +
                std::to_string(eligible * 2 / 3),
            dir_);
    // "areas: N areas of at most ..."
    std::smatch count_match;
    static const std::regex count_line("areas: ([0-9]+) areas of at most");
    const int count = std::regex_search(split.out, count_match, count_line) ? std::stoi(count_match[1]) : 0;
    if (split.exit_code != 0 || count < 2) {
      std::fprintf(stderr, "setup: the areas split failed or gave fewer than two areas: %s%s\n", split.out.c_str(),
                   split.err.c_str());
      return false;
    }
    fs::create_directories(dir_ / "bundle");
    for (int a = 0; a < count; ++a) {
      const std::string run_dir = (dir_ / ("area_run" + std::to_string(a))).string();
      if (!step("train --map " + m + " --vocab " + v + " --rounds 8 --dims-per-round 64 --area " + areas + ":" +
                std::to_string(a) + " --out " + run_dir) ||
          !step("export --run " + run_dir + " --map " + m + " --vocab " + v + " --out " +
                (dir_ / "bundle" / ("area-" + std::to_string(a) + ".lbm")).string())) {
        return false;
      }
    }
    return step("bundle --areas " + areas + " --models " + (dir_ / "bundle").string());
  }
  // DIR/gravity_SESSION.txt: each frame's gravity from the map, by file name, every digit.
  static void write_gravity(const std::string& session) {
    std::string text;
    for (const auto& [name, f] : session_frames(map_, session)) {
      text += name + " " + exact_number_text(f->gravity_in_cam.x()) + " " + exact_number_text(f->gravity_in_cam.y()) +
              " " + exact_number_text(f->gravity_in_cam.z()) + "\n";
    }
    write_file_atomically(dir_ / ("gravity_" + session + ".txt"), text);
  }
  // `lboost localize` on the photos of images/SESSION with their gravity; `extra`: more options.
  static RunResult localize_session(const std::string& session, const fs::path& out, const std::string& extra = "") {
    return run("localize --images " + (world_ / "collection/images" / session).string() + " --camera '" + camera_ +
                   "' --gravity-file " + (dir_ / ("gravity_" + session + ".txt")).string() + " --out " + out.string() +
                   " " + extra,
               dir_);
  }
  // The --map reference's frame entries of a session, by file name.
  static std::map<std::string, nlohmann::json> reference(const std::string& session) {
    std::map<std::string, nlohmann::json> frames;
    const nlohmann::json all = read_json(dir_ / "map_poses.json");
    for (const nlohmann::json& f : all.at("frames")) {
      const std::string name = f.at("name");
      if (name.rfind(session + "/", 0) == 0) frames[fs::path(name).filename().string()] = f;
    }
    return frames;
  }

  static fs::path world_;
  static fs::path dir_;
  static LandmarkMap map_;
  static std::string camera_;
  static bool ok_;
};
fs::path LocalizePhotosTest::world_;
fs::path LocalizePhotosTest::dir_;
LandmarkMap LocalizePhotosTest::map_;
std::string LocalizePhotosTest::camera_;
bool LocalizePhotosTest::ok_ = false;

TEST_F(LocalizePhotosTest, QueryPhotosGiveTheMapModesPosesBitForBit) {
  const fs::path out = dir_ / "query_photos.json";
  const RunResult r = localize_session("query", out, "--model " + (dir_ / "model.lbm").string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json j = read_json(out);
  const std::map<std::string, nlohmann::json> want = reference("query");
  ASSERT_EQ(j.at("photos").size(), 16u);  // the default world's 16 query frames, sorted by name
  ASSERT_EQ(want.size(), 16u);
  int localized = 0;
  for (const nlohmann::json& p : j.at("photos")) {
    const std::string name = fs::path(p.at("path").get<std::string>()).filename().string();
    const nlohmann::json& f = want.at(name);
    const MapFrame& frame = *session_frames(map_, "query").at(name);
    EXPECT_FALSE(p.contains("error")) << name;
    EXPECT_EQ(p.at("num_keypoints"), frame.num_keypoints) << name;
    EXPECT_EQ(p.at("success"), f.at("success")) << name;
    EXPECT_EQ(p.at("pose_found"), f.at("pose_found")) << name;
    EXPECT_EQ(p.at("confidence"), f.at("confidence")) << name;
    EXPECT_EQ(p.at("num_inliers"), f.at("num_inliers")) << name;
    EXPECT_EQ(p.at("num_correspondences"), f.at("num_correspondences")) << name;
    ASSERT_EQ(p.contains("cam_from_world"), f.at("pose_found").get<bool>()) << name;
    if (!f.at("pose_found").get<bool>()) continue;
    EXPECT_EQ(p.at("cam_from_world"), f.at("cam_from_world")) << name;  // every double the same
    // The matrix and the centre are the same pose.
    const nlohmann::json& q = p.at("cam_from_world");
    const Rigid3d pose(Eigen::Quaterniond(q.at("qw"), q.at("qx"), q.at("qy"), q.at("qz")),
                       Eigen::Vector3d(q.at("tx"), q.at("ty"), q.at("tz")));
    const Eigen::Matrix3d rot = pose.rotation.toRotationMatrix();
    for (int row = 0; row < 3; ++row) {
      for (int col = 0; col < 3; ++col) EXPECT_NEAR(p.at("cam_from_world_matrix")[row][col], rot(row, col), 1e-12);
      EXPECT_EQ(p.at("cam_from_world_matrix")[row][3], pose.translation(row));
      EXPECT_NEAR(p.at("camera_center")[row], pose.center()(row), 1e-12);
    }
    localized += p.at("success").get<bool>();
  }
  EXPECT_GE(localized, 8) << "the model localizes most query frames of this world";
  EXPECT_EQ(j.at("summary").at("localized"), localized);
  EXPECT_EQ(j.at("summary").at("unreadable"), 0);
  EXPECT_EQ(j.at("camera"), camera_);
  // The same photos named one by one, in another order, on two threads: the same entries in the
  // order given.
  const fs::path images = world_ / "collection/images/query";
  const fs::path out2 = dir_ / "query_photos_2.json";
  const RunResult r2 =
      run("localize --model " + (dir_ / "model.lbm").string() + " --image " + (images / "000005.png").string() + " " +
              (images / "000001.png").string() + " --camera '" + camera_ + "' --gravity-file " +
              (dir_ / "gravity_query.txt").string() + " --threads 2 --out " + out2.string(),
          dir_);
  ASSERT_EQ(r2.exit_code, 0) << r2.err;
  const nlohmann::json j2 = read_json(out2);
  ASSERT_EQ(j2.at("photos").size(), 2u);
  for (int i = 0; i < 2; ++i) {
    nlohmann::json got = j2.at("photos")[i], expected = j.at("photos")[i == 0 ? 5 : 1];
    got.erase("timings_ms");
    expected.erase("timings_ms");
    EXPECT_EQ(got, expected);
  }
}

TEST_F(LocalizePhotosTest, OutsidePhotosAreNotLocalized) {
  // The outside session was rendered in a corridor no map frame sees: the calibrated rule keeps
  // wrong poses out, and on this world it passes none of the outside frames.
  const fs::path out = dir_ / "outside_photos.json";
  const RunResult r = localize_session("outside", out, "--model " + (dir_ / "model.lbm").string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json j = read_json(out);
  ASSERT_TRUE(j.at("summary").at("calibrated").get<bool>());
  const std::map<std::string, nlohmann::json> want = reference("outside");
  ASSERT_EQ(j.at("photos").size(), want.size());
  ASSERT_GE(want.size(), 4u);
  int pose_found = 0;
  for (const nlohmann::json& p : j.at("photos")) {
    const std::string name = fs::path(p.at("path").get<std::string>()).filename().string();
    EXPECT_FALSE(p.at("success").get<bool>()) << name << " localized with confidence " << p.at("confidence");
    EXPECT_EQ(p.at("success"), want.at(name).at("success")) << name;
    EXPECT_EQ(p.at("num_inliers"), want.at(name).at("num_inliers")) << name;
    pose_found += p.at("pose_found").get<bool>();
  }
  // Not for want of a pose: RANSAC finds wrong poses in the look-alike corridor, and the
  // confidence turns them down.
  EXPECT_GT(pose_found, 0);
  EXPECT_EQ(j.at("summary").at("localized"), 0);
}

TEST_F(LocalizePhotosTest, JpegCopiesLocalizeToo) {
  const fs::path jpeg_dir = dir_ / "jpeg";
  fs::create_directories(jpeg_dir);
  std::string gravity;
  for (const auto& [name, f] : session_frames(map_, "query")) {
    const cv::Mat image = cv::imread((world_ / "collection/images/query" / name).string(), cv::IMREAD_UNCHANGED);
    ASSERT_FALSE(image.empty()) << name;
    const std::string jpeg = fs::path(name).stem().string() + ".jpg";
    ASSERT_TRUE(cv::imwrite((jpeg_dir / jpeg).string(), image, {cv::IMWRITE_JPEG_QUALITY, 95}));
    gravity += jpeg + " " + exact_number_text(f->gravity_in_cam.x()) + " " + exact_number_text(f->gravity_in_cam.y()) +
               " " + exact_number_text(f->gravity_in_cam.z()) + "\n";
  }
  write_file_atomically(dir_ / "gravity_jpeg.txt", gravity);
  const fs::path out = dir_ / "jpeg_photos.json";
  const RunResult r =
      run("localize --model " + (dir_ / "model.lbm").string() + " --images " + jpeg_dir.string() + " --camera '" +
              camera_ + "' --gravity-file " + (dir_ / "gravity_jpeg.txt").string() + " --out " + out.string(),
          dir_);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json j = read_json(out);
  ASSERT_EQ(j.at("photos").size(), 16u);
  int localized = 0, right = 0;
  for (const nlohmann::json& p : j.at("photos")) {
    if (!p.at("success").get<bool>()) continue;
    ++localized;
    const std::string png = fs::path(p.at("path").get<std::string>()).stem().string() + ".png";
    const Eigen::Vector3d truth = session_frames(map_, "query").at(png)->cam_from_world.center();
    const Eigen::Vector3d c(p.at("camera_center")[0], p.at("camera_center")[1], p.at("camera_center")[2]);
    right += (c - truth).norm() < 0.2;
  }
  // The PNG photos' count, give or take the frames whose confidence lies near the operating point.
  int png_localized = 0;
  for (const auto& [name, f] : reference("query")) png_localized += f.at("success").get<bool>();
  EXPECT_GE(localized, png_localized - 3);
  EXPECT_GE(right, localized - 1) << "JPEG photos localized within 20 cm of their true pose";
}

TEST_F(LocalizePhotosTest, BundleWithAPriorScoresTheAreasItSelects) {
  const auto bundle = AreaBundle::open(dir_ / "bundle/bundle.txt");
  const size_t areas = bundle->areas().size();
  ASSERT_GE(areas, 2u);
  // A prior far out along an axis, radius 0: the bundle selects the one area at that end.
  std::optional<PositionPrior> prior;
  for (int axis = 0; axis < 3 && !prior; ++axis) {
    for (double side : {-1000.0, 1000.0}) {
      PositionPrior p;
      p.position[axis] = side;
      if (!prior && bundle->select(&p).size() == 1) prior = p;
    }
  }
  ASSERT_TRUE(prior.has_value());
  const int32_t area = bundle->select(&*prior)[0];
  const std::string b = "--bundle " + (dir_ / "bundle/bundle.txt").string();
  // Without a prior every area is scored.
  const RunResult all = localize_session("query", dir_ / "bundle_all.json", b);
  ASSERT_EQ(all.exit_code, 0) << all.err;
  int localized = 0;
  const nlohmann::json every_area = read_json(dir_ / "bundle_all.json");
  for (const nlohmann::json& p : every_area.at("photos")) {
    EXPECT_EQ(p.at("areas_selected"), static_cast<int>(areas));
    EXPECT_EQ(p.at("areas_scored"), areas);
    localized += p.at("success").get<bool>();
  }
  EXPECT_GT(localized, 0);
  // With the prior: only that area, and then the bundle gives that area's model's poses.
  const std::string prior_text = exact_number_text(prior->position.x()) + " " + exact_number_text(prior->position.y()) +
                                 " " + exact_number_text(prior->position.z()) + " 0";
  const RunResult one = localize_session("query", dir_ / "bundle_prior.json", b + " --prior " + prior_text);
  ASSERT_EQ(one.exit_code, 0) << one.err;
  const RunResult single = localize_session("query", dir_ / "area_model.json",
                                            "--model " + (dir_ / "bundle" / bundle->areas()[area].file).string());
  ASSERT_EQ(single.exit_code, 0) << single.err;
  const nlohmann::json got = read_json(dir_ / "bundle_prior.json"), want = read_json(dir_ / "area_model.json");
  EXPECT_EQ(got.at("prior").at("radius"), 0.0);
  ASSERT_EQ(got.at("photos").size(), want.at("photos").size());
  for (size_t i = 0; i < got.at("photos").size(); ++i) {
    const nlohmann::json& g = got.at("photos")[i];
    const nlohmann::json& w = want.at("photos")[i];
    EXPECT_EQ(g.at("areas_selected"), 1);
    EXPECT_EQ(g.at("scored"), std::vector<int32_t>{area});
    EXPECT_EQ(g.at("success"), w.at("success")) << i;
    EXPECT_EQ(g.at("pose_found"), w.at("pose_found")) << i;
    EXPECT_EQ(g.contains("cam_from_world"), w.contains("cam_from_world")) << i;
    // Without a pose the bundle has no winning area (0 inliers); with one, the area's pose.
    if (w.at("pose_found").get<bool>()) {
      EXPECT_EQ(g.at("area"), area) << i;
      EXPECT_EQ(g.at("num_inliers"), w.at("num_inliers")) << i;
      EXPECT_EQ(g.at("cam_from_world"), w.at("cam_from_world")) << i;
    } else {
      EXPECT_EQ(g.at("area"), -1) << i;
    }
  }
}

TEST_F(LocalizePhotosTest, AnUnreadablePhotoGetsItsErrorAndTheOthersGoOn) {
  const fs::path bad = dir_ / "not_an_image.png";
  write_file_atomically(bad, "this is text, not a PNG\n");
  const fs::path good = world_ / "collection/images/query/000003.png";
  const fs::path out = dir_ / "unreadable.json";
  const RunResult r = run("localize --model " + (dir_ / "model.lbm").string() + " --image " + bad.string() + " " +
                              (dir_ / "missing.jpg").string() + " " + good.string() + " --camera '" + camera_ +
                              "' --gravity-file " + (dir_ / "gravity_query.txt").string() + " --out " + out.string(),
                          dir_);
  // Exit status 0, nothing on stderr but the log; the errors are in the JSON.
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.err.find("error"), std::string::npos) << r.err;
  const nlohmann::json j = read_json(out);
  ASSERT_EQ(j.at("photos").size(), 3u);
  EXPECT_EQ(j.at("photos")[0].at("error"), bad.string() + ": cannot read the image: not a format OpenCV decodes");
  EXPECT_EQ(j.at("photos")[1].at("error"),
            (dir_ / "missing.jpg").string() + ": cannot read the image: no such file, or not a readable file");
  for (int i = 0; i < 2; ++i) {
    EXPECT_FALSE(j.at("photos")[i].at("success").get<bool>());
    EXPECT_FALSE(j.at("photos")[i].contains("cam_from_world"));
  }
  EXPECT_FALSE(j.at("photos")[2].contains("error"));
  EXPECT_EQ(j.at("photos")[2].at("num_inliers"), reference("query").at("000003.png").at("num_inliers"));
  EXPECT_EQ(j.at("summary").at("unreadable"), 2);
  EXPECT_NE(r.out.find("2 unreadable"), std::string::npos) << r.out;
}

TEST_F(LocalizePhotosTest, RefusalsAreOneLine) {
  const std::string model = "--model " + (dir_ / "model.lbm").string();
  const std::string photo = (world_ / "collection/images/query/000000.png").string();
  const std::string out = " --out " + (dir_ / "refused.json").string();
  // No camera: one line naming --camera.
  expect_one_error(run("localize " + model + " --image " + photo + out, dir_), "localize", "needs --camera");
  // Another size than the camera's: one line naming the photo and both sizes.
  const Camera& c = map_.cameras[0];
  const std::string bigger =
      "PINHOLE " + std::to_string(2 * c.width) + " " + std::to_string(2 * c.height) + " 400 400 320 240";
  expect_one_error(run("localize " + model + " --image " + photo + " --camera '" + bigger + "'" + out, dir_),
                   "localize",
                   photo + ": image is " + std::to_string(c.width) + "x" + std::to_string(c.height) +
                       " pixels but --camera is " + std::to_string(2 * c.width) + "x" + std::to_string(2 * c.height));
  // Photos and the map's query frames at once.
  expect_one_error(run("localize " + model + " --image " + photo + " --camera '" + camera_ + "' --map " +
                           (world_ / "map.h5").string() + out,
                       dir_),
                   "localize", "--image/--images and --map are exclusive");
  // A photo option in the map mode.
  expect_one_error(
      run("localize " + model + " --map " + (world_ / "map.h5").string() + " --camera '" + camera_ + "'" + out, dir_),
      "localize", "--camera is for photos");
  // A camera model this project does not represent, a wrong parameter count.
  expect_one_error(run("localize " + model + " --image " + photo + " --camera 'FISHEYE 320 240 1 2 3'" + out, dir_),
                   "localize", "--camera: unsupported camera model 'FISHEYE'");
  expect_one_error(
      run("localize " + model + " --image " + photo + " --camera 'PINHOLE 320 240 200 200 160'" + out, dir_),
      "localize", "--camera: camera model PINHOLE takes 4 parameters, got 3");
  // A photo without a line in the gravity file.
  write_file_atomically(dir_ / "gravity_other.txt", "other.png 0 1 0\n");
  expect_one_error(run("localize " + model + " --image " + photo + " --camera '" + camera_ + "' --gravity-file " +
                           (dir_ / "gravity_other.txt").string() + out,
                       dir_),
                   "localize", (dir_ / "gravity_other.txt").string() + ": no gravity for photo 000000.png");
  // --prior without a bundle; the output is one of the photos.
  expect_one_error(
      run("localize " + model + " --image " + photo + " --camera '" + camera_ + "' --prior 0 0 0 1" + out, dir_),
      "localize", "--prior needs --bundle");
  expect_one_error(run("localize " + model + " --image " + photo + " --camera '" + camera_ + "' --out " + photo, dir_),
                   "localize", "--out " + photo + " is the input --image " + photo);
  const fs::path folder = world_ / "collection/images/query";
  expect_one_error(run("localize " + model + " --images " + folder.string() + " --camera '" + camera_ + "' --out " +
                           (folder / "poses.json").string(),
                       dir_),
                   "localize", "lies inside the input --images " + folder.string());
  EXPECT_FALSE(fs::exists(dir_ / "refused.json"));
  EXPECT_FALSE(fs::exists(folder / "poses.json"));
}

TEST_F(LocalizePhotosTest, TheLocalizedPhotosGoToTheScene) {
  const fs::path poses = dir_ / "scene_poses.json";
  ASSERT_EQ(localize_session("query", poses, "--model " + (dir_ / "model.lbm").string()).exit_code, 0);
  int localized = 0;
  const nlohmann::json j = read_json(poses);
  for (const nlohmann::json& p : j.at("photos")) localized += p.at("success").get<bool>();
  const RunResult r = run("scene --map " + (world_ / "map.h5").string() + " --poses " + poses.string() + " --out " +
                              (dir_ / "scene").string(),
                          dir_);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string images = slurp(dir_ / "scene/sparse/images.txt");
  int localized_images = 0;
  for (size_t at = images.find(" localized/"); at != std::string::npos; at = images.find(" localized/", at + 1)) {
    ++localized_images;
  }
  EXPECT_EQ(localized_images, localized);
}

}  // namespace
}  // namespace lmb
