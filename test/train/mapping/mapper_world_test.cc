// The mapper on a rendered world (lboost world --preset tiny): landmark positions and track purity
// against the world's exact depth maps.
#include <unistd.h>

#include <cstdio>

#include <gtest/gtest.h>

#include "common/io/map_h5.h"
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
  std::printf("tiny world: %lld landmarks, %.2f map obs/landmark, %lld query keypoints with a landmark; "
              "purity %.4f (observations %.4f, pure tracks %.4f); position error median %.4f m, "
              "mean %.4f m, p90 %.4f m; hamming NN precision@1 %.4f; mapping %.1f s\n",
              static_cast<long long>(stats.num_landmarks), stats.mean_map_observations,
              static_cast<long long>(stats.num_query_observations), a.mean_track_purity, a.observation_purity,
              a.pure_track_share, a.median_position_error_m, a.mean_position_error_m, a.p90_position_error_m,
              nn.precision_at_1, stats.total_seconds);
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

}  // namespace
}  // namespace lmb
