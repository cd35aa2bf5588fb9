#include "train/world/renderer.h"

#include <cmath>

#include <gtest/gtest.h>
#include <opencv2/features2d.hpp>

#include "common/error.h"
#include "train/world/trajectory.h"

namespace lmb {
namespace {

// Distance from a world point to the nearest surface of the world (corridor faces and box faces).
double distance_to_surfaces(const World& w, const Eigen::Vector3d& p) {
  double d = std::min({std::abs(p.z()), std::abs(p.z() - w.height), std::abs(p.y() + w.width / 2),
                       std::abs(p.y() - w.width / 2), std::abs(p.x()), std::abs(p.x() - w.length)});
  for (const Box& b : w.boxes) {
    for (int axis = 0; axis < 3; ++axis) {
      bool inside_face = true;
      for (int o = 0; o < 3; ++o) {
        if (o != axis && (p[o] < b.lo[o] - 1e-3 || p[o] > b.hi[o] + 1e-3)) inside_face = false;
      }
      if (!inside_face) continue;
      d = std::min({d, std::abs(p[axis] - b.lo[axis]), std::abs(p[axis] - b.hi[axis])});
    }
  }
  return d;
}

TEST(RendererTest, RayTableRoundTripsThroughTheCamera) {
  const RayTable rays(world_camera(), 2);
  const Camera& cam = rays.camera();
  for (int r = 0; r < cam.height; r += 37) {
    for (int c = 0; c < cam.width; c += 41) {
      const Eigen::Vector2d back = cam.img_from_cam(rays.centre(c, r).cast<double>());
      EXPECT_NEAR(back.x(), c + 0.5, 1e-3);
      EXPECT_NEAR(back.y(), r + 0.5, 1e-3);
      const Eigen::Vector2d s3 = cam.img_from_cam(rays.sample(c, r, 3).cast<double>());
      EXPECT_NEAR(s3.x(), c + 0.75, 1e-3);
      EXPECT_NEAR(s3.y(), r + 0.75, 1e-3);
    }
  }
  // Barrel distortion: the corner pixel's ray is wider than the pinhole ray.
  EXPECT_GT(std::abs(rays.centre(0, 0).x()), 319.5 / 460.0);
  Camera bad = world_camera();
  bad.params[4] = -3.0;  // folds over inside the image
  EXPECT_THROW(RayTable(bad, 1), Error);
}

TEST(RendererTest, CastRayKnownAnswers) {
  const World w = build_world(world_preset("tiny"));
  SurfaceHit hit;
  ASSERT_TRUE(cast_ray(w, Eigen::Vector3d(2.1, 0.0, 1.5), Eigen::Vector3d(0, 0, -2), &hit));
  EXPECT_EQ(hit.box, -1);
  EXPECT_EQ(hit.surface, Surface::kFloor);
  EXPECT_NEAR(hit.t, 0.75, 1e-12);
  EXPECT_NEAR(hit.point.z(), 0.0, 1e-12);
  ASSERT_TRUE(cast_ray(w, Eigen::Vector3d(2.1, 0.0, 1.5), Eigen::Vector3d(0, 0, 1), &hit));
  EXPECT_EQ(hit.surface, Surface::kCeiling);
  EXPECT_NEAR(hit.t, w.height - 1.5, 1e-12);
  // Towards the first pillar (x = 4, on the right wall, 0.25 m deep): its front face.
  ASSERT_TRUE(cast_ray(w, Eigen::Vector3d(4.0, 0.0, 1.5), Eigen::Vector3d(0, -1, 0), &hit));
  EXPECT_GE(hit.box, 0);
  EXPECT_NEAR(hit.t, w.width / 2 - 0.25, 1e-12);
  EXPECT_EQ(hit.normal, Eigen::Vector3d(0, 1, 0));
  // Next to it the wall.
  ASSERT_TRUE(cast_ray(w, Eigen::Vector3d(3.0, 0.0, 1.5), Eigen::Vector3d(0, -1, 0), &hit));
  EXPECT_EQ(hit.box, -1);
  EXPECT_EQ(hit.surface, Surface::kWallRight);
  EXPECT_FALSE(cast_ray(w, Eigen::Vector3d(-1.0, 0.0, 1.5), Eigen::Vector3d(-1, 0, 0), &hit));
}

TEST(RendererTest, DepthBackProjectsOntoWorldSurfaces) {
  const World w = build_world(world_preset("tiny"));
  const RayTable rays(world_camera(), 1);
  const Session s = make_map_session(w, 6);
  const Camera& cam = rays.camera();
  for (int f : {1, 4}) {
    const RenderedFrame frame = render_frame(w, rays, s.cam_from_world[f], s.lighting, f, 2);
    const Rigid3d world_from_cam = s.cam_from_world[f].inverse();
    int floor_pixels = 0;
    double worst = 0.0;
    for (int r = 0; r < cam.height; r += 7) {
      for (int c = 0; c < cam.width; c += 7) {
        const uint16_t mm = frame.depth_mm.at<uint16_t>(r, c);
        ASSERT_GT(mm, 0);
        // Back-project with the camera model (independently of the ray table).
        const Eigen::Vector2d n = cam.cam_from_img(Eigen::Vector2d(c + 0.5, r + 0.5));
        const Eigen::Vector3d x = world_from_cam * (mm * 1e-3 * Eigen::Vector3d(n.x(), n.y(), 1.0));
        // Depth is rounded to 1 mm along z; the ray is at most ~1.6x longer.
        worst = std::max(worst, distance_to_surfaces(w, x));
        if (r > cam.height * 3 / 4 && std::abs(x.z()) < 2e-3) ++floor_pixels;
      }
    }
    EXPECT_LT(worst, 2e-3) << "frame " << f;
    EXPECT_GT(floor_pixels, 100) << "frame " << f;  // the lower image shows floor at z ~ 0
  }
}

TEST(RendererTest, RenderingIsDeterministicAndThreadCountIndependent) {
  const World w = build_world(world_preset("tiny"));
  const RayTable rays(world_camera(), 1);
  const Session s = make_query_session(w, 3);
  const RenderedFrame a = render_frame(w, rays, s.cam_from_world[1], s.lighting, 7, 1);
  const RenderedFrame b = render_frame(w, rays, s.cam_from_world[1], s.lighting, 7, 2);
  EXPECT_EQ(cv::countNonZero(a.image != b.image), 0);
  EXPECT_EQ(cv::countNonZero(a.depth_mm != b.depth_mm), 0);
  // Another frame key changes the noise only.
  const RenderedFrame c = render_frame(w, rays, s.cam_from_world[1], s.lighting, 8, 2);
  EXPECT_GT(cv::countNonZero(a.image != c.image), 1000);
  EXPECT_EQ(cv::countNonZero(a.depth_mm != c.depth_mm), 0);
  cv::Scalar mean = cv::mean(a.image);
  EXPECT_GT(mean[0], 60.0);   // neither black
  EXPECT_LT(mean[0], 220.0);  // nor blown out
}

// Renders door `k` head-on from 1.2 m under flat lighting and returns the image region inside the
// door leaf, plus BRISK descriptors computed at fixed keypoints of that region.
struct DoorView {
  cv::Mat patch;
  cv::Mat descriptors;
};

DoorView view_door(const World& w, const RayTable& rays, const Decal& door, std::vector<cv::KeyPoint>* keypoints) {
  const double xc = 0.5 * (door.a0 + door.a1);
  const bool left = door.surface == Surface::kWallLeft;
  const double y_wall = left ? w.width / 2 : -w.width / 2;
  const Eigen::Vector3d centre(xc, y_wall + (left ? -1.2 : 1.2), 1.05);
  const Rigid3d pose = cam_from_world_pose(centre, left ? M_PI / 2 : -M_PI / 2, 0.0, 0.0);
  Lighting flat;
  flat.flat = true;
  const RenderedFrame f = render_frame(w, rays, pose, flat, 0, 2);
  // The door leaf (0.95 x 2.1 m) covers at least the central 200 x 300 pixels from 1.2 m.
  DoorView v;
  v.patch = f.image(cv::Rect(220, 90, 200, 300)).clone();
  if (keypoints->empty()) cv::BRISK::create()->detect(v.patch, *keypoints);
  std::vector<cv::KeyPoint> kps = *keypoints;
  cv::BRISK::create()->compute(v.patch, kps, v.descriptors);
  EXPECT_EQ(kps.size(), keypoints->size());
  return v;
}

double mean_hamming(const cv::Mat& a, const cv::Mat& b) {
  double sum = 0;
  for (int i = 0; i < a.rows; ++i) sum += cv::norm(a.row(i), b.row(i), cv::NORM_HAMMING);
  return sum / std::max(1, a.rows);
}

TEST(RendererTest, DoorsAliasInTheAliasedWorldAndDifferInTheControlWorld) {
  WorldOptions o = world_preset("tiny");
  o.length_m = 20.0;
  const RayTable rays(world_camera(), 2);
  for (bool non_aliased : {false, true}) {
    o.non_aliased = non_aliased;
    const World w = build_world(o);
    // Two doors on the same wall, far apart.
    const Decal* first = nullptr;
    const Decal* second = nullptr;
    for (const Decal& d : w.doors) {
      if (!first) {
        first = &d;
      } else if (d.surface == first->surface && d.a0 > first->a1 + 3.0) {
        second = &d;
        break;
      }
    }
    ASSERT_TRUE(first && second);
    std::vector<cv::KeyPoint> keypoints;
    const DoorView a = view_door(w, rays, *first, &keypoints);
    const DoorView b = view_door(w, rays, *second, &keypoints);
    ASSERT_GE(keypoints.size(), 5u);
    cv::Mat diff;
    cv::absdiff(a.patch, b.patch, diff);
    const double mean_diff = cv::mean(diff)[0];
    const double hamming = mean_hamming(a.descriptors, b.descriptors);
    if (!non_aliased) {
      EXPECT_LT(mean_diff, 0.5) << "identical doors render identically";
      EXPECT_LT(hamming, 8.0) << "descriptors at the same door points alias (of 512 bits)";
    } else {
      EXPECT_GT(mean_diff, 8.0) << "control-world doors differ";
      EXPECT_GT(hamming, 60.0) << "control-world descriptors differ";
    }
  }
}

}  // namespace
}  // namespace lmb
