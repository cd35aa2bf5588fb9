#include "train/mapping/camera_refinement.h"

#include <cmath>

#include <gtest/gtest.h>

#include "common/error.h"
#include "common/random.h"
#include "synthetic_scene.h"

namespace lmb {
namespace {

// Tracks of the synthetic corridor's points seen by its map frames with `camera` (exact pixels plus
// noise); each track starts at its point moved by `offset` metres in a random direction.
std::vector<RefinementTrack> corridor_tracks(const test::SyntheticScene& scene, const Camera& camera, double noise_px,
                                             double offset, Rng* rng) {
  std::vector<RefinementTrack> tracks;
  for (size_t p = 0; p < scene.points.size(); ++p) {
    RefinementTrack t;
    for (size_t f = 0; f < scene.frames.size(); ++f) {
      const Eigen::Vector3d x = scene.frames[f].cam_from_world * scene.points[p];
      Eigen::Vector2d pixel;
      if (x.z() < 0.3 || !camera.project(x, &pixel)) continue;
      if (pixel.x() < 0 || pixel.y() < 0 || pixel.x() > camera.width || pixel.y() > camera.height) continue;
      t.frames.push_back(static_cast<int>(f));
      t.pixels.push_back(pixel + noise_px * Eigen::Vector2d(rng->normal(), rng->normal()));
    }
    if (t.frames.size() < 3) continue;
    t.position = scene.points[p] + offset * Eigen::Vector3d(rng->normal(), rng->normal(), rng->normal()).normalized();
    tracks.push_back(std::move(t));
  }
  return tracks;
}

struct CorridorSetup {
  test::SyntheticScene scene;
  std::vector<Rigid3d> poses;
  std::vector<camera_t> frame_camera;
};

CorridorSetup corridor() {
  test::SyntheticSceneOptions o;
  o.num_points = 800;
  o.num_query_frames = 0;
  CorridorSetup s{test::make_synthetic_scene(o), {}, {}};
  for (const MapperFrame& f : s.scene.frames) {
    s.poses.push_back(f.cam_from_world);
    s.frame_camera.push_back(0);
  }
  return s;
}

TEST(RefineCameras, RecoversAPerturbedFocalLength) {
  const CorridorSetup s = corridor();
  Rng rng(7);
  const auto tracks = corridor_tracks(s.scene, s.scene.camera, 0.3, 0.05, &rng);
  ASSERT_GT(tracks.size(), 300u);
  const Camera wrong = scaled_camera(s.scene.camera, 1.08);
  CameraRefinementOptions options;
  const CameraRefinementResult r = refine_cameras({wrong}, s.poses, s.frame_camera, tracks, options);
  std::printf("focal %.3f -> %.3f (true %.3f) in %d iterations; error %.3f -> %.3f px\n", wrong.mean_focal_length(),
              r.cameras[0].mean_focal_length(), s.scene.camera.mean_focal_length(), r.iterations,
              r.mean_error_before_px[0], r.mean_error_after_px[0]);
  EXPECT_NEAR(r.cameras[0].mean_focal_length() / s.scene.camera.mean_focal_length(), 1.0, 0.002);
  EXPECT_NEAR(r.cameras[0].params[1] / r.cameras[0].params[0], 1.0, 1e-12);  // the aspect ratio stays
  EXPECT_EQ(r.cameras[0].params[2], wrong.params[2]);                        // the principal point too
  EXPECT_LT(r.mean_error_after_px[0], 0.5);
  EXPECT_GT(r.mean_error_before_px[0], 2.0 * r.mean_error_after_px[0]);
  EXPECT_EQ(r.positions.size(), tracks.size());
  EXPECT_LT(r.iterations, options.max_iterations);
}

TEST(RefineCameras, RecoversFocalAndPrincipalPoint) {
  const CorridorSetup s = corridor();
  Rng rng(8);
  const auto tracks = corridor_tracks(s.scene, s.scene.camera, 0.3, 0.05, &rng);
  const Camera wrong = scaled_camera(s.scene.camera, 0.94, Eigen::Vector2d(6, -4));
  CameraRefinementOptions options;
  options.principal_point = true;
  const CameraRefinementResult r = refine_cameras({wrong}, s.poses, s.frame_camera, tracks, options);
  EXPECT_NEAR(r.cameras[0].mean_focal_length() / s.scene.camera.mean_focal_length(), 1.0, 0.003);
  EXPECT_NEAR((r.cameras[0].principal_point() - s.scene.camera.principal_point()).norm(), 0.0, 1.0);
  EXPECT_LT(r.mean_error_after_px[0], 0.5);
}

TEST(RefineCameras, OutliersAndTooFewObservations) {
  const CorridorSetup s = corridor();
  Rng rng(9);
  auto tracks = corridor_tracks(s.scene, s.scene.camera, 0.3, 0.02, &rng);
  for (size_t t = 0; t < tracks.size(); t += 10) tracks[t].pixels[0] += Eigen::Vector2d(40, -25);  // wrong matches
  const Camera wrong = scaled_camera(s.scene.camera, 1.05);
  const CameraRefinementResult r = refine_cameras({wrong}, s.poses, s.frame_camera, tracks, {});
  EXPECT_NEAR(r.cameras[0].mean_focal_length() / s.scene.camera.mean_focal_length(), 1.0, 0.003);
  // A camera with fewer observations than the minimum is left as it is.
  CameraRefinementOptions strict;
  strict.min_observations = 1000000;
  const CameraRefinementResult kept = refine_cameras({wrong}, s.poses, s.frame_camera, tracks, strict);
  EXPECT_EQ(kept.cameras[0].params, wrong.params);
}

TEST(RefineCameras, BadInputThrows) {
  const CorridorSetup s = corridor();
  RefinementTrack t;
  t.frames = {0, static_cast<int>(s.poses.size())};
  t.pixels = {Eigen::Vector2d(1, 1), Eigen::Vector2d(2, 2)};
  EXPECT_THROW(refine_cameras({s.scene.camera}, s.poses, s.frame_camera, {t}, {}), Error);
  t.frames = {0};
  EXPECT_THROW(refine_cameras({s.scene.camera}, s.poses, s.frame_camera, {t}, {}), Error);
  CameraRefinementOptions bad;
  bad.huber_px = 0;
  EXPECT_THROW(refine_cameras({s.scene.camera}, s.poses, s.frame_camera, {}, bad), Error);
}

}  // namespace
}  // namespace lmb
