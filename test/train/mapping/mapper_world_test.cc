// The mapper on a rendered world (lboost world --preset tiny): landmark positions and track purity
// against the world's exact depth maps.
#include <unistd.h>

#include <array>
#include <cstdio>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include "common/io/colmap_model.h"
#include "common/io/map_h5.h"
#include "common/io/session_file.h"
#include "train/mapping/depth_ground_truth.h"
#include "train/mapping/descriptor_nn.h"
#include "train/mapping/mapper.h"
#include "train/world/world_model.h"
#include "train/world/world_writer.h"

namespace lmb {
namespace {

namespace fs = std::filesystem;

TEST(MapperOnRenderedWorld, TinyWorldMatchesDepthGroundTruth) {
  const fs::path dir = fs::temp_directory_path() / ("lmb_mapper_world_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  WorldOptions world = world_preset("tiny");
  world.seed = 1;
  write_world(world, dir / "world");

  MapperOptions options;
  MapperStats stats;
  const LandmarkMap map = map_collection(dir / "world", options, &stats);
  write_map_h5(map, dir / "map.h5");
  const LandmarkMap reread = read_map_h5(dir / "map.h5");
  EXPECT_EQ(reread.keypoint_landmark, map.keypoint_landmark);

  const MapAccuracy a = check_map_against_depth(reread, dir / "world");
  const HammingNnStats nn = evaluate_hamming_nn(reread, 2);
  std::printf(
      "tiny world: %lld landmarks, %.2f map obs/landmark, %lld query keypoints with a landmark; "
      "purity %.4f (observations %.4f, pure tracks %.4f); position error median %.4f m, "
      "mean %.4f m, p90 %.4f m; hamming NN precision@1 %.4f; mapping %.1f s\n",
      static_cast<long long>(stats.num_landmarks), stats.mean_map_observations,
      static_cast<long long>(stats.num_query_observations), a.mean_track_purity, a.observation_purity,
      a.pure_track_share, a.median_position_error_m, a.mean_position_error_m, a.p90_position_error_m, nn.precision_at_1,
      stats.total_seconds);
  EXPECT_EQ(stats.num_map_frames, world.map_frames);
  EXPECT_EQ(stats.num_query_frames, world.query_frames);
  EXPECT_GT(stats.num_landmarks, 1000);
  EXPECT_GT(stats.num_query_observations, 500);
  EXPECT_GT(a.landmarks_checked, 0.95 * stats.num_landmarks);
  EXPECT_GT(a.mean_track_purity, 0.95);
  EXPECT_GT(a.observation_purity, 0.95);
  EXPECT_LT(a.median_position_error_m, 0.03);
  EXPECT_LT(a.p90_position_error_m, 0.15);
  fs::remove_all(dir);
}

// Two map sessions of the tiny world (same total map frames): tracks join the sessions, and the
// map's landmarks stay as clean. Then the same sessions as two collections joined by
// map_collections give the same map, frame for frame, with labelled names.
TEST(MapperOnRenderedWorld, TwoMapSessionsJoinAndCollectionsJoinTheSame) {
  const fs::path dir = fs::temp_directory_path() / ("lmb_mapper_sessions_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  WorldOptions world = world_preset("tiny");
  world.seed = 1;
  world.map_sessions = 2;
  world.image_scale = 0.5;  // 320 x 240, as the default preset: a quarter of the pixels
  world.map_frames = 60;    // 30 a session
  write_world(world, dir / "world");

  MapperOptions options;
  MapperStats stats;
  const LandmarkMap map = map_collection(dir / "world", options, &stats);
  write_map_h5(map, dir / "map.h5");
  const LandmarkMap reread = read_map_h5(dir / "map.h5");
  ASSERT_EQ(reread.sessions.size(), 3u);
  EXPECT_EQ(reread.sessions[0].name, "map");
  EXPECT_EQ(reread.sessions[1].name, "map-2");
  EXPECT_EQ(reread.sessions[2].name, "query");
  EXPECT_EQ(reread.sessions[2].kind, SessionKind::kQuery);
  std::vector<int> frames_per_session(3, 0);
  for (const MapFrame& f : reread.frames) {
    ++frames_per_session[static_cast<size_t>(f.session)];
    EXPECT_EQ(f.name.substr(0, f.name.find('/')), reread.sessions[static_cast<size_t>(f.session)].name);
  }
  EXPECT_EQ(frames_per_session, (std::vector<int>{30, 30, world.query_frames}));

  // Landmarks seen from both map sessions, and their accuracy against the depth maps.
  std::vector<std::array<int, 2>> seen(reread.landmarks.size(), {0, 0});
  for (const MapFrame& f : reread.frames) {
    if (f.session > 1) continue;
    for (int64_t k = f.first_keypoint; k < f.first_keypoint + f.num_keypoints; ++k) {
      if (reread.keypoint_landmark[k] >= 0) ++seen[reread.keypoint_landmark[k]][f.session];
    }
  }
  int64_t both = 0;
  for (const auto& c : seen) both += c[0] > 0 && c[1] > 0;
  const MapAccuracy a = check_map_against_depth(reread, dir / "world");
  std::printf(
      "tiny world, 2 map sessions: %lld landmarks, %lld (%.1f%%) observed in both map sessions, %.2f map "
      "obs/landmark, %lld query keypoints with a landmark; purity %.4f, position error median %.4f m, "
      "p90 %.4f m\n",
      static_cast<long long>(stats.num_landmarks), static_cast<long long>(both),
      100.0 * static_cast<double>(both) / std::max<double>(1.0, static_cast<double>(stats.num_landmarks)),
      stats.mean_map_observations, static_cast<long long>(stats.num_query_observations), a.mean_track_purity,
      a.median_position_error_m, a.p90_position_error_m);
  EXPECT_GT(stats.num_landmarks, 600);
  EXPECT_GT(both, 0.4 * static_cast<double>(stats.num_landmarks));
  EXPECT_GT(stats.num_query_observations, 300);
  EXPECT_GT(a.mean_track_purity, 0.93);  // half resolution: less than the full-resolution test's 0.95
  EXPECT_LT(a.median_position_error_m, 0.03);

  // The sessions as two collections: "a" holds map, "b" holds map-2 and query (the same frame
  // order), with links to the world's images. The image lines are copied as text: a pose read and
  // written again may move by an ulp (the reader normalizes quaternions).
  auto write_part = [&](const std::string& name, const std::vector<std::string>& session_names) {
    const fs::path part = dir / name;
    fs::create_directories(part / "images");
    fs::create_directories(part / "sparse");
    fs::copy_file(dir / "world" / "sparse" / "cameras.txt", part / "sparse" / "cameras.txt");
    std::vector<MapSession> sessions;
    for (const std::string& s : session_names) {
      fs::create_symlink(dir / "world" / "images" / s, part / "images" / s);
      sessions.push_back(reread.sessions[static_cast<size_t>(reread.find_session(s))]);
    }
    std::ifstream in(dir / "world" / "sparse" / "images.txt");
    std::ofstream out(part / "sparse" / "images.txt");
    std::string line, points;
    while (std::getline(in, line)) {
      if (line.empty() || line[0] == '#') continue;
      std::getline(in, points);  // the image's 2D points line (empty here)
      const std::string image_name = line.substr(line.rfind(' ') + 1);
      for (const std::string& s : session_names) {
        if (image_name.rfind(s + "/", 0) == 0) out << line << '\n' << points << '\n';
      }
    }
    write_session_file(sessions, part / kSessionFileName);
    return part;
  };
  const fs::path part_a = write_part("a", {"map"}), part_b = write_part("b", {"map-2", "query"});
  MapperStats joined_stats;
  const LandmarkMap joined = map_collections({{part_a, "", ""}, {part_b, "", ""}}, options, &joined_stats);
  ASSERT_EQ(joined.sessions.size(), 3u);
  EXPECT_EQ(joined.sessions[0].name, "a/map");
  EXPECT_EQ(joined.sessions[1].name, "b/map-2");
  EXPECT_EQ(joined.sessions[2].name, "b/query");
  ASSERT_EQ(joined.frames.size(), map.frames.size());
  EXPECT_EQ(joined.cameras.size(), 2u);  // one per collection
  for (size_t f = 0; f < map.frames.size(); ++f) {
    EXPECT_EQ(joined.frames[f].name, (f < 30 ? "a/" : "b/") + map.frames[f].name);
    EXPECT_EQ(joined.frames[f].session, map.frames[f].session);
    EXPECT_EQ(joined.frames[f].camera, f < 30 ? 0 : 1);
    EXPECT_EQ(joined.frames[f].num_keypoints, map.frames[f].num_keypoints);
  }
  EXPECT_EQ(joined.descriptors, map.descriptors);
  EXPECT_EQ(joined.keypoint_landmark, map.keypoint_landmark);
  ASSERT_EQ(joined.landmarks.size(), map.landmarks.size());
  for (size_t l = 0; l < map.landmarks.size(); ++l) {
    EXPECT_EQ(joined.landmarks[l].position, map.landmarks[l].position);
    EXPECT_EQ(joined.landmarks[l].num_map_observations, map.landmarks[l].num_map_observations);
  }
  // Labels: given ones replace the folder names; two collections with one label are refused.
  const LandmarkMap labelled = map_collections({{part_a, "day1", ""}, {part_b, "day2", ""}}, options);
  EXPECT_EQ(labelled.sessions[1].name, "day2/map-2");
  EXPECT_THROW(map_collections({{part_a, "x", ""}, {part_b, "x", ""}}, options), Error);
  fs::remove_all(dir);
}

// Wrong intrinsics: the tiny world rendered with its focal length and mapped with one 8% longer.
// The focal check flags it; the refinement (on, and auto after the check) recovers the rendered
// focal length within 1%, and the map it writes (with the refined camera) gets back the landmarks
// of the right one. With the right focal length auto leaves the camera as it is.
TEST(MapperOnRenderedWorld, RefineFocalRecoversTheRenderedFocalLength) {
  const fs::path dir = fs::temp_directory_path() / ("lmb_mapper_focal_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  WorldOptions world = world_preset("tiny");
  world.seed = 1;
  write_world(world, dir / "world");
  MapperOptions options;
  MapperStats right;
  const LandmarkMap right_map = map_collection(dir / "world", options, &right);
  const double focal = right_map.cameras[0].mean_focal_length();
  ASSERT_EQ(right.focal_check.size(), 1u);
  EXPECT_NEAR(right.focal_check[0].fitted_focal_px / focal, 1.0, 0.005);
  EXPECT_FALSE(right.refined);  // auto: the check moved it by less than 1%
  EXPECT_EQ(right_map.cameras[0].params, read_colmap_model(dir / "world" / "sparse").cameras.begin()->second.params);

  ColmapModel model = read_colmap_model(dir / "world" / "sparse");
  for (auto& [id, camera] : model.cameras) camera = scaled_camera(camera, 1.08);
  fs::create_directories(dir / "wrong" / "sparse");
  write_colmap_text(model, dir / "wrong" / "sparse");
  fs::create_symlink(dir / "world" / "images", dir / "wrong" / "images");
  fs::copy_file(dir / "world" / kSessionFileName, dir / "wrong" / kSessionFileName);
  MapperStats wrong;
  options.refine_focal = FocalRefinement::kOff;
  map_collection(dir / "wrong", options, &wrong);
  EXPECT_FALSE(wrong.refined);
  ASSERT_EQ(wrong.focal_check.size(), 1u);
  EXPECT_NEAR(wrong.focal_check[0].focal_px, 1.08 * focal, 1e-9);
  EXPECT_LT(wrong.focal_check[0].fitted_focal_px, 1.05 * focal);  // flagged: moves toward the truth
  EXPECT_LT(wrong.num_landmarks, right.num_landmarks / 2);

  options.refine_focal = FocalRefinement::kOn;
  MapperStats refined;
  const LandmarkMap map = map_collection(dir / "wrong", options, &refined);
  std::printf(
      "tiny world, focal %.2f px mapped as %.2f px: refined to %.2f px in %d round(s); landmarks %lld (right focal "
      "%lld, wrong %lld), query keypoints with a landmark %lld (%lld, %lld)\n",
      focal, 1.08 * focal, map.cameras[0].mean_focal_length(), refined.refine_rounds,
      static_cast<long long>(refined.num_landmarks), static_cast<long long>(right.num_landmarks),
      static_cast<long long>(wrong.num_landmarks), static_cast<long long>(refined.num_query_observations),
      static_cast<long long>(right.num_query_observations), static_cast<long long>(wrong.num_query_observations));
  EXPECT_NEAR(map.cameras[0].mean_focal_length() / focal, 1.0, 0.01);
  EXPECT_EQ(map.cameras[0].params[2], model.cameras.begin()->second.params[2]);  // principal point kept
  ASSERT_EQ(refined.cameras_before.size(), 1u);
  EXPECT_EQ(refined.cameras_before[0].params, model.cameras.begin()->second.params);
  EXPECT_EQ(refined.cameras_after[0].params, map.cameras[0].params);
  EXPECT_TRUE(refined.focal_check.empty());
  EXPECT_GT(refined.num_landmarks, 0.9 * static_cast<double>(right.num_landmarks));
  EXPECT_GT(refined.num_query_observations, 0.9 * static_cast<double>(right.num_query_observations));
  EXPECT_LT(refined.reprojection_error_after_px, refined.reprojection_error_before_px);
  EXPECT_TRUE(refined.refined);
  write_map_h5(map, dir / "map.h5");
  EXPECT_EQ(read_map_h5(dir / "map.h5").cameras[0].params, map.cameras[0].params);

  // auto: the check flags the camera, then the same refinement runs (the check is kept).
  options.refine_focal = FocalRefinement::kAuto;
  MapperStats automatic;
  const LandmarkMap auto_map = map_collection(dir / "wrong", options, &automatic);
  EXPECT_TRUE(automatic.refined);
  ASSERT_EQ(automatic.focal_check.size(), 1u);
  EXPECT_EQ(automatic.focal_check[0].fitted_focal_px, wrong.focal_check[0].fitted_focal_px);
  EXPECT_EQ(auto_map.cameras[0].params, map.cameras[0].params);
  EXPECT_EQ(automatic.num_landmarks, refined.num_landmarks);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace lmb
