// `lboost areas` and `lboost train --area` on the tiny rendered world (docs/areas.md): the split
// covers every eligible landmark; an area's run trains exactly its landmarks, bit-identical on 1,
// 2 and 3 MPI ranks; the area is recorded in config.toml and a resume with another area or a
// changed areas file is refused; bad --area values fail with one line. Bundles: one area localizes
// as its model (library, `lboost localize --bundle` and `lboost eval --bundle`); a bundle of every
// area selects the areas the split's prior selection gives, --no-prior scores every area, a
// damaged area fails alone with one line.
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "common/file_container.h"
#include "common/file_io.h"
#include "common/io/map_h5.h"
#include "common/text_parse.h"
#include "infer/bundle_localizer.h"
#include "infer/localizer.h"
#include "infer/model.h"
#include "test/support/lboost_run.h"
#include "train/areas/area_file.h"
#include "train/areas/area_split.h"
#include "train/boost/boost_model.h"
#include "train/eval/pose_calibration_fit.h"

namespace lmb {
namespace {

namespace fs = std::filesystem;

using test::expect_one_error;
using test::RunResult;
using test::slurp;

RunResult run(const std::string& args, const fs::path& dir, const std::string& prefix = "") {
  return test::run_lboost(args, dir, prefix);
}

class AreasCliTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    const char* map = std::getenv("LMB_TINY_MAP");
    if (map == nullptr || !fs::exists(map)) return;
    dir_ = fs::temp_directory_path() / ("lmb_areas_cli_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    map_ = map;
    const fs::path images = fs::path(map).parent_path() / "collection" / "images";
    ok_ = run("vocab --words 16 --max-descriptors 20000 --images " + images.string() + " --seed 7 --out " +
                  (dir_ / "vocab.lbv").string(),
              dir_)
              .exit_code == 0;
    // K: a third of the eligible landmarks, so that the map splits into several areas.
    const LandmarkMap m = read_map_h5(map_);
    const std::vector<int32_t> counts = map_observation_counts(m);
    eligible_ = std::count_if(counts.begin(), counts.end(), [](int32_t c) { return c >= 3; });
    max_classes_ = static_cast<int32_t>(eligible_ / 3);
    const RunResult a =
        run("areas --map " + map_.string() + " --out " + (dir_ / "areas.txt").string() +
                " --min-observations 3 --overlap 0.2 --prior-noise 0.5 --max-classes " + std::to_string(max_classes_),
            dir_);
    areas_out_ = a.out;
    ok_ = ok_ && a.exit_code == 0;
    if (!ok_) std::fprintf(stderr, "setup failed: %s\n", a.err.c_str());
  }
  static void TearDownTestSuite() {
    if (!dir_.empty()) fs::remove_all(dir_);
  }
  void SetUp() override {
    if (map_.empty()) GTEST_SKIP() << "LMB_TINY_MAP (a map.h5 of `lboost world --preset tiny`) is not available";
    ASSERT_TRUE(ok_) << "the shared setup failed";
  }
  static std::string train_args(const std::string& area, const fs::path& out) {
    return "train --map " + map_.string() + " --vocab " + (dir_ / "vocab.lbv").string() +
           " --rounds 6 --dims-per-round 64 --checkpoint-interval 3 --area " + area + " --out " + out.string();
  }
  static fs::path dir_;
  static fs::path map_;
  static bool ok_;
  static int64_t eligible_;
  static int32_t max_classes_;
  static std::string areas_out_;
};
fs::path AreasCliTest::dir_;
fs::path AreasCliTest::map_;
bool AreasCliTest::ok_ = false;
int64_t AreasCliTest::eligible_ = 0;
int32_t AreasCliTest::max_classes_ = 0;
std::string AreasCliTest::areas_out_;

TEST_F(AreasCliTest, SplitCoversEveryEligibleLandmark) {
  const AreaFile file = read_area_file(dir_ / "areas.txt");
  EXPECT_EQ(file.split.num_eligible, eligible_);
  EXPECT_GE(file.split.areas.size(), 3u);
  std::set<landmark_t> covered;
  for (const Area& a : file.split.areas) {
    EXPECT_LE(static_cast<int32_t>(a.landmarks.size()), max_classes_);
    covered.insert(a.landmarks.begin(), a.landmarks.end());
  }
  EXPECT_EQ(static_cast<int64_t>(covered.size()), eligible_);
  EXPECT_NE(areas_out_.find(" 0 uncovered"), std::string::npos) << areas_out_;
  EXPECT_NE(areas_out_.find("prior noise 0.5 m:"), std::string::npos) << areas_out_;
  // Deterministic: the same command writes the same bytes.
  const fs::path again = dir_ / "areas_again.txt";
  ASSERT_EQ(run("areas --map " + map_.string() + " --out " + again.string() +
                    " --min-observations 3 --overlap 0.2 --max-classes " + std::to_string(max_classes_),
                dir_)
                .exit_code,
            0);
  EXPECT_EQ(slurp(again), slurp(dir_ / "areas.txt"));
}

TEST_F(AreasCliTest, AnAreaTrainsExactlyItsLandmarksOnAnyRankCount) {
  const AreaFile file = read_area_file(dir_ / "areas.txt");
  const std::vector<landmark_t>& want = file.split.areas[1].landmarks;
  const std::string area = (dir_ / "areas.txt").string() + ":1";
  const fs::path serial = dir_ / "area1_serial";
  const RunResult r = run(train_args(area, serial), dir_);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const TrainedModel model = load_trained_model(serial / "model.bin");
  EXPECT_EQ(model.model.class_landmark, want);
  const nlohmann::json summary = nlohmann::json::parse(slurp(serial / "summary.json"));
  EXPECT_EQ(summary["classes"].get<int64_t>(), static_cast<int64_t>(want.size()));
  EXPECT_EQ(summary["area"].get<int>(), 1);
  const std::string config = slurp(serial / "config.toml");
  EXPECT_NE(config.find("[area]"), std::string::npos) << config;
  EXPECT_NE(config.find("id = 1"), std::string::npos) << config;
  EXPECT_NE(config.find("landmarks = " + std::to_string(want.size())), std::string::npos) << config;
  for (int ranks : {2, 3}) {
    const fs::path dir = dir_ / ("area1_ranks" + std::to_string(ranks));
    const RunResult m =
        run(train_args(area, dir), dir_, std::string(LMB_MPIEXEC) + " -n " + std::to_string(ranks) + " ");
    ASSERT_EQ(m.exit_code, 0) << m.err;
    EXPECT_EQ(slurp(dir / "model.bin"), slurp(serial / "model.bin")) << ranks << " ranks";
  }
  // The exported model (with the fitted fusion, which rebuilds the area's training set).
  const RunResult e = run("export --run " + serial.string() + " --map " + map_.string() + " --vocab " +
                              (dir_ / "vocab.lbv").string() + " --out " + (dir_ / "area1.lbm").string(),
                          dir_);
  EXPECT_EQ(e.exit_code, 0) << e.err;
}

TEST_F(AreasCliTest, ResumeChecksTheArea) {
  const fs::path run_dir = dir_ / "area0";
  const std::string areas = (dir_ / "areas.txt").string();
  ASSERT_EQ(run(train_args(areas + ":0", run_dir), dir_).exit_code, 0);
  // Another area into the same folder: refused, naming the setting.
  expect_one_error(run(train_args(areas + ":2", run_dir), dir_), "train",
                   "the config differs from the checkpoint's in area.id (checkpoint 0, now 2)");
  // The run's own config.toml, but the areas file changed under it: refused, naming the file.
  const std::string original = slurp(areas);
  AreaFile changed = read_area_file(areas);
  changed.split.areas[0].landmarks.pop_back();
  write_area_file(areas, changed, "");
  const RunResult r = run("train --map " + map_.string() + " --vocab " + (dir_ / "vocab.lbv").string() + " --config " +
                              (run_dir / "config.toml").string() + " --rounds 9 --out " + run_dir.string(),
                          dir_);
  write_file_atomically(areas, original);
  expect_one_error(r, "train", areas + ": area 0 now has ");
}

TEST_F(AreasCliTest, ABundleOfOneAreaLocalizesAsItsModel) {
  // One area holding every eligible landmark, trained, exported and bundled.
  const fs::path one = dir_ / "one_area.txt";
  ASSERT_EQ(run("areas --map " + map_.string() + " --out " + one.string() + " --min-observations 3 --max-classes " +
                    std::to_string(eligible_),
                dir_)
                .exit_code,
            0);
  ASSERT_EQ(read_area_file(one).split.areas.size(), 1u);
  const fs::path models = dir_ / "one_bundle";
  fs::create_directories(models);
  const RunResult t = run(train_args(one.string() + ":0", dir_ / "one_run"), dir_);
  ASSERT_EQ(t.exit_code, 0) << t.err;
  const RunResult e = run("export --run " + (dir_ / "one_run").string() + " --map " + map_.string() + " --vocab " +
                              (dir_ / "vocab.lbv").string() + " --out " + (models / "area-0.lbm").string(),
                          dir_);
  ASSERT_EQ(e.exit_code, 0) << e.err;
  const RunResult b = run("bundle --areas " + one.string() + " --models " + models.string(), dir_);
  ASSERT_EQ(b.exit_code, 0) << b.err;
  const auto bundle = AreaBundle::open(models / "bundle.txt");
  ASSERT_EQ(bundle->areas().size(), 1u);
  EXPECT_EQ(bundle->reach(), read_area_file(one).split.options.reach);
  const Localizer single(Model::load(models / "area-0.lbm"));
  const LandmarkMap map = read_map_h5(map_);
  int frames = 0, localized = 0;
  for (const MapFrame& f : map.frames) {
    if (!f.is_query) continue;
    const std::vector<Keypoint> keypoints(map.keypoints.begin() + f.first_keypoint,
                                          map.keypoints.begin() + f.first_keypoint + f.num_keypoints);
    const LocalizeResult want =
        single.localize(map.cameras[f.camera], keypoints, map.descriptor(f.first_keypoint), f.gravity_in_cam);
    PositionPrior prior;
    prior.position = f.cam_from_world.center();
    prior.radius = 1.0;
    const PositionPrior* no_prior = nullptr;
    const PositionPrior* with_prior = &prior;
    for (const PositionPrior* p : {no_prior, with_prior}) {
      const BundleLocalizeResult got = BundleLocalizer(bundle).localize(
          map.cameras[f.camera], keypoints, map.descriptor(f.first_keypoint), f.gravity_in_cam, p);
      EXPECT_EQ(got.scored, std::vector<int32_t>{0});
      ASSERT_EQ(got.area, want.pose.success ? 0 : -1);
      if (want.pose.success) {
        EXPECT_EQ(got.result.pose.num_inliers, want.pose.num_inliers);
        EXPECT_EQ(got.result.pose.cam_from_world.translation, want.pose.cam_from_world.translation);
      }
    }
    ++frames;
    localized += want.pose.success;
  }
  EXPECT_GT(frames, 0);
  EXPECT_GT(localized, 0);
  // The CLI: `lboost localize --bundle` with a prior, without one, and the single model in the same
  // run give the same frames, poses and inliers (one area); `lboost eval --bundle` the same recall
  // at every seed.
  const fs::path loc = dir_ / "bundle_localize.json";
  const RunResult l =
      run("localize --bundle " + (models / "bundle.txt").string() + " --map " + map_.string() + " --model " +
              (models / "area-0.lbm").string() + " --prior-noise 0.5 --no-prior --out " + loc.string(),
          dir_);
  ASSERT_EQ(l.exit_code, 0) << l.err;
  const nlohmann::json lj = nlohmann::json::parse(slurp(loc));
  ASSERT_EQ(lj["modes"].size(), 3u);
  EXPECT_EQ(lj["modes"][0]["mode"], "prior 0.5 m");
  EXPECT_EQ(lj["modes"][1]["mode"], "no prior");
  EXPECT_EQ(lj["modes"][2]["mode"], "single model");
  const nlohmann::json& single_frames = lj["modes"][2]["frames"];
  EXPECT_EQ(single_frames.size(), static_cast<size_t>(frames));
  int single_localized = 0;
  for (int m = 0; m < 2; ++m) {
    const nlohmann::json& fr = lj["modes"][m]["frames"];
    ASSERT_EQ(fr.size(), single_frames.size());
    for (size_t i = 0; i < fr.size(); ++i) {
      EXPECT_EQ(fr[i]["name"], single_frames[i]["name"]);
      EXPECT_EQ(fr[i]["success"], single_frames[i]["success"]) << i;
      EXPECT_EQ(fr[i]["num_inliers"], single_frames[i]["num_inliers"]) << i;
      EXPECT_EQ(fr[i]["correct"], single_frames[i]["correct"]) << i;
      EXPECT_EQ(fr[i]["areas_selected"], 1);
      EXPECT_EQ(fr[i]["area"], single_frames[i]["success"].get<bool>() ? 0 : -1);
      if (fr[i]["success"].get<bool>()) {
        EXPECT_EQ(fr[i]["position_error_m"], single_frames[i]["position_error_m"]) << i;
      }
      single_localized += m == 0 && single_frames[i]["success"].get<bool>();
    }
  }
  EXPECT_EQ(single_localized, localized);
  const fs::path rep = dir_ / "bundle_eval.json";
  const RunResult ev = run("eval --bundle " + (models / "bundle.txt").string() + " --map " + map_.string() +
                               " --model " + (models / "area-0.lbm").string() +
                               " --prior-noise 0.5 --no-prior --ransac-sweep-seeds 2 --report " + rep.string(),
                           dir_);
  ASSERT_EQ(ev.exit_code, 0) << ev.err;
  const nlohmann::json ej = nlohmann::json::parse(slurp(rep));
  ASSERT_EQ(ej["modes"].size(), 3u);
  EXPECT_EQ(ej["seeds"], 2);
  EXPECT_EQ(ej["modes"][0]["frames_correct_per_seed"], ej["modes"][2]["frames_correct_per_seed"]);
  EXPECT_EQ(ej["modes"][1]["frames_correct_per_seed"], ej["modes"][2]["frames_correct_per_seed"]);
  EXPECT_EQ(ej["modes"][0]["pose_recall"], ej["modes"][2]["pose_recall"]);
  ASSERT_EQ(ej["areas"].size(), 1u);
  EXPECT_TRUE(ej["areas"][0]["resident_bytes"].is_number_integer()) << ej["areas"][0];
  EXPECT_EQ(ej["areas"][0]["file_bytes"].get<uint64_t>(), fs::file_size(models / "area-0.lbm"));
  EXPECT_NE(ev.out.find("single model"), std::string::npos) << ev.out;
  // The split of several areas has no models in that folder: one line naming the first area.
  expect_one_error(run("bundle --areas " + (dir_ / "areas.txt").string() + " --models " + models.string(), dir_),
                   "bundle", "area-0.lbm (area 0): ");
  fs::remove(models / "area-0.lbm");
  expect_one_error(run("bundle --areas " + one.string() + " --models " + models.string(), dir_), "bundle",
                   "area 0: " + (models / "area-0.lbm").string());
}

TEST_F(AreasCliTest, ABundleOfEveryAreaSelectsByPriorAndFailsAreaByArea) {
  // Every area of the split trained (a few rounds: the test is about the areas, not the poses),
  // exported and bundled.
  const fs::path areas = dir_ / "areas.txt";
  const AreaFile file = read_area_file(areas);
  const fs::path models = dir_ / "all_bundle";
  fs::create_directories(models);
  const int num_areas = static_cast<int>(file.split.areas.size());
  for (int id = 0; id < num_areas; ++id) {
    const fs::path run_dir = dir_ / ("all_area" + std::to_string(id));
    const RunResult t = run(train_args(areas.string() + ":" + std::to_string(id), run_dir), dir_);
    ASSERT_EQ(t.exit_code, 0) << t.err;
    const RunResult e =
        run("export --run " + run_dir.string() + " --map " + map_.string() + " --vocab " +
                (dir_ / "vocab.lbv").string() + " --out " + (models / ("area-" + std::to_string(id) + ".lbm")).string(),
            dir_);
    ASSERT_EQ(e.exit_code, 0) << e.err;
  }
  // The tiny world's reach spans it whole; the bundle takes a shorter one (the same split with
  // --reach 0.3), so that a prior selects fewer than every area.
  const fs::path short_reach = dir_ / "areas_reach.txt";
  ASSERT_EQ(run("areas --map " + map_.string() + " --out " + short_reach.string() +
                    " --min-observations 3 --overlap 0.2 --reach 0.3 --max-classes " + std::to_string(max_classes_),
                dir_)
                .exit_code,
            0);
  const AreaFile reach_file = read_area_file(short_reach);
  ASSERT_EQ(reach_file.split.areas.size(), file.split.areas.size());
  for (size_t i = 0; i < file.split.areas.size(); ++i) {
    ASSERT_EQ(reach_file.split.areas[i].landmarks, file.split.areas[i].landmarks);
  }
  const RunResult b = run("bundle --areas " + short_reach.string() + " --models " + models.string(), dir_);
  ASSERT_EQ(b.exit_code, 0) << b.err;
  const fs::path out = dir_ / "all_localize.json";
  const std::string localize = "localize --bundle " + (models / "bundle.txt").string() + " --map " + map_.string() +
                               " --prior-noise 0 --prior-noise 0.5 --no-prior --out " + out.string();
  const RunResult l = run(localize, dir_);
  ASSERT_EQ(l.exit_code, 0) << l.err;
  const nlohmann::json j = nlohmann::json::parse(slurp(out));
  ASSERT_EQ(j["modes"].size(), 3u);
  // The areas of a frame on 3 threads: the same frames, areas, inliers, support and poses.
  {
    const fs::path threaded = dir_ / "all_localize_threads.json";
    const RunResult t =
        run(localize.substr(0, localize.find(" --out ")) + " --area-threads 3 --out " + threaded.string(), dir_);
    ASSERT_EQ(t.exit_code, 0) << t.err;
    const nlohmann::json tj = nlohmann::json::parse(slurp(threaded));
    EXPECT_EQ(tj["area_threads"], 3);
    for (size_t m = 0; m < 3; ++m) {
      const nlohmann::json& one = j["modes"][m]["frames"];
      const nlohmann::json& three = tj["modes"][m]["frames"];
      ASSERT_EQ(one.size(), three.size());
      for (size_t i = 0; i < one.size(); ++i) {
        for (const char* key : {"success", "area", "scored", "scored_inliers", "scored_support", "rival_support",
                                "num_inliers", "position_error_m"}) {
          EXPECT_EQ(one[i].value(key, nlohmann::json()), three[i].value(key, nlohmann::json()))
              << m << " " << i << " " << key;
        }
      }
    }
  }
  // The areas each mode selects: the split's own selection (train/areas) for the same prior.
  const LandmarkMap map = read_map_h5(map_);
  std::vector<frame_t> queries;
  for (frame_t f = 0; f < map.num_frames(); ++f) {
    if (map.frames[f].is_query) queries.push_back(f);
  }
  const std::vector<double> noise = {0.0, 0.5};
  int fewer = 0;    // prior frames that select fewer than every area
  int stopped = 0;  // prior frames whose search stopped before the last selected area
  for (int m = 0; m < 3; ++m) {
    const nlohmann::json& fr = j["modes"][m]["frames"];
    ASSERT_EQ(fr.size(), queries.size());
    for (size_t i = 0; i < queries.size(); ++i) {
      const MapFrame& f = map.frames[queries[i]];
      size_t want = static_cast<size_t>(num_areas);
      if (m < 2) {
        const Eigen::Vector3d prior = f.cam_from_world.center() + noise[m] * prior_direction(1, queries[i]);
        want = areas_near(reach_file.split, prior, noise[m] + reach_file.split.options.reach).size();
        fewer += want < static_cast<size_t>(num_areas);
      }
      EXPECT_EQ(fr[i]["areas_selected"].get<size_t>(), want) << m << " " << i;
      // Without a prior every area is scored; with one, nearest first: fewer only when an area's
      // calibrated pose stopped the search.
      const size_t scored = fr[i]["areas_scored"].get<size_t>();
      // The areas scored in the search's order, each once, with their poses' inliers and support
      // (with one match a keypoint, a pose explains at least its own inliers' keypoints); the winner
      // is one of them with the inliers reported for the frame, and without a prior (every area
      // scored, no stop) the one with the most support.
      const std::vector<int32_t> order = fr[i]["scored"].get<std::vector<int32_t>>();
      const std::vector<int32_t> order_inliers = fr[i]["scored_inliers"].get<std::vector<int32_t>>();
      const std::vector<int32_t> order_support = fr[i]["scored_support"].get<std::vector<int32_t>>();
      ASSERT_EQ(order.size(), scored) << m << " " << i;
      ASSERT_EQ(order_inliers.size(), scored) << m << " " << i;
      ASSERT_EQ(order_support.size(), scored) << m << " " << i;
      EXPECT_EQ(std::set<int32_t>(order.begin(), order.end()).size(), scored) << m << " " << i;
      for (size_t a = 0; a < scored; ++a) {
        EXPECT_GE(order_support[a], order_inliers[a]) << m << " " << i;
        if (order_inliers[a] == 0) {
          EXPECT_EQ(order_support[a], 0) << m << " " << i;
        }
      }
      if (fr[i]["success"].get<bool>()) {
        const auto at = std::find(order.begin(), order.end(), fr[i]["area"].get<int32_t>());
        ASSERT_NE(at, order.end()) << m << " " << i;
        const size_t w = static_cast<size_t>(at - order.begin());
        EXPECT_EQ(order_inliers[w], fr[i]["num_inliers"].get<int32_t>());
        if (m == 2) {
          EXPECT_EQ(order_support[w], *std::max_element(order_support.begin(), order_support.end())) << m << " " << i;
        }
      }
      if (m == 2 || !fr[i]["success"].get<bool>()) {
        EXPECT_EQ(scored, want) << m << " " << i;
      } else {
        EXPECT_GE(scored, 1u) << m << " " << i;
        EXPECT_LE(scored, want) << m << " " << i;
        stopped += scored < want;
      }
      if (m == 0 && fr[i]["success"].get<bool>()) {
        // The winning area is one the prior selected: its cell lies within the reach.
        const Area& a = file.split.areas[fr[i]["area"].get<size_t>()];
        EXPECT_LE(a.cell.distance(f.cam_from_world.center()), reach_file.split.options.reach) << i;
      }
    }
  }
  EXPECT_GT(fewer, 0) << "a prior that selects every area tests nothing";
  EXPECT_GT(stopped, 0) << "the exported models are calibrated: some nearest area should stop the search";
  // --all-areas scores every selected area.
  const RunResult all = run(localize + " --all-areas", dir_);
  ASSERT_EQ(all.exit_code, 0) << all.err;
  const nlohmann::json aj = nlohmann::json::parse(slurp(out));
  for (int m = 0; m < 3; ++m) {
    for (const nlohmann::json& f : aj["modes"][m]["frames"]) {
      EXPECT_EQ(f["areas_scored"].get<size_t>(), f["areas_selected"].get<size_t>()) << m;
    }
  }
  EXPECT_EQ(aj["area_search"], "all");
  // --winners-view: the nearest area first, as nearest first; without a prior every area, as before.
  const RunResult view = run(localize + " --winners-view", dir_);
  ASSERT_EQ(view.exit_code, 0) << view.err;
  const nlohmann::json vj = nlohmann::json::parse(slurp(out));
  EXPECT_EQ(vj["area_search"], "winners_view");
  EXPECT_EQ(j["area_search"], "nearest_first");
  for (int m = 0; m < 3; ++m) {
    const nlohmann::json& vf = vj["modes"][m]["frames"];
    const nlohmann::json& nf = j["modes"][m]["frames"];
    ASSERT_EQ(vf.size(), nf.size()) << m;
    for (size_t i = 0; i < vf.size(); ++i) {
      if (m == 2) {
        EXPECT_EQ(vf[i]["scored"], nf[i]["scored"]) << i;
        EXPECT_EQ(vf[i]["area"], nf[i]["area"]) << i;
      } else if (!nf[i]["scored"].empty()) {
        EXPECT_EQ(vf[i]["scored"][0], nf[i]["scored"][0]) << m << " " << i;
      }
    }
  }
  // --track: the query frames in name order through BundleLocalizer::track. The first frame has no
  // last pose (every area); with a radius that holds the whole map every later posed frame is
  // tracked, i.e. stops inside the motion gate.
  {
    const fs::path tout = dir_ / "track.json";
    const RunResult t = run("localize --bundle " + (models / "bundle.txt").string() + " --map " + map_.string() +
                                " --track 1000 --tracking-areas 1 --out " + tout.string(),
                            dir_);
    ASSERT_EQ(t.exit_code, 0) << t.err;
    const nlohmann::json tj = nlohmann::json::parse(slurp(tout));
    ASSERT_EQ(tj["modes"].size(), 1u);
    const nlohmann::json& mode = tj["modes"][0];
    EXPECT_EQ(mode["mode"], "tracking 1000 m");
    EXPECT_EQ(mode["tracking_areas"], 1);
    const nlohmann::json& frames = mode["frames"];
    ASSERT_GE(frames.size(), 2u);
    EXPECT_TRUE(frames[0]["relocalized"].get<bool>());
    EXPECT_FALSE(frames[0]["tracked"].get<bool>());
    EXPECT_EQ(frames[0]["areas_scored"].get<int>(), num_areas);
    int tracked = 0, relocalized = 0, tracked_correct = 0;
    std::vector<double> tracked_ms;
    bool posed = false;  // a pose so far: the tracker has a last pose
    for (size_t i = 0; i < frames.size(); ++i) {
      const nlohmann::json& fr = frames[i];
      if (i > 0) {
        EXPECT_GT(fr["name"].get<std::string>(), frames[i - 1]["name"].get<std::string>());
      }
      if (posed) {
        EXPECT_FALSE(fr["relocalized"].get<bool>()) << i;
      }
      if (fr["tracked"].get<bool>()) {
        EXPECT_LE(fr["areas_scored"].get<int>(), fr["areas_selected"].get<int>());
      }
      EXPECT_EQ(fr["tracked"].get<bool>(), posed && fr["success"].get<bool>()) << i;
      tracked += fr["tracked"].get<bool>();
      tracked_correct += fr["tracked"].get<bool>() && fr["correct"].get<bool>();
      if (fr["tracked"].get<bool>()) tracked_ms.push_back(fr["cpu_ms"].get<double>());
      relocalized += fr["relocalized"].get<bool>();
      posed = posed || fr["success"].get<bool>();
    }
    EXPECT_GT(tracked, 0);
    const double n = static_cast<double>(frames.size());
    EXPECT_DOUBLE_EQ(mode["tracked_per_frame"].get<double>(), tracked / n);
    EXPECT_EQ(mode["tracked_frames_per_seed"][0].get<int>(), tracked);
    EXPECT_EQ(mode["tracked_correct_per_seed"][0].get<int>(), tracked_correct);
    // One seed: the tracked frames' time is over the frames listed.
    std::sort(tracked_ms.begin(), tracked_ms.end());
    const size_t m = tracked_ms.size();
    EXPECT_DOUBLE_EQ(mode["cpu_ms_per_tracked_frame"]["median"].get<double>(),
                     m % 2 ? tracked_ms[m / 2] : 0.5 * (tracked_ms[m / 2 - 1] + tracked_ms[m / 2]));
    EXPECT_DOUBLE_EQ(mode["relocalized_per_frame"].get<double>(), relocalized / n);
    // Relocalizing with a position prior: named in the mode; the first frame scores only the areas
    // a 0 m prior at its true centre selects.
    const RunResult g = run("localize --bundle " + (models / "bundle.txt").string() + " --map " + map_.string() +
                                " --track 1000 --track-prior-noise 0 --out " + tout.string(),
                            dir_);
    ASSERT_EQ(g.exit_code, 0) << g.err;
    const nlohmann::json gj = nlohmann::json::parse(slurp(tout));
    EXPECT_EQ(gj["modes"][0]["mode"], "tracking 1000 m, relocalizing with a 0 m prior");
    EXPECT_EQ(gj["modes"][0]["relocalization_prior_noise_m"], 0.0);
    const nlohmann::json& g0 = gj["modes"][0]["frames"][0];
    EXPECT_TRUE(g0["relocalized"].get<bool>());
    const LandmarkMap lm = read_map_h5(map_);
    const auto first = std::find_if(lm.frames.begin(), lm.frames.end(),
                                    [&](const MapFrame& mf) { return mf.name == g0["name"].get<std::string>(); });
    ASSERT_NE(first, lm.frames.end());
    PositionPrior at_truth;
    at_truth.position = first->cam_from_world.center();
    EXPECT_EQ(g0["areas_selected"].get<size_t>(), AreaBundle::open(models / "bundle.txt")->select(&at_truth).size());
    EXPECT_LE(g0["areas_scored"].get<int>(), g0["areas_selected"].get<int>());
    // `lboost-bench bundle` times the same tracking mode (GPS-like relocalization, an app's steady state)
    // against the single model and names how it relocalizes; its JSON is the localize report's.
    const fs::path bj = dir_ / "bench_bundle.json";
    const RunResult bench_run = test::run_lboost_bench(
        "bundle --bundle " + (models / "bundle.txt").string() + " --map " + map_.string() + " --model " +
            (models / "area-0.lbm").string() + " --repeats 1 --track 1000 --track-prior-noise 0 --json " + bj.string(),
        dir_);
    ASSERT_EQ(bench_run.exit_code, 0) << bench_run.err;
    EXPECT_NE(bench_run.out.find("relocalized with a 0 m prior"), std::string::npos) << bench_run.out;
    const nlohmann::json bench = nlohmann::json::parse(slurp(bj));
    EXPECT_EQ(bench["modes"][2]["mode"], "tracking 1000 m, relocalizing with a 0 m prior");
    EXPECT_EQ(bench["modes"][2]["relocalization_prior_noise_m"], 0.0);
    const RunResult bad = test::run_lboost_bench("bundle --bundle " + (models / "bundle.txt").string() + " --map " +
                                                     map_.string() + " --model " + (models / "area-0.lbm").string() +
                                                     " --repeats 1 --track-prior-noise 5",
                                                 dir_);
    expect_one_error(bad, "bundle", "--track-prior-noise 5: must be finite and needs --track", "lboost-bench");
  }
  // The bundle's calibration (lboost bundle --map): fitted on the map frames and their "elsewhere"
  // variants, written into an index that opens calibrated; a localization reports each
  // frame's confidence, localized exactly when it reaches the operating point. A map the areas file
  // was not made from is refused.
  {
    const fs::path cal = dir_ / "cal_bundle";
    fs::create_directories(cal);
    for (int id = 0; id < num_areas; ++id) {
      const std::string name = "area-" + std::to_string(id) + ".lbm";
      fs::copy_file(models / name, cal / name, fs::copy_options::overwrite_existing);
    }
    const RunResult c = run("bundle --areas " + short_reach.string() + " --models " + cal.string() + " --map " +
                                map_.string() + " --calibration-frames 40",
                            dir_);
    ASSERT_EQ(c.exit_code, 0) << c.err;
    EXPECT_NE((c.out + c.err).find("bundle: calibration on "), std::string::npos) << c.out << c.err;
    // The areas' fusion leaves the calibration frames' own descriptors out of its exemplars, as
    // `lboost export` does: counted here by brute force over every area's exemplar rows (a class
    // whose rows all come from those frames keeps them).
    {
      const LandmarkMap m = read_map_h5(map_);
      PoseCalibrationOptions options;
      options.max_frames = 40;
      TrainingSetOptions areas_training;  // what the bundle's calibration assumes: no fold models
      areas_training.calibration_folds = 0;
      const std::vector<frame_t> frames = calibration_frames(m, with_holdout_frames(options, m, areas_training));
      ASSERT_FALSE(frames.empty());
      int64_t rows = 0, left_out = 0;
      for (int id = 0; id < num_areas; ++id) {
        const ModelData d = Model::load(cal / ("area-" + std::to_string(id) + ".lbm"))->data();
        ASSERT_TRUE(d.fusion.enabled());
        const size_t bytes = static_cast<size_t>(d.descriptor_bytes);
        for (int32_t k = 0; k < d.num_classes; ++k) {
          int64_t own = 0;
          for (int64_t r = d.fusion.exemplar_begin[k]; r < d.fusion.exemplar_begin[k + 1]; ++r) {
            const uint8_t* row = d.fusion.exemplars.data() + r * d.descriptor_bytes;
            bool in_frames = false;
            for (frame_t f : frames) {
              const MapFrame& fr = m.frames[f];
              for (int64_t q = fr.first_keypoint; q < fr.first_keypoint + fr.num_keypoints && !in_frames; ++q) {
                in_frames =
                    m.keypoint_landmark[q] == d.class_landmark[k] && std::memcmp(row, m.descriptor(q), bytes) == 0;
              }
            }
            own += in_frames;
          }
          const int64_t n = d.fusion.exemplar_begin[k + 1] - d.fusion.exemplar_begin[k];
          rows += n;
          left_out += own < n ? own : 0;
        }
      }
      ASSERT_GT(left_out, 0) << "the calibration frames hold some area's exemplars";
      EXPECT_NE((c.out + c.err)
                    .find("the areas' fusion without the frames' own " + std::to_string(left_out) + " of " +
                          std::to_string(rows) + " exemplars"),
                std::string::npos)
          << c.out << c.err;
    }
    const auto calibrated = AreaBundle::open(cal / "bundle.txt");
    ASSERT_TRUE(calibrated->calibrated()) << c.err;
    EXPECT_GT(calibrated->calibration().num_samples, calibrated->calibration().num_positive);
    const fs::path cal_out = dir_ / "cal_localize.json";
    ASSERT_EQ(run("localize --bundle " + (cal / "bundle.txt").string() + " --map " + map_.string() +
                      " --no-prior --out " + cal_out.string(),
                  dir_)
                  .exit_code,
              0);
    const nlohmann::json cj = nlohmann::json::parse(slurp(cal_out));
    int localized = 0;
    for (const nlohmann::json& fr : cj["modes"][0]["frames"]) {
      const double confidence = fr["confidence"].get<double>();
      if (!fr["success"].get<bool>()) {
        EXPECT_FALSE(fr["localized"].get<bool>());
        continue;
      }
      EXPECT_GE(confidence, 0.0);
      EXPECT_EQ(fr["localized"].get<bool>(), confidence >= calibrated->calibration().threshold);
      localized += fr["localized"].get<bool>();
    }
    EXPECT_EQ(cj["modes"][0]["localized_frames_per_seed"][0].get<int>(), localized);
    // The walk calibration of track(), fitted on walks through the same frames: a tracking mode's
    // `localized` is the walk's verdict, which differs from the frame rule's only where the walk
    // rule adds a pose or the agreement refuses one.
    ASSERT_TRUE(calibrated->walk_calibration().has_value()) << c.err;
    EXPECT_TRUE(calibrated->walk_calibration()->has_agreement());
    EXPECT_NE((c.out + c.err).find("bundle: walk calibration on "), std::string::npos) << c.out << c.err;
    ASSERT_EQ(run("localize --bundle " + (cal / "bundle.txt").string() + " --map " + map_.string() +
                      " --track 1 --out " + cal_out.string(),
                  dir_)
                  .exit_code,
              0);
    const nlohmann::json tj = nlohmann::json::parse(slurp(cal_out));
    EXPECT_EQ(tj["calibration"]["calibrated"], true);
    EXPECT_EQ(tj["calibration"]["saw_wrong_pose"], !calibrated->calibration().saw_no_wrong_pose());
    EXPECT_EQ(tj["calibration"]["walk_calibrated"], true);
    EXPECT_EQ(tj["calibration"]["walk_agreement"], true);
    EXPECT_EQ(tj["calibration"]["walk_rule"], calibrated->walk_calibration()->adds);
    const nlohmann::json& tracking = tj["modes"][0];
    ASSERT_TRUE(tracking.contains("walk")) << tracking.dump();
    int frame_rule = 0, walk_localized = 0, by_walk = 0, disagreeing = 0, refused_by_frame = 0;
    for (const nlohmann::json& fr : tracking["frames"]) {
      const nlohmann::json& w = fr["walk"];
      const bool by_frame = w["frame_rule_localized"].get<bool>();
      const bool reported = fr["localized"].get<bool>();
      frame_rule += by_frame;
      walk_localized += reported;
      by_walk += w["by_walk"].get<bool>();
      disagreeing += w["disagrees"].get<bool>();
      refused_by_frame += by_frame && w["disagrees"].get<bool>();
      EXPECT_TRUE(!reported || by_frame || w["by_walk"].get<bool>()) << fr.dump();
      EXPECT_TRUE(reported || !by_frame || w["disagrees"].get<bool>()) << fr.dump();
      EXPECT_FALSE(reported && w["disagrees"].get<bool>()) << fr.dump();
    }
    EXPECT_EQ(tracking["walk"]["frame_rule_localized_per_seed"][0].get<int>(), frame_rule);
    EXPECT_EQ(tracking["localized_frames_per_seed"][0].get<int>(), walk_localized);
    // The walk's first trusted pose and the time until it; the 95th percentile of a frame's time.
    int64_t first = -1;
    double cpu_to_first = 0.0;
    for (size_t i = 0; i < tracking["frames"].size() && first < 0; ++i) {
      cpu_to_first += tracking["frames"][i]["cpu_ms"].get<double>();
      if (tracking["frames"][i]["localized"].get<bool>()) first = static_cast<int64_t>(i);
    }
    EXPECT_EQ(tracking["first_localized_frame_per_seed"][0].get<int64_t>(), first);
    EXPECT_NEAR(tracking["cpu_ms_to_first_localized_per_seed"][0].get<double>(), first < 0 ? -1.0 : cpu_to_first, 1e-6);
    EXPECT_GE(tracking["cpu_ms_per_frame"]["p95"].get<double>(), tracking["cpu_ms_per_frame"]["median"].get<double>());
    EXPECT_EQ(tracking["walk"]["by_walk"].get<int>(), by_walk);  // one seed
    EXPECT_EQ(tracking["walk"]["disagreeing"].get<int>(), disagreeing);
    EXPECT_EQ(walk_localized, frame_rule - refused_by_frame + by_walk);
    const fs::path other_map = dir_ / "other_map.h5";
    LandmarkMap moved = read_map_h5(map_);
    moved.landmarks.front().position.x() += 1.0;
    write_map_h5(moved, other_map);
    // A refused bundle changes nothing: the calibrated index stays byte for byte.
    const std::string index_before = slurp(cal / "bundle.txt");
    expect_one_error(
        run("bundle --areas " + short_reach.string() + " --models " + cal.string() + " --map " + other_map.string(),
            dir_),
        "bundle", "is not the map");
    expect_one_error(run("bundle --areas " + short_reach.string() + " --models " + cal.string() + " --map " +
                             map_.string() + " --target-precision nan",
                         dir_),
                     "bundle", "--target-precision");
    EXPECT_EQ(slurp(cal / "bundle.txt"), index_before);
    // The bundle knows its map: another map, or a single model of another map beside the bundle,
    // is refused before any frame is posed.
    expect_one_error(run("localize --bundle " + (cal / "bundle.txt").string() + " --map " + other_map.string() +
                             " --no-prior --out " + cal_out.string(),
                         dir_),
                     "localize", "the bundle was made for another map than " + other_map.string());
    expect_one_error(run("eval --bundle " + (cal / "bundle.txt").string() + " --map " + other_map.string() +
                             " --no-prior --report " + cal_out.string(),
                         dir_),
                     "eval", "the bundle was made for another map");
    ModelData shifted = Model::load(cal / "area-0.lbm")->data();
    for (Eigen::Vector3d& p : shifted.class_position) p.x() += 13.0;
    Model(shifted).save(dir_ / "shifted.lbm");
    expect_one_error(run("localize --bundle " + (cal / "bundle.txt").string() + " --map " + map_.string() +
                             " --model " + (dir_ / "shifted.lbm").string() + " --no-prior --out " + cal_out.string(),
                         dir_),
                     "localize", "(the model was trained on another map)");
    // An area file swapped for another area's model (its size and CRC-32 copied into the index) is
    // refused when it loads, and so is a model of another map under an old index that records no
    // map: the areas are checked against --map as they load.
    if (num_areas >= 2) {
      const fs::path swap = dir_ / "swap_bundle";
      fs::create_directories(swap);
      for (int id = 0; id < num_areas; ++id) {
        const std::string name = "area-" + std::to_string(id) + ".lbm";
        fs::copy_file(cal / name, swap / name, fs::copy_options::overwrite_existing);
      }
      ASSERT_EQ(run("bundle --areas " + short_reach.string() + " --models " + swap.string(), dir_).exit_code, 0);
      BundleIndex index = read_bundle_index(swap / "bundle.txt");
      Model(shifted).save(swap / "area-0.lbm");
      const std::string bytes = slurp(swap / "area-0.lbm");
      index.areas[0].bytes = bytes.size();
      index.areas[0].crc32 = crc32(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size());
      write_bundle_index(swap / "bundle.txt", index);
      const RunResult r = run("localize --bundle " + (swap / "bundle.txt").string() + " --map " + map_.string() +
                                  " --no-prior --out " + cal_out.string(),
                              dir_);
      EXPECT_EQ(r.exit_code, 0) << r.err;
      EXPECT_NE(r.err.find("lboost localize: warning: "), std::string::npos) << r.err;
      EXPECT_NE(r.err.find("area 0 (area-0.lbm): its classes (landmark ids and positions) differ"), std::string::npos)
          << r.err;
      // Version 1 (no map, no classes): the same model is refused by the map check.
      char crc[16];
      std::snprintf(crc, sizeof(crc), "%08x", index.areas[0].crc32);
      std::string v1 = "lmb-bundle 1\nreach " + exact_number_text(index.reach) + "\nareas " +
                       std::to_string(index.areas.size()) + "\n";
      for (const BundleArea& a : index.areas) {
        std::snprintf(crc, sizeof(crc), "%08x", a.crc32);
        v1 += "area " + std::to_string(a.id) + " file " + a.file + " bytes " + std::to_string(a.bytes) + " crc32 " +
              crc + " landmarks " + std::to_string(a.landmarks) + " cell";
        for (int k = 0; k < 3; ++k) v1 += " " + exact_number_text(a.cell_lo[k]);
        for (int k = 0; k < 3; ++k) v1 += " " + exact_number_text(a.cell_hi[k]);
        v1 += "\n";
      }
      write_file_atomically(swap / "bundle.txt", v1);
      const RunResult r1 = run("localize --bundle " + (swap / "bundle.txt").string() + " --map " + map_.string() +
                                   " --no-prior --out " + cal_out.string(),
                               dir_);
      EXPECT_EQ(r1.exit_code, 0) << r1.err;
      EXPECT_NE(r1.err.find("area 0 (area-0.lbm): the area's model: class 0"), std::string::npos) << r1.err;
      EXPECT_NE(r1.err.find("(the model was trained on another map)"), std::string::npos) << r1.err;
    }
  }
  // A damaged area: the run goes on without it, naming it once per frame that selects it.
  std::string image = slurp(models / "area-1.lbm");
  image[image.size() / 2] ^= 0x20;
  write_file_atomically(models / "area-1.lbm", image);
  const RunResult d = run(localize, dir_);
  ASSERT_EQ(d.exit_code, 0) << d.err;
  // Said on stderr once, in one line.
  EXPECT_EQ(std::count(d.err.begin(), d.err.end(), '\n'), 1) << d.err;
  EXPECT_EQ(d.err.rfind("lboost localize: warning: ", 0), 0u) << d.err;
  EXPECT_NE(d.err.find("area 1 (area-1.lbm): CRC-32 mismatch"), std::string::npos) << d.err;
  const nlohmann::json dj = nlohmann::json::parse(slurp(out));
  const nlohmann::json& nf = dj["modes"][2]["frames"];
  for (size_t i = 0; i < nf.size(); ++i) {
    EXPECT_EQ(nf[i]["areas_scored"].get<int>(), num_areas - 1);
    ASSERT_EQ(nf[i]["errors"].size(), 1u);
    const std::string e = nf[i]["errors"][0];
    EXPECT_NE(e.find("area 1 (area-1.lbm): CRC-32 mismatch"), std::string::npos) << e;
    EXPECT_NE(nf[i]["area"], 1);
  }
  // No area loads: exit 1 and one line, not a table of zeros.
  {
    const fs::path broken = dir_ / "broken_bundle";
    fs::create_directories(broken);
    for (int id = 0; id < num_areas; ++id) {
      const std::string name = "area-" + std::to_string(id) + ".lbm";
      fs::copy_file(models / name, broken / name, fs::copy_options::overwrite_existing);
    }
    fs::copy_file(models / "bundle.txt", broken / "bundle.txt", fs::copy_options::overwrite_existing);
    for (int id = 0; id < num_areas; ++id) fs::remove(broken / ("area-" + std::to_string(id) + ".lbm"));
    for (const std::string command : {"localize", "eval"}) {
      const RunResult r = run(command + " --bundle " + (broken / "bundle.txt").string() + " --map " + map_.string() +
                                  " --no-prior --prior-noise 0.5 " + (command == "eval" ? "--report " : "--out ") +
                                  (dir_ / "broken.json").string(),
                              dir_);
      expect_one_error(r, command, "no area could be loaded");
      EXPECT_FALSE(fs::exists(dir_ / "broken.json"));
    }
  }
  // Bad flags: one line.
  expect_one_error(run("localize --bundle " + (models / "bundle.txt").string() + " --map " + map_.string() + " --out " +
                           out.string(),
                       dir_),
                   "localize", "--bundle needs --prior-noise METRES, --track METRES and/or --no-prior");
  expect_one_error(run("localize --bundle " + (models / "bundle.txt").string() + " --map " + map_.string() +
                           " --track 0 --out " + out.string(),
                       dir_),
                   "localize", "--track 0: must be finite and > 0");
  expect_one_error(run("localize --bundle " + (models / "bundle.txt").string() + " --map " + map_.string() +
                           " --no-prior --track-prior-noise 5 --out " + out.string(),
                       dir_),
                   "localize", "--track-prior-noise 5: must be finite and needs --track");
  expect_one_error(run("localize --bundle " + (models / "bundle.txt").string() + " --map " + map_.string() +
                           " --prior-noise -2 --out " + out.string(),
                       dir_),
                   "localize", "--prior-noise -2: must be finite and >= 0");
  expect_one_error(run("localize --map " + map_.string() + " --no-prior --out " + out.string(), dir_), "localize",
                   "--prior-noise, --track and --no-prior need --bundle");
  expect_one_error(run("eval --map " + map_.string() + " --report " + out.string(), dir_), "eval",
                   "--model is required (or --bundle)");
}

TEST_F(AreasCliTest, BadAreaArgumentsFailWithOneLine) {
  const fs::path out = dir_ / "bad";
  const std::string areas = (dir_ / "areas.txt").string();
  expect_one_error(run(train_args(areas, out), dir_), "train", "expected FILE:ID");
  expect_one_error(run(train_args(areas + ":99", out), dir_), "train", "has no area 99");
  expect_one_error(run(train_args((dir_ / "missing.txt").string() + ":0", out), dir_), "train", "missing.txt");
  expect_one_error(run("train --synthetic small --rounds 2 --area " + areas + ":0 --out " + out.string(), dir_),
                   "train", "--area trains an area of a map");
  // An areas file of another map.
  AreaFile other = read_area_file(areas);
  other.map_fingerprint ^= 1;
  write_area_file(dir_ / "other_areas.txt", other, "");
  expect_one_error(run(train_args((dir_ / "other_areas.txt").string() + ":0", out), dir_), "train",
                   "made from another map");
  EXPECT_FALSE(fs::exists(out / "config.toml"));
  expect_one_error(
      run("areas --map " + map_.string() + " --out " + (dir_ / "x.txt").string() + " --max-classes 0", dir_), "areas",
      "--max-classes 0: must be >= 1");
  expect_one_error(
      run("areas --map " + map_.string() + " --out " + (dir_ / "x.txt").string() + " --prior-noise -1", dir_), "areas",
      "--prior-noise -1: must be finite and >= 0");
}

}  // namespace
}  // namespace lmb
